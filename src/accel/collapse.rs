//! The binary tree collapsed to the compressed tree's eight-wide nodes: obvhs's
//! `bvh2_to_cwbvh` (the cost-optimal collapse of Ylitie et al. 2017, children ordered
//! by octant), node for node, without the quantized planes.
//!
//! obvhs's conversion took about 40 % of the 20M-triangle mesh's cluster builds (10 s of
//! the cores' 25 s): it allocates a table of seven decisions a node for every call
//! (fresh pages each cluster: a quarter of its time went to the kernel's page
//! clearing), fills it by recursion over the binary nodes (which PLOC and the
//! reinsertion leave scattered in memory), and computes each node's quantized planes,
//! which [`super::cwbvh::Cwbvh`] replaces with its own exact ones. Here the binary nodes
//! are read once, into a list in pre-order (a node's left child is the next entry);
//! the table, indexed by that position, is filled in one sweep over the list reversed
//! (children before parents), and the nodes are emitted by an explicit stack in the
//! order of obvhs's recursion, every pass after the first reading nearly in order. The
//! tables are kept per thread and reused (a thread keeps at most about 44 MB, for a
//! cluster of 2^18 primitives). The planes and the scale are left zero: every slot's
//! are made by the requantization. `tests` checks the structure against obvhs's.

use obvhs::bvh2::Bvh2;
use obvhs::cwbvh::{node::CwBvhNode, CwBvh};
use std::cell::RefCell;

/// The cost of a primitive test against a node's (obvhs's `PRIM_COST`).
const PRIM_COST: f32 = 0.3;
const NONE: u8 = u8::MAX;

#[derive(Clone, Copy, PartialEq, Default)]
enum Kind {
    Leaf,
    Internal,
    #[default]
    Distribute,
}

/// The choice for a node given `i + 1` slots (the paper's i = 1..7): what it becomes,
/// at what cost, and how it shares slots between its children when it distributes.
#[derive(Clone, Copy, Default)]
struct Decision {
    cost: f32,
    kind: Kind,
    left: u8,
    right: u8,
}

/// A binary node in pre-order: its left child is the next entry.
#[derive(Clone, Copy, Default)]
struct Entry {
    /// An internal node's right child's entry; a leaf's primitive.
    next: u32,
    /// Primitives below.
    count: u32,
    leaf: bool,
    half_area: f32,
    /// The node's box centre (the child order's).
    centre: [f32; 3],
}

/// A thread's tables, kept between calls: the nodes in pre-order, and each one's
/// decisions (by pre-order position).
#[derive(Default)]
struct Scratch {
    entries: Vec<Entry>,
    decisions: Vec<[Decision; 7]>,
    stack: Vec<(u32, u32)>,
}

thread_local! {
    static SCRATCH: RefCell<Scratch> = RefCell::new(Scratch::default());
}

/// The compressed tree of `bvh2` (leaves of one primitive each, as PLOC makes them),
/// leaves of at most `max_leaf` primitives: obvhs's `bvh2_to_cwbvh(bvh2, max_leaf, true,
/// false)` with every node's `p`, `e` and planes zero.
pub fn collapse(bvh2: &Bvh2, max_leaf: u32) -> CwBvh {
    if bvh2.nodes.is_empty() {
        return CwBvh::default();
    }
    SCRATCH.with(|s| {
        let s = &mut *s.borrow_mut();
        entries(bvh2, s);
        costs(max_leaf, s);
        let (nodes, primitive_indices) = emit(s);
        CwBvh {
            nodes,
            primitive_indices,
            total_aabb: *bvh2.nodes[0].aabb(),
            exact_node_aabbs: None,
            uses_spatial_splits: bvh2.uses_spatial_splits,
        }
    })
}

/// The nodes in pre-order (the one pass that reads the binary nodes, which PLOC and
/// the reinsertion leave scattered; every later pass reads the entries nearly in order).
fn entries(bvh2: &Bvh2, s: &mut Scratch) {
    let nodes = &bvh2.nodes;
    s.entries.clear();
    s.entries.reserve(nodes.len());
    s.stack.clear();
    // (node, the entry whose right child it is, or NO_ENTRY).
    s.stack.push((0, NO_ENTRY));
    while let Some((i, parent)) = s.stack.pop() {
        let at = s.entries.len() as u32;
        if parent != NO_ENTRY {
            s.entries[parent as usize].next = at;
        }
        let n = &nodes[i as usize];
        let half_area = n.aabb().half_area();
        let centre = n.aabb().center().into();
        if n.is_leaf() {
            assert!(
                n.prim_count == 1,
                "the collapse expects leaves of one primitive"
            );
            s.entries.push(Entry {
                next: bvh2.primitive_indices[n.first_index as usize],
                count: n.prim_count,
                leaf: true,
                half_area,
                centre,
            });
        } else {
            s.entries.push(Entry {
                half_area,
                centre,
                ..Entry::default()
            });
            s.stack.push((n.first_index + 1, at));
            s.stack.push((n.first_index, NO_ENTRY));
        }
    }
}

const NO_ENTRY: u32 = u32::MAX;

/// Fills the decision table, children before parents (the pre-order reversed).
fn costs(max_leaf: u32, s: &mut Scratch) {
    let n = s.entries.len();
    s.decisions.clear();
    s.decisions.resize(n, [Decision::default(); 7]);
    let d = &mut s.decisions;
    for at in (0..n).rev() {
        let e = s.entries[at];
        if e.leaf {
            let leaf = Decision {
                cost: e.half_area * e.count as f32 * PRIM_COST,
                kind: Kind::Leaf,
                ..Decision::default()
            };
            d[at] = [leaf; 7];
            continue;
        }
        let (l, r) = (at + 1, e.next as usize);
        let count = s.entries[l].count + s.entries[r].count;
        s.entries[at].count = count;
        let (dl, dr) = (d[l], d[r]);
        let mut out = [Decision::default(); 7];
        // One slot: a leaf, or an internal node whose children share seven slots.
        let cost_leaf = if count <= max_leaf {
            count as f32 * e.half_area * PRIM_COST
        } else {
            f32::INFINITY
        };
        let (mut best, mut left, mut right) = (f32::INFINITY, NONE, NONE);
        for k in 0..7 {
            let c = dl[k].cost + dr[6 - k].cost;
            if c < best {
                (best, left, right) = (c, k as u8, 6 - k as u8);
            }
        }
        let cost_internal = best + e.half_area;
        out[0] = if cost_leaf < cost_internal {
            Decision {
                cost: cost_leaf,
                kind: Kind::Leaf,
                left,
                right,
            }
        } else {
            Decision {
                cost: cost_internal,
                kind: Kind::Internal,
                left,
                right,
            }
        };
        // i + 1 slots: as with i, or the children sharing them.
        for i in 1..7 {
            let (mut best, mut left, mut right) = (out[i - 1].cost, NONE, NONE);
            for k in 0..i {
                let c = dl[k].cost + dr[i - k - 1].cost;
                if c < best {
                    (best, left, right) = (c, k as u8, (i - k - 1) as u8);
                }
            }
            out[i] = if left != NONE {
                Decision {
                    cost: best,
                    kind: Kind::Distribute,
                    left,
                    right,
                }
            } else {
                out[i - 1]
            };
        }
        d[at] = out;
    }
}

/// The nodes and leaf references, from the table, in obvhs's recursion's order.
fn emit(s: &mut Scratch) -> (Vec<CwBvhNode>, Vec<u32>) {
    let (entries, d) = (&s.entries, &s.decisions);
    let mut nodes = Vec::with_capacity(entries.len() / 8 + 1);
    nodes.push(CwBvhNode::default());
    let mut refs = Vec::with_capacity(entries.len() / 2 + 1);
    // (eight-wide node, entry); the stack pops them in the recursion's order.
    let mut stack = vec![(0u32, 0u32)];
    let mut leaves = Vec::new();
    while let Some((at, from)) = stack.pop() {
        let mut children = [u32::MAX; 8];
        let mut count = 0;
        gather(entries, d, from, 0, &mut children, &mut count);
        order_children(entries, from, &mut children, count);
        let mut node = CwBvhNode {
            primitive_base_idx: refs.len() as u32,
            child_base_idx: nodes.len() as u32,
            ..CwBvhNode::default()
        };
        let mut internal = 0;
        let mut prims = 0u32;
        for (slot, &c) in children.iter().enumerate() {
            if c == u32::MAX {
                continue;
            }
            match d[c as usize][0].kind {
                Kind::Leaf => {
                    let before = refs.len();
                    leaves.clear();
                    leaves.push(c);
                    // Left first, as obvhs's count_primitives.
                    while let Some(n) = leaves.pop() {
                        let e = &entries[n as usize];
                        if e.leaf {
                            refs.push(e.next);
                        } else {
                            leaves.push(e.next);
                            leaves.push(n + 1);
                        }
                    }
                    let here = refs.len() - before;
                    assert!((1..=3).contains(&here), "a leaf of {here} primitives");
                    node.child_meta[slot] =
                        prims as u8 | [0b0010_0000, 0b0110_0000, 0b1110_0000][here - 1];
                    prims += here as u32;
                }
                Kind::Internal => {
                    node.imask |= 1 << slot;
                    node.child_meta[slot] = (24 + slot as u8) | 0b0010_0000;
                    internal += 1;
                }
                Kind::Distribute => unreachable!("a distributing child"),
            }
        }
        nodes.resize(nodes.len() + internal, CwBvhNode::default());
        nodes[at as usize] = node;
        // The internal children, the first popped first.
        let mut offset = internal as u32;
        for (slot, &c) in children.iter().enumerate().rev() {
            if c != u32::MAX && node.imask & (1 << slot) != 0 {
                offset -= 1;
                stack.push((node.child_base_idx + offset, c));
            }
        }
    }
    (nodes, refs)
}

/// The children (entries) entry `at` has with `i + 1` slots: its binary descendants
/// where the table stops distributing (obvhs's get_children).
fn gather(
    entries: &[Entry],
    d: &[[Decision; 7]],
    at: u32,
    i: usize,
    children: &mut [u32; 8],
    count: &mut usize,
) {
    let e = &entries[at as usize];
    if e.leaf {
        children[*count] = at;
        *count += 1;
        return;
    }
    let here = d[at as usize][i];
    for (child, share) in [(at + 1, here.left), (e.next, here.right)] {
        if d[child as usize][share as usize].kind == Kind::Distribute {
            gather(entries, d, child, share as usize, children, count);
        } else {
            children[*count] = child;
            *count += 1;
        }
    }
}

/// Puts each child in a slot by octant: the cost of child c in slot s is the dot product
/// of s's direction (−1 where bit 2, 1, 0 of s is set for x, y, z; +1 elsewhere) with
/// c's centre's offset from the node's; the cheapest free pairs first, as obvhs's
/// greedy order_children. (Children and node as entries.)
fn order_children(entries: &[Entry], at: u32, children: &mut [u32; 8], count: usize) {
    let centre = |at: u32| glam::Vec3A::from(entries[at as usize].centre);
    let p = centre(at);
    let sign = |bit: usize| if bit != 0 { -1.0 } else { 1.0 };
    let mut cost = [[f32::MAX; 8]; 8];
    for (c, row) in cost.iter_mut().enumerate().take(count) {
        let v = centre(children[c]) - p;
        for (s, cost) in row.iter_mut().enumerate() {
            let d = glam::Vec3A::new(sign(s & 0b100), sign(s & 0b010), sign(s & 0b001));
            *cost = d.dot(v);
        }
    }
    let mut assignment = [usize::MAX; 8];
    let mut filled = [false; 8];
    loop {
        let (mut min, mut slot, mut index) = (f32::MAX, usize::MAX, usize::MAX);
        for c in 0..count {
            if assignment[c] == usize::MAX {
                for s in 0..8 {
                    if !filled[s] && cost[c][s] < min {
                        (min, slot, index) = (cost[c][s], s, c);
                    }
                }
            }
        }
        if slot == usize::MAX {
            break;
        }
        filled[slot] = true;
        assignment[index] = slot;
    }
    let original = std::mem::replace(children, [u32::MAX; 8]);
    for c in 0..count {
        children[assignment[c]] = original[c];
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use obvhs::aabb::Aabb;
    use obvhs::cwbvh::bvh2_to_cwbvh::bvh2_to_cwbvh;

    /// Boxes of a few kinds: scattered, clustered, coincident, thin.
    fn boxes(n: usize, seed: u64) -> Vec<Aabb> {
        let mut state = seed;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        (0..n)
            .map(|i| {
                let c = match i % 4 {
                    0 => glam::Vec3A::new(next(), next(), next()) * 100.0,
                    1 => glam::Vec3A::new(next(), next(), next()) + glam::Vec3A::splat(50.0),
                    2 => glam::Vec3A::splat(7.0),
                    _ => glam::Vec3A::new(next() * 100.0, 3.0, next()),
                };
                let e = glam::Vec3A::new(next(), next() * 0.01, next()) * 2.0;
                Aabb::new(c - e, c + e)
            })
            .collect()
    }

    /// Unit boxes on a lattice of `side`³ points: costs that tie exactly throughout (the
    /// collapse must break ties as obvhs does, whatever generator made the other inputs).
    fn lattice(side: u32) -> Vec<Aabb> {
        let mut out = Vec::new();
        for i in 0..side * side * side {
            let c = glam::Vec3A::new(
                (i % side) as f32,
                (i / side % side) as f32,
                (i / side / side) as f32,
            );
            out.push(Aabb::new(c * 2.0, c * 2.0 + glam::Vec3A::ONE));
        }
        out
    }

    #[test]
    fn collapse_is_obvhs_node_for_node() {
        let inputs = [
            (1, 1),
            (2, 2),
            (3, 3),
            (9, 4),
            (100, 5),
            (5000, 6),
            (40_000, 7),
        ]
        .map(|(n, seed)| boxes(n, seed))
        .into_iter()
        .chain([lattice(4), lattice(11)]);
        for b in inputs {
            let n = b.len();
            let mut params = obvhs::BvhBuildParams::slow_build();
            params.pre_split = false;
            let bvh2 = super::super::clusters::ploc(b, params);
            for max_leaf in [1, 3] {
                let ours = collapse(&bvh2, max_leaf);
                let theirs = bvh2_to_cwbvh(&bvh2, max_leaf, true, false);
                assert_eq!(
                    ours.primitive_indices, theirs.primitive_indices,
                    "{n} boxes"
                );
                assert_eq!(ours.nodes.len(), theirs.nodes.len(), "{n} boxes");
                assert_eq!(ours.total_aabb, theirs.total_aabb);
                for (a, b) in ours.nodes.iter().zip(&theirs.nodes) {
                    assert_eq!(
                        (
                            a.imask,
                            a.child_base_idx,
                            a.primitive_base_idx,
                            a.child_meta
                        ),
                        (
                            b.imask,
                            b.child_base_idx,
                            b.primitive_base_idx,
                            b.child_meta
                        ),
                        "{n} boxes, max leaf {max_leaf}"
                    );
                    // Empty slots' planes are zero in both (the requantization makes
                    // the occupied slots').
                    for s in 0..8 {
                        if b.child_meta[s] == 0 {
                            assert_eq!(
                                (b.child_min_x[s], b.child_max_x[s], b.child_max_z[s]),
                                (0, 0, 0)
                            );
                        }
                    }
                }
            }
        }
    }
}

//! The compressed BVH's build, in spatial clusters on every core.
//!
//! obvhs's PLOC with reinsertion (the "slow" preset) makes the best trees measured here
//! (docs/visibility.md), but on one core and in time that grows faster than the input:
//! 1.7 s per million triangles at one million, 4.1 s at twenty million, as its working
//! set leaves the caches. And when many primitives share one box its merge loop
//! finds few mutual nearest neighbours a round: 20,000 copies of one triangle took
//! 14 s, 100,000 took 355 s.
//!
//! So a large input is cut first. Primitives are sorted by the Morton code of their
//! box centres (21 bits an axis) and the sorted list is split, as a radix tree is, at
//! the highest bit where a range's first and last codes differ, until each range holds
//! at most [`CLUSTER_SIZE`] primitives: each range is an octree cell, compact in space.
//! Each cluster is built as before (PLOC, reinsertion — a lighter one,
//! [`CLUSTER_REINSERTION`] — collapsed to eight-wide nodes by [`super::collapse`]), the
//! clusters on all cores at once. A range of more than [`RUN_LIMIT`] primitives
//! with one Morton code (coincident, or nearly) is not given to PLOC: it becomes a
//! balanced tree, split at the index median, as the binary builder does. A small
//! compressed tree over the pieces' root boxes, one piece a leaf, joins them: each of
//! its leaf slots becomes the piece's root node (see [`join`]).
//!
//! An input of at most one cluster without such a run is built exactly as before (one
//! PLOC over the input in its order), so small scenes' trees, and images, are unchanged.
//! The tree depends on the input alone, never on the number of threads.
//!
//! Measured on the 20M-triangle mesh (docs/performance.md): 83.6 s before, 20.2 s after
//! on this machine's two cores, the rays traced as fast; 12.0–12.1 s with the lighter
//! reinsertion of the pieces, the collapse of `super::collapse` and the keys on every
//! core (twenty-eighth session).

use super::collapse::collapse;
use super::cwbvh::{requantize_node, requantize_tree, Child};
use obvhs::aabb::Aabb;
use obvhs::bvh2::{node::Bvh2Node, reinsertion::ReinsertionOptimizer, Bvh2};
use obvhs::cwbvh::{node::CwBvhNode, CwBvh};
use obvhs::ploc::PlocBuilder;
use obvhs::BvhBuildParams;

/// Most primitives one PLOC build is given (large enough that the top tree's seams cost
/// little, small enough that its arrays stay in cache).
pub const CLUSTER_SIZE: usize = 1 << 18;

/// Longest run of one Morton code given to PLOC (a longer one, or one longer than the
/// cluster size, is a balanced tree).
pub const RUN_LIMIT: usize = 256;

/// The reinsertion batch ratio of the pieces of an input built in several (obvhs's
/// "medium" preset's; the "slow" preset's 0.2 for an input of one piece). On the
/// 20M-triangle mesh it took the pieces' reinsertion from 10–12 s of the cores' time to
/// 2 s and traced as fast (0.36–0.42 Mrays/s against 0.36–0.43 in interleaved runs;
/// none at all: 0.33). docs/performance.md, "Twenty-eighth session".
pub const CLUSTER_REINSERTION: f32 = 0.05;

/// Bits of a Morton code an axis.
const MORTON_BITS: u32 = 21;

/// The compressed tree over `bounds` (leaves of at most `max_leaf` primitives, their
/// references indexing `bounds`), built with `params` in clusters of at most
/// `cluster_size` primitives on `threads` threads (the tree does not depend on them).
/// (The boxes become obvhs's a cluster at a time: no copy of them all.)
pub fn build(
    bounds: &[Bounds],
    params: BvhBuildParams,
    max_leaf: u32,
    cluster_size: usize,
    threads: usize,
) -> (Vec<CwBvhNode>, Vec<u32>) {
    if bounds.is_empty() {
        return (vec![CwBvhNode::default()], Vec::new());
    }
    let keys = sorted_keys(bounds, threads);
    let mut items = Vec::new();
    split(&keys, cluster_size.max(1), &mut items);
    if let [Item::Cluster(_)] = items[..] {
        // One cluster, no long run: the input in its own order, as before.
        let boxes: Vec<Aabb> = bounds.iter().map(obvhs_box).collect();
        let mut cw = collapse(&ploc(boxes, params), max_leaf);
        requantize_tree(&mut cw.nodes, &cw.primitive_indices, |p| bounds[p as usize]);
        return (cw.nodes, cw.primitive_indices);
    }
    // The pieces' reinsertion that of obvhs's "medium" preset (see CLUSTER_REINSERTION).
    let pieces = BvhBuildParams {
        reinsertion_batch_ratio: CLUSTER_REINSERTION,
        ..params
    };
    let trees = build_items(bounds, &items, pieces, max_leaf, threads);
    join(&trees, params)
}

/// The tree's boxes.
type Bounds = super::geometry::Aabb;

/// `b` as obvhs's box.
fn obvhs_box(b: &Bounds) -> Aabb {
    Aabb::new(b.min.into(), b.max.into())
}

/// One PLOC build with reinsertion over `boxes`.
pub(super) fn ploc(boxes: Vec<Aabb>, params: BvhBuildParams) -> Bvh2 {
    let mut scratch = Scratch {
        boxes,
        ..Scratch::default()
    };
    scratch.ploc(params);
    scratch.bvh
}

/// A thread's arrays for the builds of its clusters, kept from one cluster to the next:
/// the boxes, obvhs's builder, tree and reinsertion (each of which clears and refills
/// what it reuses). With fresh arrays for every cluster the kernel's page faults and
/// clearing took 10 % of the 20M-triangle mesh's cluster builds (perf, 1 % after); the
/// trees are the same (`cwbvh`'s `clustered_build_does_not_depend_on_threads` builds
/// the clusters on one thread, each after another's, and on several).
#[derive(Default)]
struct Scratch {
    boxes: Vec<Aabb>,
    builder: PlocBuilder,
    bvh: Bvh2,
    reinsertion: ReinsertionOptimizer,
}

impl Scratch {
    /// PLOC with reinsertion over `self.boxes`, into `self.bvh`.
    fn ploc(&mut self, params: BvhBuildParams) {
        let mut indices = std::mem::take(&mut self.bvh.primitive_indices);
        indices.clear();
        indices.extend(0..self.boxes.len() as u32);
        self.builder.build_with_bvh(
            &mut self.bvh,
            params.ploc_search_distance,
            &self.boxes,
            indices,
            params.sort_precision,
            params.search_depth_threshold,
        );
        self.reinsertion
            .run(&mut self.bvh, params.reinsertion_batch_ratio, None);
    }
}

thread_local! {
    static SCRATCH: std::cell::RefCell<Scratch> = std::cell::RefCell::new(Scratch::default());
}

/// `(Morton code of the box centre, index)`, sorted (the index breaks ties, so the
/// order is the input's alone). The keys are counted by their codes' top [`BUCKET_BITS`]
/// bits a piece per thread, then made again and put in those buckets (a counting sort,
/// each piece scattering its own keys at once) and the buckets sorted at once; where one
/// bucket would hold more than a quarter of them (a scene whose primitives crowd one
/// corner of its box), sorted in `threads` pieces at once and merged instead. Either way
/// the same list.
fn sorted_keys(boxes: &[Bounds], threads: usize) -> Vec<(u64, u32)> {
    let piece = boxes.len().div_ceil(threads.max(1)).max(1 << 16);
    let centres = super::map_pieces(boxes, piece, threads, |boxes| {
        let mut centres = Aabb::empty();
        for b in boxes.iter() {
            centres.extend(obvhs_box(b).center());
        }
        centres
    })
    .into_iter()
    .fold(Aabb::empty(), |a, b| a.union(&b));
    let extent = centres.diagonal();
    let cells = ((1u32 << MORTON_BITS) - 1) as f32;
    let scale = glam::Vec3A::select(
        extent.cmpgt(glam::Vec3A::ZERO),
        cells / extent,
        glam::Vec3A::ZERO,
    );
    let key = |i: usize| {
        let q = ((obvhs_box(&boxes[i]).center() - centres.min) * scale)
            .clamp(glam::Vec3A::ZERO, glam::Vec3A::splat(cells))
            .as_uvec3();
        (morton(q.x, q.y, q.z), i as u32)
    };
    let bucket = |k: &(u64, u32)| (k.0 >> (3 * MORTON_BITS - BUCKET_BITS)) as usize;
    // How many of each piece's keys fall in each bucket. (The keys are made again where
    // they are scattered: an array of them all would be 16 bytes a primitive of fresh
    // memory, which costs more to touch than the codes cost to make.)
    let mut pieces: Vec<std::ops::Range<usize>> = (0..boxes.len())
        .step_by(piece)
        .map(|first| first..(first + piece).min(boxes.len()))
        .collect();
    let counts = super::map_in_parallel(&mut pieces, threads, |range| {
        let mut count = vec![0usize; 1 << BUCKET_BITS];
        for i in range.clone() {
            count[bucket(&key(i))] += 1;
        }
        count
    });
    let total = |b: usize| counts.iter().map(|c| c[b]).sum::<usize>();
    if (0..1 << BUCKET_BITS).any(|b| total(b) > boxes.len() / 4) {
        let keys = super::map_in_parallel(&mut pieces, threads, |r| {
            r.clone().map(key).collect::<Vec<_>>()
        });
        return merged_keys(keys.concat(), threads);
    }
    // Each bucket's place, shared out to the pieces in order (piece p's part of bucket b
    // after the parts of the pieces before it): each piece scatters its keys into its own
    // parts, every piece at once.
    let mut sorted = vec![(0u64, 0u32); boxes.len()];
    let mut parts: Vec<(std::ops::Range<usize>, Vec<&mut [(u64, u32)]>)> = pieces
        .into_iter()
        .map(|r| (r, Vec::with_capacity(1 << BUCKET_BITS)))
        .collect();
    let mut rest = &mut sorted[..];
    let mut start = vec![0usize; (1 << BUCKET_BITS) + 1];
    for b in 0..1 << BUCKET_BITS {
        for (p, count) in counts.iter().enumerate() {
            let (part, tail) = std::mem::take(&mut rest).split_at_mut(count[b]);
            parts[p].1.push(part);
            rest = tail;
        }
        start[b + 1] = start[b] + total(b);
    }
    super::map_in_parallel(&mut parts, threads, |(range, parts)| {
        let mut next = vec![0usize; 1 << BUCKET_BITS];
        for i in range.clone() {
            let k = key(i);
            let b = bucket(&k);
            parts[b][next[b]] = k;
            next[b] += 1;
        }
    });
    drop(parts);
    let mut buckets = Vec::new();
    let mut rest = &mut sorted[..];
    for b in 0..1 << BUCKET_BITS {
        let (head, tail) = rest.split_at_mut(start[b + 1] - start[b]);
        if head.len() > 1 {
            buckets.push(head);
        }
        rest = tail;
    }
    super::map_in_parallel(&mut buckets, threads, |b| b.sort_unstable());
    sorted
}

/// The top bits of the Morton codes [`sorted_keys`] buckets by.
const BUCKET_BITS: u32 = 12;

/// `keys` sorted in `threads` pieces at once, then merged.
fn merged_keys(keys: Keys, threads: usize) -> Keys {
    let piece = keys.len().div_ceil(threads.max(1)).max(1 << 16);
    let mut sorted = super::map_pieces(&keys, piece, threads, |keys| {
        let mut keys = keys.to_vec();
        keys.sort_unstable();
        keys
    });
    drop(keys);
    // Merge pairs of sorted runs until one is left (the pairs of a round at once).
    while sorted.len() > 1 {
        let mut pairs: Vec<(Keys, Option<Keys>)> = Vec::new();
        let mut runs = sorted.into_iter();
        while let Some(a) = runs.next() {
            pairs.push((a, runs.next()));
        }
        sorted = super::map_in_parallel(&mut pairs, threads, |(a, b)| match b.take() {
            Some(b) => merge(a, &b),
            None => std::mem::take(a),
        });
    }
    sorted.pop().unwrap_or_default()
}

/// Morton keys, `(code, index)`.
type Keys = Vec<(u64, u32)>;

/// Two sorted lists as one sorted list.
fn merge(a: &[(u64, u32)], b: &[(u64, u32)]) -> Vec<(u64, u32)> {
    let mut out = Vec::with_capacity(a.len() + b.len());
    let (mut i, mut j) = (0, 0);
    while i < a.len() && j < b.len() {
        if b[j] < a[i] {
            out.push(b[j]);
            j += 1;
        } else {
            out.push(a[i]);
            i += 1;
        }
    }
    out.extend_from_slice(&a[i..]);
    out.extend_from_slice(&b[j..]);
    out
}

/// The 63-bit Morton code of three 21-bit coordinates.
fn morton(x: u32, y: u32, z: u32) -> u64 {
    fn spread(v: u32) -> u64 {
        let mut v = v as u64 & 0x1f_ffff;
        v = (v | v << 32) & 0x001f_0000_0000_ffff;
        v = (v | v << 16) & 0x001f_0000_ff00_00ff;
        v = (v | v << 8) & 0x100f_00f0_0f00_f00f;
        v = (v | v << 4) & 0x10c3_0c30_c30c_30c3;
        v = (v | v << 2) & 0x1249_2492_4924_9249;
        v
    }
    spread(x) << 2 | spread(y) << 1 | spread(z)
}

/// A piece of the sorted list, built on its own.
enum Item<'a> {
    /// Built by PLOC.
    Cluster(&'a [(u64, u32)]),
    /// One Morton code throughout: a balanced tree.
    Run(&'a [(u64, u32)]),
}

impl<'a> Item<'a> {
    fn keys(&self) -> &'a [(u64, u32)] {
        match self {
            Item::Cluster(k) | Item::Run(k) => k,
        }
    }
}

fn longest_run(keys: &[(u64, u32)]) -> usize {
    let (mut longest, mut run) = (0, 0);
    for (i, k) in keys.iter().enumerate() {
        run = if i > 0 && keys[i - 1].0 == k.0 {
            run + 1
        } else {
            1
        };
        longest = longest.max(run);
    }
    longest
}

/// Cuts `keys` at the highest differing bit until each piece is a cluster of at most
/// `cluster_size` without a run longer than [`RUN_LIMIT`], or a run.
fn split<'a>(keys: &'a [(u64, u32)], cluster_size: usize, items: &mut Vec<Item<'a>>) {
    let (first, last) = (keys[0].0, keys[keys.len() - 1].0);
    if keys.len() <= cluster_size && longest_run(keys) <= RUN_LIMIT {
        items.push(Item::Cluster(keys));
        return;
    }
    if first == last {
        items.push(Item::Run(keys));
        return;
    }
    let bit = 63 - (first ^ last).leading_zeros();
    let middle = keys.partition_point(|k| k.0 >> bit & 1 == 0);
    split(&keys[..middle], cluster_size, items);
    split(&keys[middle..], cluster_size, items);
}

/// Each item's compressed tree (its nodes requantized, its references mapped to input
/// indices) and its exact box, the items shared out to the threads.
fn build_items(
    bounds: &[Bounds],
    items: &[Item],
    params: BvhBuildParams,
    max_leaf: u32,
    threads: usize,
) -> Vec<(CwBvh, Bounds)> {
    let mut items: Vec<&Item> = items.iter().collect();
    super::map_in_parallel(&mut items, threads, |item| {
        let keys = item.keys();
        SCRATCH.with(|s| {
            let s = &mut *s.borrow_mut();
            s.boxes.clear();
            s.boxes
                .extend(keys.iter().map(|&(_, p)| obvhs_box(&bounds[p as usize])));
            let mut cw = match item {
                Item::Cluster(_) => {
                    s.ploc(params);
                    collapse(&s.bvh, max_leaf)
                }
                Item::Run(_) => collapse(&balanced(&s.boxes), max_leaf),
            };
            let exact = requantize_tree(&mut cw.nodes, &cw.primitive_indices, |r| {
                bounds[keys[r as usize].1 as usize]
            });
            for r in &mut cw.primitive_indices {
                *r = keys[*r as usize].1;
            }
            (cw, exact)
        })
    })
}

/// A tree over `boxes` split at the index median (siblings adjacent, root at 0).
fn balanced(boxes: &[Aabb]) -> Bvh2 {
    fn node(boxes: &[Aabb], first: usize, nodes: &mut Vec<Bvh2Node>, at: usize) {
        if boxes.len() == 1 {
            nodes[at] = Bvh2Node::new(boxes[0], 1, first as u32);
            return;
        }
        let left = nodes.len();
        nodes.extend([Bvh2Node::default(); 2]);
        let half = boxes.len() / 2;
        node(&boxes[..half], first, nodes, left);
        node(&boxes[half..], first + half, nodes, left + 1);
        let both = nodes[left].aabb.union(&nodes[left + 1].aabb);
        nodes[at] = Bvh2Node::new(both, 0, left as u32);
    }
    let mut nodes = vec![Bvh2Node::default()];
    node(boxes, 0, &mut nodes, 0);
    Bvh2 {
        nodes,
        primitive_indices: (0..boxes.len() as u32).collect(),
        ..Bvh2::default()
    }
}

/// One compressed tree: a compressed tree over the items' root boxes (one item a leaf
/// slot) whose leaf slots become the items' roots (each item requantized, with its exact
/// box; the top tree's nodes are requantized here, from those).
///
/// A node's internal children sit together from its `child_base_idx`, in slot order, so
/// each top node's children are laid out anew: its occupied slots all internal, an item's
/// root copied into its place and the item's other nodes after it, their child and
/// primitive indices moved by where the item's nodes and references now start.
fn join(items: &[(CwBvh, Bounds)], params: BvhBuildParams) -> (Vec<CwBvhNode>, Vec<u32>) {
    let trees: Vec<&CwBvh> = items.iter().map(|(t, _)| t).collect();
    let roots: Vec<Aabb> = trees.iter().map(|t| t.total_aabb).collect();
    let mut binary = PlocBuilder::with_capacity(roots.len()).build(
        params.ploc_search_distance,
        &roots,
        (0..roots.len() as u32).collect(),
        params.sort_precision,
        params.search_depth_threshold,
    );
    // The top tree is small: every node a candidate.
    ReinsertionOptimizer::default().run(&mut binary, 1.0, None);
    let top = collapse(&binary, 1);
    let mut first_ref = Vec::with_capacity(trees.len());
    let mut refs = Vec::with_capacity(trees.iter().map(|t| t.primitive_indices.len()).sum());
    for t in &trees {
        first_ref.push(refs.len() as u32);
        refs.extend_from_slice(&t.primitive_indices);
    }
    let mut nodes: Vec<CwBvhNode> =
        Vec::with_capacity(trees.iter().map(|t| t.nodes.len()).sum::<usize>() + top.nodes.len());
    // (top node, where it goes); the root first. The top nodes' places in that order,
    // and the exact box of each node they point to, for their requantization.
    nodes.push(CwBvhNode::default());
    let mut queue = std::collections::VecDeque::from([(0usize, 0usize)]);
    let mut top_places = Vec::new();
    let mut exact = std::collections::HashMap::new();
    while let Some((t, at)) = queue.pop_front() {
        top_places.push(at);
        let mut node = top.nodes[t];
        let group = nodes.len();
        let mut imask = 0u8;
        let mut placed = Vec::new();
        for slot in 0..8 {
            if node.child_meta[slot] == 0 {
                continue;
            }
            let here = group + placed.len();
            let child = if node.imask & (1 << slot) != 0 {
                let below = (node.imask as u32 & ((1u32 << slot) - 1)).count_ones();
                Ok(node.child_base_idx as usize + below as usize)
            } else {
                let offset = (node.child_meta[slot] & 0x1f) as u32;
                Err(top.primitive_indices[(node.primitive_base_idx + offset) as usize] as usize)
            };
            placed.push((here, child));
            imask |= 1 << slot;
            node.child_meta[slot] = (24 + slot as u8) | 0b0010_0000;
        }
        node.imask = imask;
        node.child_base_idx = group as u32;
        node.primitive_base_idx = 0;
        nodes[at] = node;
        nodes.resize(group + placed.len(), CwBvhNode::default());
        for (here, child) in placed {
            match child {
                Ok(top_child) => queue.push_back((top_child, here)),
                Err(item) => {
                    // Item node j > 0 goes to `base + j`, its root to `here`.
                    let base = nodes.len() as u32 - 1;
                    let moved = |mut n: CwBvhNode| {
                        n.child_base_idx += base;
                        n.primitive_base_idx += first_ref[item];
                        n
                    };
                    let tree = &trees[item].nodes;
                    nodes[here] = moved(tree[0]);
                    nodes.extend(tree[1..].iter().map(|&n| moved(n)));
                    exact.insert(here as u32, items[item].1);
                }
            }
        }
    }
    // A top node's children come after it: the last first.
    for &at in top_places.iter().rev() {
        let whole = requantize_node(&mut nodes[at], |c| match c {
            Child::Node(c) => exact[&c],
            Child::Leaf { .. } => unreachable!("a top node's slots all hold nodes"),
        });
        exact.insert(at as u32, whole);
    }
    (nodes, refs)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn morton_interleaves_x_high() {
        assert_eq!(morton(1, 0, 0), 0b100);
        assert_eq!(morton(0, 1, 0), 0b010);
        assert_eq!(morton(0, 0, 1), 0b001);
        assert_eq!(morton(0x1f_ffff, 0x1f_ffff, 0x1f_ffff), (1u64 << 63) - 1);
        assert_eq!(morton(2, 0, 0), 0b100_000);
    }

    /// The keys sorted in pieces and merged are the keys sorted on one thread (ties,
    /// coincident centres, broken by the index).
    #[test]
    fn keys_sorted_in_pieces_are_sorted_keys() {
        let mut state = 7u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        // A third of the boxes at one point (one bucket too full: sorted in pieces and
        // merged), then one in fifty (bucketed); ties in both.
        for crowd in [3, 50] {
            let boxes: Vec<Bounds> = (0..300_000)
                .map(|i| {
                    let c = if i % crowd == 0 {
                        glam::Vec3::splat(0.5)
                    } else {
                        glam::Vec3::new(next(), next(), next())
                    };
                    Bounds {
                        min: c,
                        max: c + glam::Vec3::splat(0.01),
                    }
                })
                .collect();
            let one = sorted_keys(&boxes, 1);
            assert!(one.windows(2).all(|w| w[0] < w[1]));
            let mut seen = vec![false; boxes.len()];
            for &(_, i) in &one {
                seen[i as usize] = true;
            }
            assert!(seen.iter().all(|&s| s), "every box once");
            for threads in [2, 3, 5] {
                assert_eq!(sorted_keys(&boxes, threads), one, "{threads} threads");
            }
        }
    }
}

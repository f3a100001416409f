//! The CPU-built SAH BVH that the GPU traverses from a storage buffer, and its CPU
//! traversal mirror.
//!
//! Layout (read by `glsl/lib/trace_bvh.glsl`): nodes in depth-first order, root at 0.
//! An internal node (`count == 0`) has its first child at `index + 1` and its second at
//! `left_or_first`; a leaf (`count > 0`) holds `prim_refs[left_or_first..][..count]`.
//!
//! An empty scene is a single node with `count == 0` and the empty box (`min = +inf`,
//! `max = -inf`). `count == 0` would read as an internal node, so traversal checks the
//! root box first and reports no hit when it is inverted (`min.x > max.x`); no other
//! node can have an inverted box.
//!
//! Builder: binned SAH (Wald 2007, "On fast Construction of SAH-based Bounding Volume
//! Hierarchies") with [`SAH_BINS`] bins per axis over the centroid bounds, all three
//! axes, costs [`TRAVERSAL_COST`] and [`INTERSECTION_COST`]. A node becomes a leaf
//! when it has at most [`MIN_LEAF_SIZE`] primitives, or at most [`MAX_LEAF_SIZE`] and
//! the SAH says splitting does not pay. Coincident centroids split at the index median.
//! Leaf depth is capped at [`MAX_DEPTH`] so the traversal stack of [`STACK_SIZE`]
//! entries cannot overflow: where an SAH split could break the cap, the node splits at
//! the centroid median of its widest axis instead.

pub use super::geometry::Aabb;
use glam::{Vec3, Vec3A};

/// One BVH node: two std430 `vec4`s, the `w` lanes holding `uint` bits.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct BvhNode {
    pub min: [f32; 3],
    /// Internal: index of the second child. Leaf: first index into `prim_refs`.
    pub left_or_first: u32,
    pub max: [f32; 3],
    /// 0 for an internal node, else the number of primitives in the leaf.
    pub count: u32,
}

const _: () = {
    assert!(std::mem::size_of::<BvhNode>() == 32);
    assert!(std::mem::offset_of!(BvhNode, min) == 0);
    assert!(std::mem::offset_of!(BvhNode, left_or_first) == 12);
    assert!(std::mem::offset_of!(BvhNode, max) == 16);
    assert!(std::mem::offset_of!(BvhNode, count) == 28);
};

impl BvhNode {
    pub fn is_leaf(&self) -> bool {
        self.count > 0
    }

    pub fn bounds(&self) -> Aabb {
        Aabb {
            min: Vec3::from(self.min),
            max: Vec3::from(self.max),
        }
    }
}

/// Entries of the traversal stack (CPU and GPU: `BVH_STACK_SIZE`).
pub const STACK_SIZE: usize = 64;
/// Deepest leaf (root depth 0); a path pushes at most one entry per internal node above
/// its leaf, so `MAX_DEPTH < STACK_SIZE` keeps the stack from overflowing.
pub const MAX_DEPTH: u32 = 63;
/// Bins per axis of the SAH sweep.
pub const SAH_BINS: usize = 32;
/// SAH cost of visiting one node (ratio to one primitive test is what matters).
pub const TRAVERSAL_COST: f32 = 1.0;
/// SAH cost of one ray–primitive test.
pub const INTERSECTION_COST: f32 = 1.0;
/// Nodes with at most this many primitives are always leaves.
pub const MIN_LEAF_SIZE: u32 = 4;
/// No leaf holds more primitives than this.
pub const MAX_LEAF_SIZE: u32 = 16;
/// Slab exit distances are scaled by `1 + 2 gamma(3)` so that rounding in the slab
/// test never rejects a box the ray touches (Pharr et al., PBR 3rd ed., §3.9.2);
/// gamma(n) = n eps / (1 - n eps) with eps = 2^-24.
pub const SLAB_EXIT_SCALE: f32 = 1.0 + 2.0 * (3.0 * 5.960_464_5e-8) / (1.0 - 3.0 * 5.960_464_5e-8);
/// Direction components smaller in magnitude than this are replaced by ±this before
/// inverting, so the inverse is finite and `(bound - o) * inv_d` is never `0 * inf`
/// (NaN). For a ray parallel to a slab this still gives an interval covering all `t`
/// when the origin is inside the slab, and one beyond ~1e30 × the gap when outside;
/// the products stay finite for scene coordinates below ~1e8.
pub const MIN_DIR_COMPONENT: f32 = 1e-30;

#[derive(Clone, Debug, PartialEq)]
pub struct Bvh {
    pub nodes: Vec<BvhNode>,
    /// Leaf ranges index this; its values are primitive indices into the build input.
    pub prim_refs: Vec<u32>,
}

/// A primitive as the builder moves it around: its box, centroid and input index,
/// kept together so every sweep reads memory in order.
#[derive(Clone, Copy)]
struct BuildPrim {
    min: Vec3A,
    max: Vec3A,
    centroid: Vec3,
    index: u32,
}

/// Per-bin accumulation of the SAH sweep.
#[derive(Clone, Copy)]
struct Bin {
    min: Vec3A,
    max: Vec3A,
    count: u32,
}

impl Bin {
    const EMPTY: Bin = Bin {
        min: Vec3A::INFINITY,
        max: Vec3A::NEG_INFINITY,
        count: 0,
    };
}

/// Surface area of a box, 0 when empty.
fn area(min: Vec3A, max: Vec3A) -> f32 {
    let e = (max - min).max(Vec3A::ZERO);
    2.0 * (e.x * e.y + e.y * e.z + e.z * e.x)
}

/// Per-axis bin of a centroid: `(c - lo) * scale` truncated and clamped to the last
/// bin. The same expression bins and partitions, so both agree exactly.
fn bins_of(c: Vec3A, lo: Vec3A, scale: Vec3A) -> [usize; 3] {
    let b = ((c - lo) * scale).min(Vec3A::splat((SAH_BINS - 1) as f32));
    [b.x as usize, b.y as usize, b.z as usize]
}

/// Levels of median splits needed before `count` primitives fit in leaves.
fn median_levels(mut count: u32) -> u32 {
    let mut levels = 0;
    while count > MAX_LEAF_SIZE {
        count = count.div_ceil(2);
        levels += 1;
    }
    levels
}

/// A subtree still to build: `prims[begin..end]`, at `depth`; `parent` is the node
/// whose `left_or_first` must point here (second children only).
struct Task {
    begin: u32,
    end: u32,
    depth: u32,
    parent: Option<u32>,
}

/// Subtrees of more than this many primitives build their two children on two threads
/// (while threads are left).
const PARALLEL_PRIMS: usize = 1 << 16;

/// The binned SAH build of one subtree, its nodes depth first (the first child right
/// after its parent, the second at the parent's `left_or_first`), node indices counted
/// from the subtree's root and leaves' primitive indices from the whole input's.
struct SubtreeBuild {
    max_depth: u32,
    parallel_prims: usize,
}

impl SubtreeBuild {
    /// The subtree over `prims` (the input's primitives from `first` on), its root at
    /// `depth`, on up to `threads` threads.
    fn subtree(
        &self,
        prims: &mut [BuildPrim],
        first: u32,
        depth: u32,
        threads: usize,
    ) -> Vec<BvhNode> {
        if threads < 2 || prims.len() <= self.parallel_prims {
            return self.serial(prims, first, depth);
        }
        let Some((root, left_count)) = self.node(prims, depth) else {
            return self.serial(prims, first, depth);
        };
        let (left, right) = prims.split_at_mut(left_count as usize);
        let half = threads / 2;
        let (left, right) = std::thread::scope(|s| {
            let l = s.spawn(|| self.subtree(left, first, depth + 1, threads - half));
            let r = self.subtree(right, first + left_count, depth + 1, half);
            (l.join().expect("a subtree's build"), r)
        });
        let mut nodes = Vec::with_capacity(1 + left.len() + right.len());
        nodes.push(BvhNode {
            left_or_first: 1 + left.len() as u32,
            ..root
        });
        let offset_right = 1 + left.len() as u32;
        nodes.extend(left.into_iter().map(|n| moved(n, 1)));
        nodes.extend(right.into_iter().map(|n| moved(n, offset_right)));
        nodes
    }

    /// A node over `prims`: its record (internal, children not placed yet) and its first
    /// child's size, `prims` reordered so that it comes first; `None` for a leaf.
    fn node(&self, prims: &mut [BuildPrim], depth: u32) -> Option<(BvhNode, u32)> {
        let (min, max, cmin, cmax) = node_bounds(prims);
        let split = choose_split(prims, area(min, max), cmin, cmax, depth, self.max_depth)?;
        Some((
            BvhNode {
                min: min.into(),
                left_or_first: 0,
                max: max.into(),
                count: 0,
            },
            split,
        ))
    }

    /// The subtree on this thread.
    fn serial(&self, prims: &mut [BuildPrim], first: u32, depth: u32) -> Vec<BvhNode> {
        let n = prims.len() as u32;
        let mut nodes: Vec<BvhNode> = Vec::with_capacity(2 * n as usize);
        let mut tasks = vec![Task {
            begin: 0,
            end: n,
            depth,
            parent: None,
        }];
        while let Some(task) = tasks.pop() {
            let index = nodes.len() as u32;
            if let Some(parent) = task.parent {
                nodes[parent as usize].left_or_first = index;
            }
            let range = &mut prims[task.begin as usize..task.end as usize];
            let (min, max, cmin, cmax) = node_bounds(range);
            let split = choose_split(
                range,
                area(min, max),
                cmin,
                cmax,
                task.depth,
                self.max_depth,
            );
            let count = task.end - task.begin;
            nodes.push(BvhNode {
                min: min.into(),
                left_or_first: if split.is_some() {
                    0
                } else {
                    first + task.begin
                },
                max: max.into(),
                count: if split.is_some() { 0 } else { count },
            });
            if let Some(left_count) = split {
                let mid = task.begin + left_count;
                // Pushed second, popped first: the first child lands at index + 1.
                tasks.push(Task {
                    begin: mid,
                    end: task.end,
                    depth: task.depth + 1,
                    parent: Some(index),
                });
                tasks.push(Task {
                    begin: task.begin,
                    end: mid,
                    depth: task.depth + 1,
                    parent: None,
                });
            }
        }
        nodes
    }
}

/// A subtree's node placed `offset` nodes further on (its second child's index moves
/// with it; a leaf's primitives do not).
fn moved(mut node: BvhNode, offset: u32) -> BvhNode {
    if node.count == 0 {
        node.left_or_first += offset;
    }
    node
}

/// The bounds of `prims`' boxes and of their centroids.
fn node_bounds(prims: &[BuildPrim]) -> (Vec3A, Vec3A, Vec3A, Vec3A) {
    let (mut min, mut max) = (Vec3A::INFINITY, Vec3A::NEG_INFINITY);
    let (mut cmin, mut cmax) = (Vec3A::INFINITY, Vec3A::NEG_INFINITY);
    for p in prims {
        min = min.min(p.min);
        max = max.max(p.max);
        let c = Vec3A::from(p.centroid);
        cmin = cmin.min(c);
        cmax = cmax.max(c);
    }
    (min, max, cmin, cmax)
}

/// Inverse direction for the slab test, with tiny components clamped away from 0
/// (see [`MIN_DIR_COMPONENT`]).
pub fn safe_inverse(d: Vec3) -> Vec3 {
    let clamp = |x: f32| {
        if x.abs() < MIN_DIR_COMPONENT {
            if x >= 0.0 {
                MIN_DIR_COMPONENT
            } else {
                -MIN_DIR_COMPONENT
            }
        } else {
            x
        }
    };
    Vec3::new(1.0 / clamp(d.x), 1.0 / clamp(d.y), 1.0 / clamp(d.z))
}

/// Distance at which the ray enters `node`'s box within `[tmin, tmax]`, or `+inf` when
/// it misses it there. A box touched exactly at `tmax` counts as entered.
pub fn box_entry(node: &BvhNode, o: Vec3, inv_d: Vec3, tmin: f32, tmax: f32) -> f32 {
    let t0 = (Vec3::from(node.min) - o) * inv_d;
    let t1 = (Vec3::from(node.max) - o) * inv_d;
    let t_near = t0.min(t1);
    let t_far = t0.max(t1);
    let enter = t_near.x.max(t_near.y).max(t_near.z.max(tmin));
    let leave = (t_far.x.min(t_far.y).min(t_far.z) * SLAB_EXIT_SCALE).min(tmax);
    if enter <= leave {
        enter
    } else {
        f32::INFINITY
    }
}

impl Bvh {
    /// Builds the BVH over primitives whose bounds are `bounds[i]`. Deterministic: the
    /// same tree on any number of cores (subtrees of more than [`PARALLEL_PRIMS`]
    /// primitives build their two children side by side).
    pub fn build(bounds: &[Aabb]) -> Bvh {
        Self::build_with(bounds, MAX_DEPTH, super::threads(), PARALLEL_PRIMS)
    }

    fn build_with(bounds: &[Aabb], max_depth: u32, threads: usize, parallel_prims: usize) -> Bvh {
        let n = u32::try_from(bounds.len()).expect("more than 2^32 primitives");
        if n == 0 {
            let empty = Aabb::empty();
            return Bvh {
                nodes: vec![BvhNode {
                    min: empty.min.into(),
                    left_or_first: 0,
                    max: empty.max.into(),
                    count: 0,
                }],
                prim_refs: Vec::new(),
            };
        }
        assert!(median_levels(n) <= max_depth);
        let mut prims: Vec<BuildPrim> = bounds
            .iter()
            .zip(0..n)
            .map(|(b, index)| {
                // An empty (or NaN) box adds nothing to any node's bounds; give it a
                // finite centroid so the binning stays finite.
                let c = b.centroid();
                let valid = !b.is_empty() && c.is_finite();
                BuildPrim {
                    min: if b.is_empty() {
                        Vec3A::INFINITY
                    } else {
                        b.min.into()
                    },
                    max: if b.is_empty() {
                        Vec3A::NEG_INFINITY
                    } else {
                        b.max.into()
                    },
                    centroid: if valid { c } else { Vec3::ZERO },
                    index,
                }
            })
            .collect();
        let build = SubtreeBuild {
            max_depth,
            parallel_prims,
        };
        let nodes = build.subtree(&mut prims, 0, 0, threads);
        Bvh {
            nodes,
            prim_refs: prims.iter().map(|p| p.index).collect(),
        }
    }

    /// Closest hit along `o + t d` with `t` in `(tmin, tmax)`. `hit_prim(prim, t_max)`
    /// tests primitive `prim` (an index into the build input) and returns its hit
    /// distance, which must be below `t_max`. Returns the primitive and distance.
    ///
    /// Shaped like the GPU loop: fixed stack, no recursion, nearer child first, and a
    /// popped node is re-tested against the current closest distance (so nodes whose
    /// entry lies beyond it are skipped without storing distances on the stack).
    pub fn closest_hit(
        &self,
        o: Vec3,
        d: Vec3,
        tmin: f32,
        tmax: f32,
        hit_prim: impl FnMut(u32, f32) -> Option<f32>,
    ) -> Option<(u32, f32)> {
        self.traverse(o, d, tmin, tmax, false, hit_prim)
    }

    /// True when some primitive is hit with `t` in `(tmin, tmax)`; stops at the first.
    pub fn any_hit(
        &self,
        o: Vec3,
        d: Vec3,
        tmin: f32,
        tmax: f32,
        hit_prim: impl FnMut(u32, f32) -> Option<f32>,
    ) -> bool {
        self.traverse(o, d, tmin, tmax, true, hit_prim).is_some()
    }

    fn traverse(
        &self,
        o: Vec3,
        d: Vec3,
        tmin: f32,
        tmax: f32,
        any_hit: bool,
        mut hit_prim: impl FnMut(u32, f32) -> Option<f32>,
    ) -> Option<(u32, f32)> {
        let inv_d = safe_inverse(d);
        let mut stack = [0u32; STACK_SIZE];
        let mut sp = 0usize;
        let mut node_index = 0u32;
        let mut closest = tmax;
        let mut found: Option<(u32, f32)> = None;
        let root = &self.nodes[0];
        // The empty scene's root has an inverted box (see the module docs).
        if root.min[0] > root.max[0] || box_entry(root, o, inv_d, tmin, closest) == f32::INFINITY {
            return None;
        }
        loop {
            let node = &self.nodes[node_index as usize];
            if node.count > 0 {
                for i in node.left_or_first..node.left_or_first + node.count {
                    let prim = self.prim_refs[i as usize];
                    if let Some(t) = hit_prim(prim, closest) {
                        if t < closest {
                            closest = t;
                            found = Some((prim, t));
                            if any_hit {
                                return found;
                            }
                        }
                    }
                }
            } else {
                let mut a = node_index + 1;
                let mut b = node.left_or_first;
                let mut ta = box_entry(&self.nodes[a as usize], o, inv_d, tmin, closest);
                let mut tb = box_entry(&self.nodes[b as usize], o, inv_d, tmin, closest);
                if ta > tb {
                    std::mem::swap(&mut ta, &mut tb);
                    std::mem::swap(&mut a, &mut b);
                }
                if ta != f32::INFINITY {
                    // The builder caps depth, so the stack cannot be full here.
                    if tb != f32::INFINITY && sp < STACK_SIZE {
                        stack[sp] = b;
                        sp += 1;
                    }
                    node_index = a;
                    continue;
                }
            }
            // Pop the next node the ray still enters before the closest hit.
            let mut next = false;
            while sp > 0 {
                sp -= 1;
                let candidate = stack[sp];
                if box_entry(&self.nodes[candidate as usize], o, inv_d, tmin, closest)
                    != f32::INFINITY
                {
                    node_index = candidate;
                    next = true;
                    break;
                }
            }
            if !next {
                return found;
            }
        }
    }
}

/// Decides how to split a node's primitives `prims` (surface area `node_area`,
/// centroid bounds `cmin..cmax`): `None` for a leaf, or the size of the first child
/// after reordering `prims` so that it comes first.
fn choose_split(
    prims: &mut [BuildPrim],
    node_area: f32,
    cmin: Vec3A,
    cmax: Vec3A,
    depth: u32,
    max_depth: u32,
) -> Option<u32> {
    let count = prims.len() as u32;
    if count <= MIN_LEAF_SIZE {
        return None;
    }
    // Finite and non-negative: centroids are finite.
    let extent = cmax - cmin;
    // Children of an SAH split may hold up to count - 1 primitives; past the depth
    // budget for that, median splits (which halve) still reach leaves in time.
    let sah_allowed = depth + 1 + median_levels(count - 1) <= max_depth;
    if extent.max_element() <= 0.0 || !sah_allowed {
        if count <= MAX_LEAF_SIZE {
            return None;
        }
        if extent.max_element() > 0.0 {
            let axis = if extent.x >= extent.y && extent.x >= extent.z {
                0
            } else if extent.y >= extent.z {
                1
            } else {
                2
            };
            let key = |p: &BuildPrim| (p.centroid[axis], p.index);
            prims.select_nth_unstable_by(prims.len() / 2, |x, y| {
                key(x).partial_cmp(&key(y)).expect("finite centroids")
            });
        }
        // Coincident centroids: any halving is as good as another; keep the order.
        return Some(count / 2);
    }

    // Binned SAH, all three axes in one pass. Axes with no extent get scale 0 (all in
    // bin 0) and are skipped in the sweep.
    let scale = Vec3A::select(
        extent.cmpgt(Vec3A::ZERO),
        Vec3A::splat(SAH_BINS as f32) / extent,
        Vec3A::ZERO,
    );
    let mut bins = [[Bin::EMPTY; SAH_BINS]; 3];
    for p in prims.iter() {
        let b = bins_of(p.centroid.into(), cmin, scale);
        for axis in 0..3 {
            let bin = &mut bins[axis][b[axis]];
            bin.min = bin.min.min(p.min);
            bin.max = bin.max.max(p.max);
            bin.count += 1;
        }
    }
    // Costs are scaled by the node's area so a flat node (area 0) needs no division.
    let mut best_cost = f32::INFINITY;
    let mut best_axis = 0;
    let mut best_plane = 0; // bins [0, plane] go left
    for (axis, bins) in bins.iter().enumerate() {
        if extent[axis] <= 0.0 {
            continue;
        }
        // Right-to-left sweep: cost of the right side of each plane.
        let mut right_cost = [0.0f32; SAH_BINS];
        let (mut min, mut max, mut acc_count) = (Vec3A::INFINITY, Vec3A::NEG_INFINITY, 0u32);
        for plane in (1..SAH_BINS).rev() {
            min = min.min(bins[plane].min);
            max = max.max(bins[plane].max);
            acc_count += bins[plane].count;
            right_cost[plane - 1] = if acc_count > 0 {
                area(min, max) * acc_count as f32
            } else {
                f32::INFINITY
            };
        }
        let (mut min, mut max, mut acc_count) = (Vec3A::INFINITY, Vec3A::NEG_INFINITY, 0u32);
        for (plane, right) in right_cost.iter().enumerate().take(SAH_BINS - 1) {
            min = min.min(bins[plane].min);
            max = max.max(bins[plane].max);
            acc_count += bins[plane].count;
            if acc_count == 0 {
                continue;
            }
            let cost = area(min, max) * acc_count as f32 + right;
            if cost < best_cost {
                best_cost = cost;
                best_axis = axis;
                best_plane = plane;
            }
        }
    }
    let split_cost = TRAVERSAL_COST * node_area + INTERSECTION_COST * best_cost;
    let leaf_cost = INTERSECTION_COST * count as f32 * node_area;
    if count <= MAX_LEAF_SIZE && leaf_cost <= split_cost {
        return None;
    }

    // Partition in place: primitives in bins [0, best_plane] first.
    let goes_left =
        |p: &BuildPrim| bins_of(p.centroid.into(), cmin, scale)[best_axis] <= best_plane;
    let (mut i, mut j) = (0usize, prims.len());
    while i < j {
        if goes_left(&prims[i]) {
            i += 1;
        } else {
            j -= 1;
            prims.swap(i, j);
        }
    }
    debug_assert!(i > 0 && i < prims.len());
    Some(i as u32)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::geometry::triangle_bounds;
    use crate::accel::testing::{
        check_against_brute_force as check_rays, coincident_and_cluster_cases,
        far_from_origin_case, impl_traversal, mixed_cases, random_triangles, soup_bounds,
        soup_cases, Prim, Rng,
    };

    use std::time::Instant;

    impl_traversal!(Bvh);

    /// Builds the BVH, checks its structure, and checks rays against brute force.
    fn check_against_brute_force(prims: &[Prim], rays: usize, seed: u64) {
        let bounds: Vec<Aabb> = prims.iter().map(Prim::bounds).collect();
        let bvh = Bvh::build(&bounds);
        check_structure(&bvh, &bounds, MAX_DEPTH);
        check_rays(&bvh, prims, rays, seed);
    }

    /// Structural invariants: a permutation of primitives in leaves, one leaf each,
    /// nested boxes, leaf sizes within the cap, depth within the stack, every node
    /// reachable.
    fn check_structure(bvh: &Bvh, bounds: &[Aabb], max_depth: u32) {
        let n = bounds.len();
        assert_eq!(bvh.prim_refs.len(), n);
        if n == 0 {
            assert_eq!(bvh.nodes.len(), 1);
            assert!(bvh.nodes[0].bounds().is_empty());
            assert_eq!(bvh.nodes[0].count, 0);
            return;
        }
        let mut seen = vec![0u32; n];
        let mut covered = vec![false; n];
        let mut visited = 0usize;
        let mut stack = vec![(0u32, 0u32)];
        while let Some((index, depth)) = stack.pop() {
            visited += 1;
            assert!(depth <= max_depth, "depth {depth}");
            let node = bvh.nodes[index as usize];
            let b = node.bounds();
            assert!(!b.is_empty());
            if node.is_leaf() {
                assert!(node.count <= MAX_LEAF_SIZE);
                for i in node.left_or_first..node.left_or_first + node.count {
                    assert!(!covered[i as usize], "prim_refs slot {i} in two leaves");
                    covered[i as usize] = true;
                    let p = bvh.prim_refs[i as usize] as usize;
                    seen[p] += 1;
                    assert!(b.contains(&bounds[p]));
                }
            } else {
                let (l, r) = (index + 1, node.left_or_first);
                assert!(r > l && (r as usize) < bvh.nodes.len());
                for c in [l, r] {
                    assert!(b.contains(&bvh.nodes[c as usize].bounds()));
                    stack.push((c, depth + 1));
                }
            }
        }
        assert_eq!(visited, bvh.nodes.len(), "unreachable nodes");
        assert!(
            seen.iter().all(|&s| s == 1),
            "a primitive not in exactly one leaf"
        );
        assert!(covered.iter().all(|&c| c));
    }

    #[test]
    fn empty_scene_never_hits() {
        let bvh = Bvh::build(&[]);
        check_structure(&bvh, &[], MAX_DEPTH);
        let mut calls = 0;
        let hit = bvh.closest_hit(Vec3::ZERO, Vec3::X, 0.0, f32::INFINITY, |_, _| {
            calls += 1;
            Some(1.0)
        });
        assert_eq!(hit, None);
        assert!(!bvh.any_hit(Vec3::ZERO, Vec3::X, 0.0, f32::INFINITY, |_, _| Some(1.0)));
        assert_eq!(calls, 0);
    }

    #[test]
    fn triangle_soups_match_brute_force() {
        for (prims, rays, seed) in soup_cases(&mut Rng(1)) {
            check_against_brute_force(&prims, rays, seed);
        }
    }

    #[test]
    fn mixed_spheres_and_triangles_match_brute_force() {
        for (prims, rays, seed) in mixed_cases(&mut Rng(2)) {
            check_against_brute_force(&prims, rays, seed);
        }
    }

    #[test]
    fn coincident_and_extreme_inputs_match_brute_force() {
        for (prims, rays, seed) in coincident_and_cluster_cases(&mut Rng(3)) {
            check_against_brute_force(&prims, rays, seed);
        }
    }

    #[test]
    fn far_from_origin_matches_brute_force() {
        let (prims, rays, seed) = far_from_origin_case(&mut Rng(29));
        check_against_brute_force(&prims, rays, seed);
    }

    #[test]
    fn depth_cap_forces_median_splits() {
        let mut rng = Rng(4);
        let prims = random_triangles(&mut rng, 3000, 10.0);
        let bounds: Vec<Aabb> = prims.iter().map(Prim::bounds).collect();
        // 3000 primitives need 8 levels of halving to reach leaves of 16.
        for max_depth in [8, 9, 12] {
            let bvh = Bvh::build_with(&bounds, max_depth, 2, PARALLEL_PRIMS);
            check_structure(&bvh, &bounds, max_depth);
        }
        // A chain-like distribution stays within the real cap too.
        let chain: Vec<Aabb> = (0..4000)
            .map(|i| {
                let c = Vec3::new(1.004f32.powi(i), 0.0, 0.0);
                Aabb {
                    min: c - 0.001,
                    max: c + 0.001,
                }
            })
            .collect();
        check_structure(&Bvh::build(&chain), &chain, MAX_DEPTH);
    }

    /// Subtrees built on several threads make the tree the serial build makes, node for
    /// node (mutation: the second subtree's nodes not moved past the first's fails it).
    #[test]
    fn a_parallel_build_is_the_serial_build() {
        let bounds = soup_bounds(9, 20_000, 300);
        let serial = Bvh::build_with(&bounds, MAX_DEPTH, 1, usize::MAX);
        for threads in [2, 3, 8] {
            let parallel = Bvh::build_with(&bounds, MAX_DEPTH, threads, 64);
            assert!(parallel == serial, "{threads} threads");
        }
        check_structure(&serial, &bounds, MAX_DEPTH);
    }

    #[test]
    fn build_is_deterministic() {
        let bounds = soup_bounds(5, 5000, 100);
        assert_eq!(Bvh::build(&bounds), Bvh::build(&bounds));
    }

    #[test]
    fn sah_root_splits_between_clusters() {
        let mut rng = Rng(6);
        let mut bounds = Vec::new();
        for i in 0..1000 {
            let centre = if i % 2 == 0 { -100.0 } else { 100.0 };
            let c = Vec3::new(centre, 0.0, 0.0) + rng.vec3(-5.0, 5.0);
            bounds.push(triangle_bounds([
                c + rng.vec3(-0.5, 0.5),
                c + rng.vec3(-0.5, 0.5),
                c + rng.vec3(-0.5, 0.5),
            ]));
        }
        let bvh = Bvh::build(&bounds);
        let root = bvh.nodes[0];
        assert!(!root.is_leaf());
        let (a, b) = (
            bvh.nodes[1].bounds(),
            bvh.nodes[root.left_or_first as usize].bounds(),
        );
        let (neg, pos) = if a.min.x < b.min.x { (a, b) } else { (b, a) };
        assert!(neg.max.x < -90.0 && pos.min.x > 90.0, "{neg:?} {pos:?}");
    }

    #[test]
    fn leaf_policy_follows_sah() {
        // Four or fewer primitives: one leaf.
        let b = triangle_bounds([Vec3::ZERO, Vec3::X, Vec3::Y]);
        assert_eq!(Bvh::build(&[b; 4]).nodes.len(), 1);
        // Sixteen overlapping primitives: splitting cannot pay, one leaf.
        assert_eq!(Bvh::build(&[b; 16]).nodes.len(), 1);
        // Seventeen coincident ones exceed the cap: split at the median.
        let bvh = Bvh::build(&[b; 17]);
        assert_eq!(bvh.nodes.len(), 3);
        assert_eq!((bvh.nodes[1].count, bvh.nodes[2].count), (8, 9));
        // Eight small far-apart primitives: splitting pays.
        let spread: Vec<Aabb> = (0..8)
            .map(|i| Aabb {
                min: Vec3::splat(10.0 * i as f32),
                max: Vec3::splat(10.0 * i as f32 + 0.1),
            })
            .collect();
        assert!(Bvh::build(&spread).nodes.len() > 1);
    }

    #[test]
    fn box_entry_handles_parallel_rays() {
        let node = BvhNode {
            min: [0.0, 0.0, 0.0],
            left_or_first: 0,
            max: [1.0, 1.0, 1.0],
            count: 1,
        };
        let inf = f32::INFINITY;
        // Parallel to x, origin on the min-y and min-z faces: inside the slabs.
        let o = Vec3::new(-1.0, 0.0, 0.0);
        let t = box_entry(&node, o, safe_inverse(Vec3::X), 0.0, inf);
        assert_eq!(t, 1.0);
        // Same with negative zeros in the direction.
        let t = box_entry(&node, o, safe_inverse(Vec3::new(1.0, -0.0, -0.0)), 0.0, inf);
        assert_eq!(t, 1.0);
        // Parallel outside a slab: miss.
        let o = Vec3::new(-1.0, -0.001, 0.5);
        assert_eq!(box_entry(&node, o, safe_inverse(Vec3::X), 0.0, inf), inf);
        // Origin inside: entry at tmin.
        let o = Vec3::splat(0.5);
        assert_eq!(box_entry(&node, o, safe_inverse(Vec3::Y), 0.25, inf), 0.25);
        // Box behind the ray, or beyond tmax.
        let o = Vec3::new(2.0, 0.5, 0.5);
        assert_eq!(box_entry(&node, o, safe_inverse(Vec3::X), 0.0, inf), inf);
        assert_eq!(box_entry(&node, o, safe_inverse(-Vec3::X), 0.0, 0.5), inf);
        assert_eq!(box_entry(&node, o, safe_inverse(-Vec3::X), 0.0, 1.0), 1.0);
        // A flat box (zero thickness in z) hit head-on.
        let flat = BvhNode {
            max: [1.0, 1.0, 0.0],
            ..node
        };
        let o = Vec3::new(0.5, 0.5, 3.0);
        assert_eq!(box_entry(&flat, o, safe_inverse(-Vec3::Z), 0.0, inf), 3.0);
    }

    /// A closed, bumpy, finely tessellated surface: a stand-in for a scanned model.
    fn tessellated_blob(rings: usize, segments: usize) -> Vec<Aabb> {
        let point = |i: usize, j: usize| {
            let theta = std::f32::consts::PI * i as f32 / rings as f32;
            let phi = std::f32::consts::TAU * j as f32 / segments as f32;
            let r = 1.0 + 0.2 * (5.0 * theta).sin() * (7.0 * phi).cos();
            r * Vec3::new(
                theta.sin() * phi.cos(),
                theta.cos(),
                theta.sin() * phi.sin(),
            )
        };
        let mut bounds = Vec::with_capacity(2 * rings * segments);
        for i in 0..rings {
            for j in 0..segments {
                let (a, b) = (point(i, j), point(i + 1, j));
                let (c, d) = (point(i + 1, j + 1), point(i, j + 1));
                bounds.push(triangle_bounds([a, b, c]));
                bounds.push(triangle_bounds([a, c, d]));
            }
        }
        bounds
    }

    /// Not a timed assertion: prints build times (see them with `--nocapture`).
    #[test]
    fn build_time_100k_triangles() {
        let mut rng = Rng(8);
        let soup: Vec<Aabb> = random_triangles(&mut rng, 100_000, 10.0)
            .iter()
            .map(Prim::bounds)
            .collect();
        let blob = tessellated_blob(250, 200);
        for (name, bounds) in [("random soup", &soup), ("tessellated surface", &blob)] {
            let start = Instant::now();
            let bvh = Bvh::build(bounds);
            let elapsed = start.elapsed();
            eprintln!(
                "bvh build, {name}: {} triangles, {} nodes, {:.1} ms",
                bounds.len(),
                bvh.nodes.len(),
                elapsed.as_secs_f64() * 1e3
            );
            check_structure(&bvh, bounds, MAX_DEPTH);
        }
    }
}

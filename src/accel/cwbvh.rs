//! The compressed 8-wide BVH (Ylitie, Karras & Laine 2017, "Efficient Incoherent Ray
//! Traversal on GPUs Through Compressed Wide BVHs") that the kernels traverse from a
//! storage buffer (`glsl/lib/trace_cwbvh.glsl`), and its CPU traversal mirror.
//!
//! The tree comes from the `obvhs` crate: PLOC (Meister & Bittner 2018) with parallel
//! reinsertion (its "slow" preset, without spatial splits), collapsed from a binary tree to eight-wide nodes by the paper's
//! SAH-cost dynamic program, children ordered so that a ray's octant gives a
//! near-to-far visiting order, at most three primitives per leaf.
//!
//! Node layout (80 bytes, obvhs's [`obvhs::cwbvh::node::CwBvhNode`]): the node's
//! origin `p`, one power-of-two scale `e` per axis (its exponent bits), the mask of
//! internal children, the first child node and first primitive reference, one meta
//! byte per child slot, and each child's box quantized to 8 bits per plane.
//!
//! **Conservative boxes.** obvhs quantizes with `floor`/`ceil` of rounded arithmetic
//! and a `log2` estimate of the scale, which can leave a child box an ulp short of
//! its primitives. Here every node is requantized from the exact (`f32`) boxes of its
//! children so that every plane `p + q 2^e`, in real arithmetic, contains them (checked
//! exactly, with TwoSum). The kernels meet those planes by the paper's transformed ray
//! with a bounded widening (see [`intersect_node`]), so no box a ray meets is missed.
//!
//! Traversal (CPU and GPU, the paper's algorithm 1 without triangle postponing): a
//! stack of node groups (a base child index and a hit mask whose top byte holds the
//! internal children left to visit, ordered by the ray octant) and a current primitive
//! group (the base primitive reference and a 24-bit mask of primitives left to test).

use super::bvh::{safe_inverse, SLAB_EXIT_SCALE};
pub use super::geometry::Aabb;
use glam::Vec3;
use obvhs::cwbvh::node::CwBvhNode;

/// Node groups the traversal stack holds (CPU and GPU: `CWBVH_STACK_SIZE`). A node
/// pushes at most one group, so this bounds the depth of the tree.
pub const STACK_SIZE: usize = 32;

/// Largest leaf obvhs makes (its meta byte encodes the count in unary, 3 bits).
pub const MAX_LEAF_SIZE: u32 = 3;

#[derive(Clone, Debug, PartialEq)]
pub struct Cwbvh {
    /// Root at 0. An empty scene is one node with no children.
    pub nodes: Vec<CwBvhNode>,
    /// Leaves index this; its values are primitive indices into the build input.
    pub prim_refs: Vec<u32>,
}

const _: () = assert!(std::mem::size_of::<CwBvhNode>() == 80);

/// What sits in one child slot of a node.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Child {
    /// Index of the child node.
    Node(u32),
    /// `prim_refs[first..first + count]`.
    Leaf { first: u32, count: u32 },
}

/// The child in `slot` of `node`, `None` for an empty slot.
pub fn child(node: &CwBvhNode, slot: usize) -> Option<Child> {
    let meta = node.child_meta[slot];
    if meta == 0 {
        return None;
    }
    if node.imask & (1 << slot) != 0 {
        let below = (node.imask as u32 & ((1u32 << slot) - 1)).count_ones();
        Some(Child::Node(node.child_base_idx + below))
    } else {
        Some(Child::Leaf {
            first: node.primitive_base_idx + (meta & 0x1f) as u32,
            count: (meta >> 5).count_ones(),
        })
    }
}

/// Plane `q` of axis scale `e` (its float exponent bits) from origin `p`, rounded to
/// f32 once (`q 2^e` is exact). The kernels do not form it: their box test measures
/// from `p` along the ray (see [`intersect_node`]); this is for inspecting boxes.
pub fn decode(q: u8, e: u8, p: f32) -> f32 {
    (q as f32).mul_add(f32::from_bits((e as u32) << 23), p)
}

/// The (conservative) box of `slot`, its planes rounded to f32 by [`decode`].
pub fn child_box(node: &CwBvhNode, slot: usize) -> Aabb {
    let d = |q: u8, a: usize| decode(q, node.e[a], node.p[a]);
    Aabb {
        min: Vec3::new(
            d(node.child_min_x[slot], 0),
            d(node.child_min_y[slot], 1),
            d(node.child_min_z[slot], 2),
        ),
        max: Vec3::new(
            d(node.child_max_x[slot], 0),
            d(node.child_max_y[slot], 1),
            d(node.child_max_z[slot], 2),
        ),
    }
}

/// Re-encodes `node` from the exact boxes of its children (`child_box` of each), and
/// returns its own exact box, their union (an empty node is left as it is).
pub(super) fn requantize_node(node: &mut CwBvhNode, child_box: impl Fn(Child) -> Aabb) -> Aabb {
    let mut boxes = [Aabb::empty(); 8];
    for (slot, b) in boxes.iter_mut().enumerate() {
        if let Some(c) = child(node, slot) {
            *b = child_box(c);
        }
    }
    let whole = boxes.iter().fold(Aabb::empty(), |a, b| a.union(*b));
    if whole.is_empty() {
        return whole;
    }
    node.p = whole.min;
    for a in 0..3 {
        node.e[a] = scale_exponent(whole.min[a], whole.max[a]);
    }
    let (p, e) = (node.p, node.e);
    for (slot, b) in boxes.iter().enumerate() {
        if b.is_empty() {
            continue;
        }
        node.child_min_x[slot] = quantize_down(b.min.x, e[0], p.x);
        node.child_min_y[slot] = quantize_down(b.min.y, e[1], p.y);
        node.child_min_z[slot] = quantize_down(b.min.z, e[2], p.z);
        node.child_max_x[slot] = quantize_up(b.max.x, e[0], p.x);
        node.child_max_y[slot] = quantize_up(b.max.y, e[1], p.y);
        node.child_max_z[slot] = quantize_up(b.max.z, e[2], p.z);
    }
    whole
}

/// Re-encodes every node of a tree whose children come after their parents (the order
/// `super::collapse` and `super::clusters`'s join lay nodes out in) from the exact boxes
/// of its children, the last node first: a leaf's box is the union of `leaf_box` of its
/// references. Returns the root's exact box. Each node's encoding depends on its
/// children's boxes alone, so a tree requantized in pieces (each cluster's, then the
/// nodes above them) is the tree requantized whole.
pub(super) fn requantize_tree(
    nodes: &mut [CwBvhNode],
    prim_refs: &[u32],
    leaf_box: impl Fn(u32) -> Aabb,
) -> Aabb {
    let mut exact = vec![Aabb::empty(); nodes.len()];
    for i in (0..nodes.len()).rev() {
        exact[i] = requantize_node(&mut nodes[i], |c| match c {
            Child::Node(c) => {
                debug_assert!(c as usize > i, "a child before its parent");
                exact[c as usize]
            }
            Child::Leaf { first, count } => (first..first + count)
                .map(|r| leaf_box(prim_refs[r as usize]))
                .fold(Aabb::empty(), Aabb::union),
        });
    }
    exact.first().copied().unwrap_or(Aabb::empty())
}

/// The scale of exponent bits `e`, 2^(e - 127).
fn step(e: u8) -> f64 {
    f32::from_bits((e as u32) << 23) as f64
}

/// `a` and `r` with `a + r = x + y` exactly (Knuth's TwoSum).
fn two_sum(x: f64, y: f64) -> (f64, f64) {
    let s = x + y;
    let yy = s - x;
    (s, (x - (s - yy)) + (y - yy))
}

/// `offset <= v - p` in real arithmetic (`offset` exact in f64; `v - p` is kept exact
/// as a TwoSum pair, so this holds even where their exponents are far apart). (The
/// tests' reference: the closed-form quantization is checked against it.)
#[cfg(test)]
fn at_most(offset: f64, v: f32, p: f32) -> bool {
    let (s, r) = two_sum(v as f64, -(p as f64));
    offset < s || (offset == s && r >= 0.0)
}

/// `offset >= v - p` in real arithmetic.
fn at_least(offset: f64, v: f32, p: f32) -> bool {
    let (s, r) = two_sum(v as f64, -(p as f64));
    offset > s || (offset == s && r <= 0.0)
}

/// The smallest power-of-two scale (as float exponent bits, at least 1 so that it is
/// a normal float) whose 255th step from `p` reaches `max`, in real arithmetic.
fn scale_exponent(p: f32, max: f32) -> u8 {
    let need = (max as f64 - p as f64) / 255.0;
    let mut bits: i32 = if need > 0.0 {
        (need.log2().ceil() as i32 + 127).clamp(1, 254)
    } else {
        1
    };
    while bits > 1 && at_least(255.0 * step((bits - 1) as u8), max, p) {
        bits -= 1;
    }
    while bits < 254 && !at_least(255.0 * step(bits as u8), max, p) {
        bits += 1;
    }
    bits as u8
}

/// Largest `q` whose plane `p + q 2^e` (real arithmetic) is at or below `v`
/// (`q = 0` is: `p <= v`).
///
/// `v - p` is TwoSum's pair `s + r`, and `s / 2^e` is exact (a power of two), so its
/// floor is the answer but where the plane meets `s` exactly and the remainder `r` puts
/// `v` below it: then one step down. (The search this replaced — step down while the
/// plane is above `v`, up while the next is not — gives the same `q` in every case;
/// `quantize_matches_search` checks it.)
fn quantize_down(v: f32, e: u8, p: f32) -> u8 {
    let (s, r) = two_sum(v as f64, -(p as f64));
    let step = step(e);
    let q = (s / step).floor().clamp(0.0, 255.0) as u8;
    if q > 0 && q as f64 * step == s && r < 0.0 {
        q - 1
    } else {
        q
    }
}

/// Smallest `q` whose plane is at or above `v` (`q = 255` is, by the scale's choice):
/// the ceiling of `(v - p) / 2^e`, one step up where the plane meets `s` exactly and `r`
/// puts `v` above it (as [`quantize_down`]; a NaN difference gives 255, as the search did).
fn quantize_up(v: f32, e: u8, p: f32) -> u8 {
    let (s, r) = two_sum(v as f64, -(p as f64));
    if s.is_nan() {
        return 255;
    }
    let step = step(e);
    let q = (s / step).ceil().clamp(0.0, 255.0) as u8;
    if q < 255 && q as f64 * step == s && r > 0.0 {
        q + 1
    } else {
        q
    }
}

impl Cwbvh {
    /// Builds the tree over primitives whose bounds are `bounds[i]`. Deterministic.
    pub fn build(bounds: &[Aabb]) -> Cwbvh {
        Cwbvh::build_in_clusters(bounds, super::clusters::CLUSTER_SIZE, super::threads())
    }

    /// [`Cwbvh::build`] with clusters of at most `cluster_size` primitives built on
    /// `threads` threads (tests make small scenes of many clusters).
    pub(crate) fn build_in_clusters(bounds: &[Aabb], cluster_size: usize, threads: usize) -> Cwbvh {
        if bounds.is_empty() {
            return Cwbvh {
                nodes: vec![CwBvhNode::default()],
                prim_refs: Vec::new(),
            };
        }
        // obvhs's "slow" preset (wider PLOC search, 128-bit Morton keys, reinsertion of
        // 20% of the nodes) traces the dragon 1.42x faster than its "medium" one and as
        // fast as "very slow" (docs/visibility.md, "What was tried on the compressed BVH"); 100k triangles build in ~0.25 s.
        // Without spatial splits: each primitive is referenced once.
        // Large inputs are built in clusters on every core (super::clusters).
        let mut params = obvhs::BvhBuildParams::slow_build();
        params.pre_split = false;
        // Its nodes requantized (see the module docs) as the clusters are built.
        let (nodes, prim_refs) =
            super::clusters::build(bounds, params, MAX_LEAF_SIZE, cluster_size, threads);
        Cwbvh { nodes, prim_refs }
    }

    /// Depth of the tree (the root alone is 1).
    pub fn depth(&self) -> usize {
        let mut max = 0;
        let mut stack = vec![(0u32, 1usize)];
        while let Some((i, d)) = stack.pop() {
            max = max.max(d);
            let node = &self.nodes[i as usize];
            for slot in 0..8 {
                if let Some(Child::Node(c)) = child(node, slot) {
                    stack.push((c, d + 1));
                }
            }
        }
        max
    }

    /// Closest hit along `o + t d` with `t` in `(tmin, tmax)`. `hit_prim(prim, t_max)`
    /// tests primitive `prim` (an index into the build input) and returns its hit
    /// distance, which must be below `t_max`. Returns the primitive and distance.
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

    /// The kernels' loop, line for line (see `bvh_traverse` in trace_cwbvh.glsl).
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
        let oct_inv4 = octant_inv4(d);
        let mut stack = [(0u32, 0u32); STACK_SIZE];
        let mut sp = 0usize;
        // The root, as the one internal child of a virtual node: bit 31 is slot 7 ^ 7.
        let mut node_group = (0u32, 0x8000_0000u32);
        let mut prim_group = (0u32, 0u32);
        let mut closest = tmax;
        let mut found = None;
        loop {
            while prim_group.1 != 0 {
                let bit = 31 - prim_group.1.leading_zeros();
                prim_group.1 &= !(1u32 << bit);
                let prim = self.prim_refs[(prim_group.0 + bit) as usize];
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
            if node_group.1 & 0xff00_0000 != 0 {
                let hits = node_group.1;
                let bit = 31 - hits.leading_zeros();
                node_group.1 &= !(1u32 << bit);
                if node_group.1 & 0xff00_0000 != 0 {
                    stack[sp] = node_group;
                    sp += 1;
                }
                let slot = (bit - 24) ^ (oct_inv4 & 0xff);
                let relative = (hits & !(0xffff_ffffu32 << slot)).count_ones();
                let index = node_group.0 + relative;
                let node = &self.nodes[index as usize];
                let hitmask = intersect_node(node, o, inv_d, oct_inv4, tmin, closest);
                node_group = (
                    node.child_base_idx,
                    (hitmask & 0xff00_0000) | node.imask as u32,
                );
                prim_group = (node.primitive_base_idx, hitmask & 0x00ff_ffff);
            }
            if prim_group.1 == 0 && node_group.1 & 0xff00_0000 == 0 {
                if sp == 0 {
                    return found;
                }
                sp -= 1;
                node_group = stack[sp];
            }
        }
    }
}

/// The ray octant, inverted, in each byte: children are stored so that slot `s ^ oct`
/// orders them near to far (obvhs's convention).
pub fn octant_inv4(d: Vec3) -> u32 {
    (if d.x < 0.0 { 0 } else { 0x0404_0404 })
        | (if d.y < 0.0 { 0 } else { 0x0202_0202 })
        | (if d.z < 0.0 { 0 } else { 0x0101_0101 })
}

/// Widening of each axis's entry and exit distances, in units of `|(p - o) / d|`: at
/// least the error of that quotient's two roundings (2 eps) plus one of the widening
/// itself, with room to spare (eps = 2^-24).
pub const TRANSFORMED_RAY_SLACK: f32 = 5.0 * 5.960_464_5e-8;

/// The hit mask of a node's children whose boxes the ray enters within
/// `[tmin, tmax]`: internal children set bit `24 + (slot ^ octant)`, leaves set one
/// bit per primitive at their offset from the node's first primitive.
///
/// The paper's transformed ray: plane `q` of an axis is met at `t = q (2^e / d) +
/// (p - o) / d`, one `fma` per plane, with the near and far plane of each axis chosen
/// once per node by the sign of `d`. `2^e / d` is exact; `(p - o) / d` is off by at
/// most 2 eps of itself, so the near planes start from it lowered and the far planes
/// from it raised by [`TRANSFORMED_RAY_SLACK`] of it; what remains is relative error
/// (the `fma`, the reciprocal), which the exit scale of the slab test covers. With the
/// requantized planes containing every child exactly, no box the ray meets is missed.
pub fn intersect_node(
    node: &CwBvhNode,
    o: Vec3,
    inv_d: Vec3,
    oct_inv4: u32,
    tmin: f32,
    tmax: f32,
) -> u32 {
    let scale = Vec3::new(
        f32::from_bits((node.e[0] as u32) << 23),
        f32::from_bits((node.e[1] as u32) << 23),
        f32::from_bits((node.e[2] as u32) << 23),
    );
    let big_e = scale * inv_d;
    let big_p = (node.p - o) * inv_d;
    let slack = big_p.abs() * TRANSFORMED_RAY_SLACK;
    let (p_near, p_far) = (big_p - slack, big_p + slack);
    let planes = [
        (&node.child_min_x, &node.child_max_x),
        (&node.child_min_y, &node.child_max_y),
        (&node.child_min_z, &node.child_max_z),
    ];
    let mut hitmask = 0u32;
    let meta8 = u64::from_le_bytes(node.child_meta);
    for half in 0..2 {
        let meta4 = (meta8 >> (32 * half)) as u32;
        let is_inner4 = (meta4 & (meta4 << 1)) & 0x1010_1010;
        let inner_mask4 = (is_inner4 >> 4) * 0xff;
        let bit_index4 = (meta4 ^ (oct_inv4 & inner_mask4)) & 0x1f1f_1f1f;
        let child_bits4 = (meta4 >> 5) & 0x0707_0707;
        for j in 0..4 {
            let slot = 4 * half + j;
            let mut t_near = Vec3::ZERO;
            let mut t_far = Vec3::ZERO;
            for a in 0..3 {
                let (lo, hi) = (planes[a].0[slot] as f32, planes[a].1[slot] as f32);
                let (qn, qf) = if inv_d[a] < 0.0 { (hi, lo) } else { (lo, hi) };
                t_near[a] = qn.mul_add(big_e[a], p_near[a]);
                t_far[a] = qf.mul_add(big_e[a], p_far[a]);
            }
            let enter = t_near.x.max(t_near.y).max(t_near.z.max(tmin));
            let leave = (t_far.x.min(t_far.y).min(t_far.z) * SLAB_EXIT_SCALE).min(tmax);
            if enter <= leave {
                let shift = 8 * j as u32;
                let bits = (child_bits4 >> shift) & 7;
                let index = (bit_index4 >> shift) & 31;
                hitmask |= bits << index;
            }
        }
    }
    hitmask
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::testing::{
        check_against_brute_force as check_rays, coincident_and_cluster_cases,
        far_from_origin_case, impl_traversal, mixed_cases, random_triangles, soup_bounds,
        soup_cases, Prim, Rng,
    };

    impl_traversal!(Cwbvh);

    /// Structural invariants: every primitive in exactly one leaf, leaves within the
    /// size cap, every node reachable once, depth within the stack, and every decoded
    /// child box containing the exact boxes of all primitives below it.
    fn check_structure(bvh: &Cwbvh, bounds: &[Aabb]) {
        fn subtree(
            bvh: &Cwbvh,
            i: u32,
            bounds: &[Aabb],
            seen: &mut [u32],
            visited: &mut [u32],
        ) -> Aabb {
            visited[i as usize] += 1;
            let node = &bvh.nodes[i as usize];
            let mut all = Aabb::empty();
            for slot in 0..8 {
                let Some(c) = child(node, slot) else { continue };
                let exact = match c {
                    Child::Node(n) => subtree(bvh, n, bounds, seen, visited),
                    Child::Leaf { first, count } => {
                        assert!((1..=MAX_LEAF_SIZE).contains(&count));
                        let mut b = Aabb::empty();
                        for r in first..first + count {
                            let p = bvh.prim_refs[r as usize] as usize;
                            seen[p] += 1;
                            b = b.union(bounds[p]);
                        }
                        b
                    }
                };
                let decoded = child_box(node, slot);
                assert!(
                    decoded.contains(&exact),
                    "node {i} slot {slot}: {decoded:?} does not hold {exact:?}"
                );
                all = all.union(exact);
            }
            all
        }
        assert_eq!(bvh.prim_refs.len(), bounds.len());
        let mut seen = vec![0u32; bounds.len()];
        let mut visited = vec![0u32; bvh.nodes.len()];
        subtree(bvh, 0, bounds, &mut seen, &mut visited);
        assert!(
            visited.iter().all(|&v| v == 1),
            "a node unreachable or shared"
        );
        assert!(
            seen.iter().all(|&s| s == 1),
            "a primitive not in exactly one leaf"
        );
        assert!(bvh.depth() <= STACK_SIZE);
    }

    fn check_against_brute_force(prims: &[Prim], rays: usize, seed: u64) {
        let bounds: Vec<Aabb> = prims.iter().map(Prim::bounds).collect();
        let bvh = Cwbvh::build(&bounds);
        check_structure(&bvh, &bounds);
        check_rays(&bvh, prims, rays, seed);
    }

    #[test]
    fn empty_scene_never_hits() {
        let bvh = Cwbvh::build(&[]);
        check_structure(&bvh, &[]);
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
        for (prims, rays, seed) in soup_cases(&mut Rng(101)) {
            check_against_brute_force(&prims, rays, seed);
        }
    }

    #[test]
    fn mixed_spheres_and_triangles_match_brute_force() {
        for (prims, rays, seed) in mixed_cases(&mut Rng(102)) {
            check_against_brute_force(&prims, rays, seed);
        }
    }

    #[test]
    fn coincident_far_and_tiny_inputs_match_brute_force() {
        let mut rng = Rng(103);
        let mut cases = coincident_and_cluster_cases(&mut rng);
        cases.push(far_from_origin_case(&mut rng));
        for (prims, rays, seed) in cases {
            check_against_brute_force(&prims, rays, seed);
        }
    }

    /// The searches [`quantize_down`] and [`quantize_up`] replaced.
    fn quantize_down_by_search(v: f32, e: u8, p: f32) -> u8 {
        let mut q = (((v as f64 - p as f64) / step(e)).floor()).clamp(0.0, 255.0) as u8;
        while q > 0 && !at_most(q as f64 * step(e), v, p) {
            q -= 1;
        }
        while q < 255 && at_most((q + 1) as f64 * step(e), v, p) {
            q += 1;
        }
        q
    }

    fn quantize_up_by_search(v: f32, e: u8, p: f32) -> u8 {
        let mut q = (((v as f64 - p as f64) / step(e)).ceil()).clamp(0.0, 255.0) as u8;
        while q < 255 && !at_least(q as f64 * step(e), v, p) {
            q += 1;
        }
        while q > 0 && at_least((q - 1) as f64 * step(e), v, p) {
            q -= 1;
        }
        q
    }

    /// The closed forms give the searches' planes: random values, values on a plane
    /// (ties, where TwoSum's remainder decides), below `p`, past the 255th plane, with
    /// far-apart exponents (a remainder), and NaN.
    #[test]
    fn quantize_matches_search() {
        let mut rng = Rng(105);
        // On plane 128 of 8 from -1024, a remainder either side of it (TwoSum's r).
        let mut cases = vec![
            (f32::NAN, 120u8, 0.0f32),
            (1e-30, 130, -1024.0),
            (-1e-30, 130, -1024.0),
            (1e-30, 118, -1024.0),
        ];
        assert_eq!(quantize_down(-1e-30, 130, -1024.0), 127);
        assert_eq!(quantize_up(1e-30, 130, -1024.0), 129);
        for _ in 0..200_000 {
            let p = rng.range(-1e4, 1e4);
            let max = p + rng.range(0.0, 1.0) * 10f32.powi(rng.below(9) as i32 - 4);
            let e = scale_exponent(p, max);
            let v = match rng.below(4) {
                0 => p + (max - p) * rng.f32(),
                // On (or rounded next to) a plane.
                1 => (p as f64 + rng.below(256) as f64 * step(e)) as f32,
                2 => p - rng.range(0.0, 1.0) * (max - p),
                _ => max + rng.range(0.0, 1.0) * (max - p),
            };
            cases.push((v, e, p));
        }
        let mut ties = 0;
        for (v, e, p) in cases {
            assert_eq!(
                quantize_down(v, e, p),
                quantize_down_by_search(v, e, p),
                "{v} {e} {p}"
            );
            assert_eq!(
                quantize_up(v, e, p),
                quantize_up_by_search(v, e, p),
                "{v} {e} {p}"
            );
            let (s, _) = two_sum(v as f64, -(p as f64));
            ties += ((s / step(e)).fract() == 0.0) as usize;
        }
        assert!(ties > 10_000, "only {ties} values on a plane");
    }

    /// Requantized planes are conservative in real arithmetic (what the transformed
    /// ray measures from), the scale is the smallest that reaches, and the planes the
    /// tightest.
    #[test]
    fn quantization_is_conservative() {
        let mut rng = Rng(104);
        for _ in 0..20_000 {
            let p = rng.range(-1e4, 1e4);
            let max = p + rng.range(0.0, 1.0) * 10f32.powi(rng.below(9) as i32 - 4);
            let e = scale_exponent(p, max);
            assert!(at_least(255.0 * step(e), max, p));
            assert!(
                e == 1 || !at_least(255.0 * step(e - 1), max, p),
                "scale not the smallest"
            );
            let v = p + (max - p) * rng.f32();
            let lo = quantize_down(v, e, p);
            let hi = quantize_up(v, e, p);
            assert!(at_most(lo as f64 * step(e), v, p) && at_least(hi as f64 * step(e), v, p));
            assert!(lo == 255 || !at_most((lo + 1) as f64 * step(e), v, p));
            assert!(hi == 0 || !at_least((hi - 1) as f64 * step(e), v, p));
            // Rounded to floats, the planes still hold v.
            assert!(decode(lo, e, p) <= v && v <= decode(hi, e, p));
        }
        // Far-apart exponents: the difference is not a double, TwoSum keeps it exact.
        assert!(at_most(1024.0, 1e-30, -1024.0));
        assert!(!at_most(1024.0, -1e-30, -1024.0));
        assert!(at_least(1024.0, -1e-30, -1024.0));
    }

    /// `x = m 2^k` with an integer `m`.
    fn mantissa_exponent(x: f32) -> (i128, i32) {
        if x == 0.0 {
            return (0, 0);
        }
        let bits = x.to_bits();
        let exp = ((bits >> 23) & 0xff) as i32;
        let m = (bits & 0x7f_ffff) as i128 | if exp > 0 { 1 << 23 } else { 0 };
        let m = if x < 0.0 { -m } else { m };
        (m, exp.max(1) - 150)
    }

    /// Exact sign of `a / da - b / db` for `a`, `b` multiples of 2^-40 (as integers) and
    /// nonzero `da`, `db`.
    fn compare_quotients(a: i128, da: f32, b: i128, db: f32) -> std::cmp::Ordering {
        let (ma, ka) = mantissa_exponent(da);
        let (mb, kb) = mantissa_exponent(db);
        // a/da - b/db has the sign of (a db - b da) / (da db).
        let k = ka.min(kb);
        let lhs = a * mb * (1i128 << (kb - k));
        let rhs = b * ma * (1i128 << (ka - k));
        let c = lhs.cmp(&rhs);
        if (ma < 0) != (mb < 0) {
            c.reverse()
        } else {
            c
        }
    }

    /// The box test never misses a box that the ray, in real arithmetic, meets: rays
    /// from near and far aimed at the corners and edges of a child's box (so that about
    /// half of them meet it at a single point or a hair inside), decided exactly with
    /// integer arithmetic. Mutation check: without the slack it misses some.
    #[test]
    fn box_test_never_misses_a_box_the_ray_meets() {
        let mut rng = Rng(106);
        let fixed = |x: f64| -> i128 {
            let v = x * (1u64 << 40) as f64;
            assert_eq!(v.fract(), 0.0);
            v as i128
        };
        let (mut met, mut missed_by_test) = (0, 0);
        for _ in 0..20_000 {
            // A node and one child box, quantized as the builder does.
            let p = rng.vec3(-100.0, 100.0);
            let size = rng.vec3(0.01, 10.0) * 10f32.powi(rng.below(3) as i32);
            let mut node = CwBvhNode {
                p,
                ..Default::default()
            };
            // Often far from the node's origin corner, where (p - o) / d is large.
            let lo = p + size * rng.vec3(0.0, 0.99);
            let hi = lo + (p + size - lo) * rng.vec3(0.0, 1.0);
            for a in 0..3 {
                node.e[a] = scale_exponent(p[a], p[a] + size[a]);
            }
            node.child_meta[0] = 0b0010_0000;
            node.child_min_x[0] = quantize_down(lo.x, node.e[0], p.x);
            node.child_min_y[0] = quantize_down(lo.y, node.e[1], p.y);
            node.child_min_z[0] = quantize_down(lo.z, node.e[2], p.z);
            node.child_max_x[0] = quantize_up(hi.x, node.e[0], p.x);
            node.child_max_y[0] = quantize_up(hi.y, node.e[1], p.y);
            node.child_max_z[0] = quantize_up(hi.z, node.e[2], p.z);
            // Its real planes.
            let plane = |q: u8, a: usize| p[a] as f64 + q as f64 * step(node.e[a]);
            let bmin = [
                plane(node.child_min_x[0], 0),
                plane(node.child_min_y[0], 1),
                plane(node.child_min_z[0], 2),
            ];
            let bmax = [
                plane(node.child_max_x[0], 0),
                plane(node.child_max_y[0], 1),
                plane(node.child_max_z[0], 2),
            ];
            // Aim at a corner or an edge point, from far away.
            let mut target = Vec3::ZERO;
            for a in 0..3 {
                target[a] = match rng.below(3) {
                    0 => bmin[a] as f32,
                    1 => bmax[a] as f32,
                    _ => (bmin[a] + (bmax[a] - bmin[a]) * rng.f32() as f64) as f32,
                };
            }
            let mut d = Vec3::ZERO;
            for a in 0..3 {
                let m = rng.range(0.05, 1.0);
                d[a] = if rng.below(2) == 0 { m } else { -m };
            }
            // Near (where (p - o) / d is much larger than t) and far.
            let o = target - d * 10f32.powf(rng.range(-3.0, 2.5));
            // Exactly: entry = max over axes of the near plane's t, exit = min of the far.
            let mut entry: Option<(i128, f32)> = None;
            let mut exit: Option<(i128, f32)> = None;
            for a in 0..3 {
                let (near, far) = if d[a] > 0.0 {
                    (bmin[a], bmax[a])
                } else {
                    (bmax[a], bmin[a])
                };
                let n = fixed(near - o[a] as f64);
                let f = fixed(far - o[a] as f64);
                if entry.is_none_or(|(x, dx)| compare_quotients(n, d[a], x, dx).is_gt()) {
                    entry = Some((n, d[a]));
                }
                if exit.is_none_or(|(x, dx)| compare_quotients(f, d[a], x, dx).is_lt()) {
                    exit = Some((f, d[a]));
                }
            }
            let (en, de) = entry.unwrap();
            let (ex, dx) = exit.unwrap();
            let meets = !compare_quotients(en, de, ex, dx).is_gt()
                && !compare_quotients(ex, dx, 0, 1.0).is_lt();
            if !meets {
                continue;
            }
            met += 1;
            let inv_d = safe_inverse(d);
            let hit = intersect_node(&node, o, inv_d, octant_inv4(d), 0.0, f32::INFINITY);
            if hit == 0 {
                missed_by_test += 1;
            }
        }
        assert!(met > 5000, "only {met} rays meet their box");
        assert_eq!(
            missed_by_test, 0,
            "{missed_by_test} of {met} rays that meet a box were not reported"
        );
    }

    /// Small clusters (many of them, joined by the top tree) on three threads, with
    /// runs of coincident boxes among them: the same structure and hits as brute force.
    #[test]
    fn clustered_builds_match_brute_force() {
        let mut rng = Rng(106);
        let mut cases = soup_cases(&mut rng);
        cases.extend(mixed_cases(&mut rng));
        cases.extend(coincident_and_cluster_cases(&mut rng));
        // A run of coincident triangles longer than the run limit among others.
        let mut run = random_triangles(&mut rng, 2000, 10.0);
        run.extend(vec![Prim::Triangle([Vec3::ZERO, Vec3::X, Vec3::Y]); 3000]);
        cases.push((run, 4000, 33));
        for (prims, rays, seed) in cases {
            let bounds: Vec<Aabb> = prims.iter().map(Prim::bounds).collect();
            for cluster_size in [64, 700] {
                let bvh = Cwbvh::build_in_clusters(&bounds, cluster_size, 3);
                check_structure(&bvh, &bounds);
                check_rays(&bvh, &prims, rays, seed);
            }
        }
    }

    /// Many primitives with one box (a duplicated mesh, a stack of coincident quads)
    /// make a balanced tree: before, PLOC made 100,000 copies of a triangle in 355 s and
    /// hundreds of coincident quads into a tree deeper than the traversal stack.
    #[test]
    fn coincident_primitives_make_a_shallow_tree() {
        let quad = Aabb {
            min: Vec3::new(-1.0, -1.0, 0.0),
            max: Vec3::new(1.0, 1.0, 0.0),
        };
        let mut bounds = vec![quad; 5000];
        bounds.push(Aabb {
            min: Vec3::splat(5.0),
            max: Vec3::splat(6.0),
        });
        let bvh = Cwbvh::build(&bounds);
        check_structure(&bvh, &bounds);
        assert!(bvh.depth() <= 8, "depth {}", bvh.depth());
    }

    /// The tree depends on the input alone: not on the threads that build its clusters.
    #[test]
    fn clustered_build_does_not_depend_on_threads() {
        let mut rng = Rng(107);
        let prims = random_triangles(&mut rng, 20_000, 10.0);
        let bounds: Vec<Aabb> = prims.iter().map(Prim::bounds).collect();
        let one = Cwbvh::build_in_clusters(&bounds, 1000, 1);
        assert_eq!(one, Cwbvh::build_in_clusters(&bounds, 1000, 2));
        assert_eq!(one, Cwbvh::build_in_clusters(&bounds, 1000, 5));
        assert!(one.nodes.len() > 1000 / 4);
    }

    /// Requantizing each cluster's tree as it is built, then the nodes that join them,
    /// gives every node the bytes the whole tree requantized at once gives: a build of
    /// many clusters, its nodes' boxes wiped and requantized whole, is the same.
    #[test]
    fn requantizing_in_clusters_gives_the_whole_trees_nodes() {
        let bounds = soup_bounds(7, 20_000, 500);
        let one = Cwbvh::build_in_clusters(&bounds, 1 << 10, 2);
        let mut again = one.clone();
        for n in &mut again.nodes {
            n.p = Vec3::ZERO;
            n.e = [0; 3];
            n.child_min_x = [0; 8];
            n.child_max_y = [0; 8];
        }
        let root = requantize_tree(&mut again.nodes, &again.prim_refs, |p| bounds[p as usize]);
        let all = bounds.iter().fold(Aabb::empty(), |a, &b| a.union(b));
        assert_eq!((root.min, root.max), (all.min, all.max));
        let bytes = |b: &Cwbvh| bytemuck::cast_slice::<_, u8>(&b.nodes).to_vec();
        assert!(one.nodes.len() > 1000, "{} nodes", one.nodes.len());
        assert!(bytes(&one) == bytes(&again), "the nodes differ");
    }

    #[test]
    fn build_is_deterministic() {
        let bounds = soup_bounds(105, 5000, 100);
        assert_eq!(Cwbvh::build(&bounds), Cwbvh::build(&bounds));
    }
}

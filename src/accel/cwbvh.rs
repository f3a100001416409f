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
//! children so that the kernels' decoding, `fma(q, e, p)`, gives planes that contain
//! them: the decoded value is exact to one rounding (`q e` is exact), identical with
//! or without fused multiply-add, so the slab test then has pbrt's robustness (exit
//! distances scaled by `1 + 2 gamma(3)`) and never misses a primitive.
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

/// Decoded plane `q` of axis scale `e` (its float exponent bits) from origin `p`, as
/// the kernels compute it.
pub fn decode(q: u8, e: u8, p: f32) -> f32 {
    (q as f32).mul_add(f32::from_bits((e as u32) << 23), p)
}

/// The (conservative) box of `slot`, as the kernels decode it.
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

/// The smallest power-of-two scale (as float exponent bits, at least 1 so that it is
/// a normal float) whose 255th step from `p` reaches `max`.
fn scale_exponent(p: f32, max: f32) -> u8 {
    let need = (max as f64 - p as f64) / 255.0;
    let mut bits: i32 = if need > 0.0 {
        (need.log2().ceil() as i32 + 127).clamp(1, 254)
    } else {
        1
    };
    while bits > 1 && decode(255, (bits - 1) as u8, p) >= max {
        bits -= 1;
    }
    while bits < 254 && decode(255, bits as u8, p) < max {
        bits += 1;
    }
    bits as u8
}

/// Largest `q` whose plane is at or below `v` (`decode(0) = p <= v`).
fn quantize_down(v: f32, e: u8, p: f32) -> u8 {
    let step = f32::from_bits((e as u32) << 23) as f64;
    let mut q = (((v as f64 - p as f64) / step).floor()).clamp(0.0, 255.0) as u8;
    while q > 0 && decode(q, e, p) > v {
        q -= 1;
    }
    while q < 255 && decode(q + 1, e, p) <= v {
        q += 1;
    }
    q
}

/// Smallest `q` whose plane is at or above `v` (`decode(255) >= v`).
fn quantize_up(v: f32, e: u8, p: f32) -> u8 {
    let step = f32::from_bits((e as u32) << 23) as f64;
    let mut q = (((v as f64 - p as f64) / step).ceil()).clamp(0.0, 255.0) as u8;
    while q < 255 && decode(q, e, p) < v {
        q += 1;
    }
    while q > 0 && decode(q - 1, e, p) >= v {
        q -= 1;
    }
    q
}

impl Cwbvh {
    /// Builds the tree over primitives whose bounds are `bounds[i]`. Deterministic.
    pub fn build(bounds: &[Aabb]) -> Cwbvh {
        if bounds.is_empty() {
            return Cwbvh {
                nodes: vec![CwBvhNode::default()],
                prim_refs: Vec::new(),
            };
        }
        let boxes: Vec<obvhs::aabb::Aabb> = bounds
            .iter()
            .map(|b| obvhs::aabb::Aabb::new(b.min.into(), b.max.into()))
            .collect();
        // obvhs's "slow" preset (wider PLOC search, 128-bit Morton keys, reinsertion of
        // 20% of the nodes) traces the dragon 1.42x faster than its "medium" one and as
        // fast as "very slow" (README, "Performance"); 100k triangles build in ~0.25 s.
        // Without spatial splits: each primitive is referenced once.
        let mut params = obvhs::BvhBuildParams::slow_build();
        params.pre_split = false;
        params.max_prims_per_leaf = MAX_LEAF_SIZE;
        let built =
            obvhs::cwbvh::builder::build_cwbvh(&boxes, params, &mut std::time::Duration::default());
        let mut bvh = Cwbvh {
            nodes: built.nodes,
            prim_refs: built.primitive_indices,
        };
        bvh.requantize(bounds);
        bvh
    }

    /// Re-encodes every node from the exact boxes of its children (see the module
    /// docs): children come after their parent, so one backward sweep has them all.
    fn requantize(&mut self, bounds: &[Aabb]) {
        let mut exact = vec![Aabb::empty(); self.nodes.len()];
        for i in (0..self.nodes.len()).rev() {
            let node = self.nodes[i];
            let mut boxes = [Aabb::empty(); 8];
            for (slot, b) in boxes.iter_mut().enumerate() {
                *b = match child(&node, slot) {
                    None => Aabb::empty(),
                    Some(Child::Node(c)) => exact[c as usize],
                    Some(Child::Leaf { first, count }) => (first..first + count)
                        .map(|r| bounds[self.prim_refs[r as usize] as usize])
                        .fold(Aabb::empty(), Aabb::union),
                };
            }
            let whole = boxes.iter().fold(Aabb::empty(), |a, b| a.union(*b));
            exact[i] = whole;
            if whole.is_empty() {
                continue;
            }
            let n = &mut self.nodes[i];
            n.p = whole.min;
            for a in 0..3 {
                n.e[a] = scale_exponent(whole.min[a], whole.max[a]);
            }
            for (slot, b) in boxes.iter().enumerate() {
                if b.is_empty() {
                    continue;
                }
                let (p, e) = (n.p, n.e);
                n.child_min_x[slot] = quantize_down(b.min.x, e[0], p.x);
                n.child_min_y[slot] = quantize_down(b.min.y, e[1], p.y);
                n.child_min_z[slot] = quantize_down(b.min.z, e[2], p.z);
                n.child_max_x[slot] = quantize_up(b.max.x, e[0], p.x);
                n.child_max_y[slot] = quantize_up(b.max.y, e[1], p.y);
                n.child_max_z[slot] = quantize_up(b.max.z, e[2], p.z);
            }
        }
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

/// The hit mask of a node's children whose boxes the ray enters within
/// `[tmin, tmax]`: internal children set bit `24 + (slot ^ octant)`, leaves set one
/// bit per primitive at their offset from the node's first primitive.
pub fn intersect_node(
    node: &CwBvhNode,
    o: Vec3,
    inv_d: Vec3,
    oct_inv4: u32,
    tmin: f32,
    tmax: f32,
) -> u32 {
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
            let b = child_box(node, slot);
            let t0 = (b.min - o) * inv_d;
            let t1 = (b.max - o) * inv_d;
            let t_near = t0.min(t1);
            let t_far = t0.max(t1);
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
        check_against_brute_force as check_rays, random_spheres, random_triangles, Prim, Rng,
        Traversal,
    };

    impl Traversal for Cwbvh {
        fn closest(
            &self,
            o: Vec3,
            d: Vec3,
            tmin: f32,
            tmax: f32,
            hit: &mut dyn FnMut(u32, f32) -> Option<f32>,
        ) -> Option<(u32, f32)> {
            self.closest_hit(o, d, tmin, tmax, hit)
        }
        fn any(
            &self,
            o: Vec3,
            d: Vec3,
            tmin: f32,
            tmax: f32,
            hit: &mut dyn FnMut(u32, f32) -> Option<f32>,
        ) -> bool {
            self.any_hit(o, d, tmin, tmax, hit)
        }
    }

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
        let mut rng = Rng(101);
        for (n, rays, seed) in [
            (1, 2000, 10),
            (2, 2000, 11),
            (17, 4000, 12),
            (1000, 10_000, 13),
            (20_000, 4000, 14),
        ] {
            let prims = random_triangles(&mut rng, n, 10.0);
            check_against_brute_force(&prims, rays, seed);
        }
    }

    #[test]
    fn mixed_spheres_and_triangles_match_brute_force() {
        let mut rng = Rng(102);
        for (tris, spheres, rays, seed) in [
            (0, 1, 2000, 20),
            (0, 40, 4000, 21),
            (1, 1, 2000, 22),
            (500, 60, 10_000, 23),
            (5000, 300, 10_000, 24),
        ] {
            let mut prims = random_triangles(&mut rng, tris, 10.0);
            prims.extend(random_spheres(&mut rng, spheres, 10.0));
            let len = prims.len();
            for i in (1..len).rev() {
                prims.swap(i, rng.below(i + 1));
            }
            check_against_brute_force(&prims, rays, seed);
        }
    }

    #[test]
    fn coincident_far_and_tiny_inputs_match_brute_force() {
        let mut rng = Rng(103);
        // 100 copies of one triangle: all centroids coincide.
        let t = [Vec3::ZERO, Vec3::X, Vec3::Y];
        check_against_brute_force(&vec![Prim::Triangle(t); 100], 2000, 30);
        // Geometrically spaced clusters: node scales span many binades.
        let mut prims = Vec::new();
        for i in 0..100 {
            let c = Vec3::new(1.1f32.powi(i), 0.0, 0.0);
            for _ in 0..8 {
                let v = [
                    c + rng.vec3(-0.1, 0.1),
                    c + rng.vec3(-0.1, 0.1),
                    c + rng.vec3(-0.1, 0.1),
                ];
                prims.push(Prim::Triangle(v));
            }
        }
        check_against_brute_force(&prims, 4000, 31);
        // Far from the origin, small: quantization steps a few ulps of the position.
        let prims: Vec<Prim> = random_triangles(&mut rng, 500, 1.0)
            .into_iter()
            .map(|p| match p {
                Prim::Triangle(v) => {
                    Prim::Triangle(v.map(|x| x + Vec3::new(3000.0, -2000.0, 1000.0)))
                }
                other => other,
            })
            .collect();
        check_against_brute_force(&prims, 4000, 32);
    }

    /// Requantized boxes are exactly conservative for planes the decoder lands on and
    /// next to: a box whose faces sit on the primitive's own coordinates.
    #[test]
    fn quantization_is_conservative() {
        let mut rng = Rng(104);
        for _ in 0..20_000 {
            let p = rng.range(-1e4, 1e4);
            let max = p + rng.range(0.0, 1.0) * 10f32.powi(rng.below(9) as i32 - 4);
            let e = scale_exponent(p, max);
            assert!(decode(255, e, p) >= max);
            assert!(
                e == 1 || decode(255, e - 1, p) < max,
                "scale not the smallest"
            );
            let v = p + (max - p) * rng.f32();
            let lo = quantize_down(v, e, p);
            let hi = quantize_up(v, e, p);
            assert!(decode(lo, e, p) <= v && v <= decode(hi, e, p));
            assert!(lo == 255 || decode(lo + 1, e, p) > v);
            assert!(hi == 0 || decode(hi - 1, e, p) < v);
        }
    }

    #[test]
    fn build_is_deterministic() {
        let mut rng = Rng(105);
        let mut prims = random_triangles(&mut rng, 5000, 10.0);
        prims.extend(random_spheres(&mut rng, 100, 10.0));
        let bounds: Vec<Aabb> = prims.iter().map(Prim::bounds).collect();
        assert_eq!(Cwbvh::build(&bounds), Cwbvh::build(&bounds));
    }
}

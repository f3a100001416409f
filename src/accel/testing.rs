//! Test scenes and rays shared by the BVH tests: random triangle soups with
//! degenerate, axis-aligned and duplicated triangles, ellipsoids, rays of every kind
//! (from surfaces, axis-aligned, grazing), and the brute-force reference.
#![cfg(test)]

use super::geometry::{
    intersect_triangle, intersect_unit_sphere, sphere_world_bounds, triangle_bounds, Aabb,
};
use glam::{Mat4, Quat, Vec3};

/// SplitMix64: a tiny deterministic generator for tests.
pub(crate) struct Rng(pub(crate) u64);
impl Rng {
    pub(crate) fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    pub(crate) fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }
    pub(crate) fn f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }
    pub(crate) fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.f32()
    }
    pub(crate) fn vec3(&mut self, lo: f32, hi: f32) -> Vec3 {
        Vec3::new(self.range(lo, hi), self.range(lo, hi), self.range(lo, hi))
    }
    pub(crate) fn in_box(&mut self, b: &Aabb) -> Vec3 {
        Vec3::new(
            self.range(b.min.x, b.max.x),
            self.range(b.min.y, b.max.y),
            self.range(b.min.z, b.max.z),
        )
    }
    pub(crate) fn unit_vec3(&mut self) -> Vec3 {
        loop {
            let v = self.vec3(-1.0, 1.0);
            let l = v.length_squared();
            if l > 1e-4 && l <= 1.0 {
                return v / l.sqrt();
            }
        }
    }
}

/// Spheres are boxed to keep the enum small: brute force streams the whole list
/// once per ray.
#[derive(Clone, Debug)]
pub(crate) enum Prim {
    Triangle([Vec3; 3]),
    Sphere(Box<SpherePrim>),
}

#[derive(Clone, Debug)]
pub(crate) struct SpherePrim {
    pub(crate) object_to_world: Mat4,
    pub(crate) world_to_object: Mat4,
    bounds: Aabb,
}

impl Prim {
    pub(crate) fn bounds(&self) -> Aabb {
        match self {
            Prim::Triangle(v) => triangle_bounds(*v),
            Prim::Sphere(s) => s.bounds,
        }
    }
    pub(crate) fn hit(&self, o: Vec3, d: Vec3, tmin: f32, tmax: f32) -> Option<f32> {
        match self {
            Prim::Triangle(v) => {
                intersect_triangle(v[0], v[1], v[2], o, d, tmin, tmax).map(|(t, _)| t)
            }
            Prim::Sphere(s) => intersect_unit_sphere(&s.world_to_object, o, d, tmin, tmax),
        }
    }
    pub(crate) fn point(&self) -> Vec3 {
        self.bounds().centroid()
    }
}

pub(crate) fn sphere(object_to_world: Mat4) -> Prim {
    Prim::Sphere(Box::new(SpherePrim {
        object_to_world,
        world_to_object: object_to_world.inverse(),
        bounds: sphere_world_bounds(&object_to_world),
    }))
}

/// A triangle soup in a cube of side `size` with a mix of ordinary, large, thin,
/// degenerate, axis-aligned and duplicated triangles.
pub(crate) fn random_triangles(rng: &mut Rng, n: usize, size: f32) -> Vec<Prim> {
    let mut prims: Vec<Prim> = Vec::with_capacity(n);
    let edge = size / (n as f32).cbrt().max(1.0);
    while prims.len() < n {
        let c = rng.vec3(-0.5 * size, 0.5 * size);
        let mut v = [
            c + rng.vec3(-edge, edge),
            c + rng.vec3(-edge, edge),
            c + rng.vec3(-edge, edge),
        ];
        match rng.below(20) {
            // Large.
            0 => v[2] = c + rng.vec3(-4.0 * edge, 4.0 * edge),
            // Repeated vertex.
            1 => v[2] = v[1],
            // Collinear.
            2 => v[2] = v[0] + 2.5 * (v[1] - v[0]),
            // Sliver: third vertex almost on the first edge.
            3 => v[2] = v[0] + 0.3 * (v[1] - v[0]) + rng.vec3(-1e-4, 1e-4) * edge,
            // Axis-aligned plane: a flat box.
            4 => {
                let axis = rng.below(3);
                for k in 1..3 {
                    v[k][axis] = v[0][axis];
                }
            }
            // A point.
            5 => v = [v[0]; 3],
            // Duplicate of an earlier triangle (vertices rotated sometimes).
            6 | 7 if !prims.is_empty() => {
                if let Prim::Triangle(w) = prims[rng.below(prims.len())] {
                    v = if rng.below(2) == 0 {
                        w
                    } else {
                        [w[1], w[2], w[0]]
                    };
                }
            }
            _ => {}
        }
        prims.push(Prim::Triangle(v));
    }
    prims
}

pub(crate) fn random_spheres(rng: &mut Rng, n: usize, size: f32) -> Vec<Prim> {
    (0..n)
        .map(|i| {
            let rotation = Quat::from_axis_angle(rng.unit_vec3(), rng.range(0.0, 6.3));
            let scale = if i % 3 == 0 {
                Vec3::splat(rng.range(0.02, 0.15) * size)
            } else {
                rng.vec3(0.01, 0.15) * size
            };
            let translation = rng.vec3(-0.5 * size, 0.5 * size);
            sphere(Mat4::from_scale_rotation_translation(
                scale,
                rotation,
                translation,
            ))
        })
        .collect()
}

/// The boxes of `triangles` random triangles then `spheres` random spheres in a box of
/// side 10, drawn from `Rng(seed)` (the builds' determinism tests).
pub(crate) fn soup_bounds(seed: u64, triangles: usize, spheres: usize) -> Vec<Aabb> {
    let mut rng = Rng(seed);
    let mut prims = random_triangles(&mut rng, triangles, 10.0);
    prims.extend(random_spheres(&mut rng, spheres, 10.0));
    prims.iter().map(Prim::bounds).collect()
}

pub(crate) fn brute_closest(
    prims: &[Prim],
    o: Vec3,
    d: Vec3,
    tmin: f32,
    tmax: f32,
) -> Option<(u32, f32)> {
    let mut best = None;
    let mut closest = tmax;
    for (i, p) in prims.iter().enumerate() {
        if let Some(t) = p.hit(o, d, tmin, closest) {
            closest = t;
            best = Some((i as u32, t));
        }
    }
    best
}

pub(crate) fn scene_bounds(prims: &[Prim]) -> Aabb {
    prims.iter().fold(Aabb::empty(), |b, p| b.union(p.bounds()))
}

pub(crate) struct Ray {
    pub(crate) o: Vec3,
    pub(crate) d: Vec3,
    pub(crate) tmin: f32,
    pub(crate) tmax: f32,
}

pub(crate) fn random_ray(rng: &mut Rng, prims: &[Prim], b: &Aabb) -> Ray {
    let diag = (b.max - b.min).length().max(1e-3);
    let centre = b.centroid();
    let grown = Aabb {
        min: b.min - 0.1 * diag,
        max: b.max + 0.1 * diag,
    };
    let axis_dir = |rng: &mut Rng| {
        let mut d = Vec3::ZERO;
        d[rng.below(3)] = if rng.below(2) == 0 { 1.0 } else { -1.0 };
        d
    };
    let target = |rng: &mut Rng| prims[rng.below(prims.len())].point();
    let (o, mut d) = match rng.below(7) {
        // Anywhere near the scene, any direction.
        0 => (rng.in_box(&grown), rng.unit_vec3()),
        // From outside, towards the scene.
        1 => {
            let o = centre + rng.unit_vec3() * diag * rng.range(0.6, 3.0);
            (o, rng.in_box(b) - o)
        }
        // Inside, axis-aligned (two exact zero components).
        2 => (rng.in_box(b), axis_dir(rng)),
        // Axis-aligned through a primitive, from inside or outside the bounds.
        3 => {
            let d = axis_dir(rng);
            let o = target(rng) - d * diag * rng.range(-0.5, 1.5);
            (o, d)
        }
        // One zero component.
        4 => {
            let mut d = rng.unit_vec3();
            d[rng.below(3)] = 0.0;
            (rng.in_box(&grown), d)
        }
        // From a triangle vertex (like a secondary ray), any direction.
        5 => {
            let o = match &prims[rng.below(prims.len())] {
                Prim::Triangle(v) => v[rng.below(3)],
                p => p.point(),
            };
            (o, rng.unit_vec3())
        }
        // Aimed at a primitive: mostly hits, through dense regions.
        _ => {
            let o = rng.in_box(&grown);
            (o, target(rng) - o)
        }
    };
    if d == Vec3::ZERO {
        d = Vec3::X;
    }
    d *= match rng.below(3) {
        0 => rng.range(0.01, 100.0),
        _ => 1.0,
    };
    let scale = diag / d.length();
    let tmin = if rng.below(4) == 0 {
        rng.range(0.0, 0.5) * scale
    } else {
        0.0
    };
    let tmax = if rng.below(3) == 0 {
        tmin + rng.range(0.0, 1.5) * scale
    } else {
        f32::INFINITY
    };
    Ray { o, d, tmin, tmax }
}

/// A traversal under test: the CPU mirror of one of the kernels' BVH walks.
pub(crate) trait Traversal {
    fn closest(
        &self,
        o: Vec3,
        d: Vec3,
        tmin: f32,
        tmax: f32,
        hit: &mut dyn FnMut(u32, f32) -> Option<f32>,
    ) -> Option<(u32, f32)>;
    fn any(
        &self,
        o: Vec3,
        d: Vec3,
        tmin: f32,
        tmax: f32,
        hit: &mut dyn FnMut(u32, f32) -> Option<f32>,
    ) -> bool;
}

/// Every ray's closest hit through `accel` has the brute-force distance (bit for bit:
/// the same routine computes it) on a primitive that really has it, and the any-hit
/// query agrees with brute-force existence.
pub(crate) fn check_against_brute_force(
    accel: &dyn Traversal,
    prims: &[Prim],
    rays: usize,
    seed: u64,
) {
    let sb = scene_bounds(prims);
    let mut rng = Rng(seed);
    let mut hits = 0;
    for k in 0..rays {
        let ray = random_ray(&mut rng, prims, &sb);
        let (o, d) = (ray.o, ray.d);
        let expected = brute_closest(prims, o, d, ray.tmin, ray.tmax);
        let got = accel.closest(o, d, ray.tmin, ray.tmax, &mut |p, tmax| {
            prims[p as usize].hit(o, d, ray.tmin, tmax)
        });
        match (expected, got) {
            (None, None) => {}
            (Some((_, te)), Some((pg, tg))) => {
                assert_eq!(te, tg, "ray {k}: t differs (o {o} d {d})");
                // Duplicates tie: any primitive with exactly that distance is right.
                let t_of_got = prims[pg as usize].hit(o, d, ray.tmin, ray.tmax);
                assert_eq!(t_of_got, Some(tg), "ray {k}: prim {pg} not at t {tg}");
                hits += 1;
            }
            _ => panic!(
                "ray {k}: bvh {got:?} vs brute force {expected:?} \
                 (o {o} d {d} tmin {} tmax {})",
                ray.tmin, ray.tmax
            ),
        }
        let any = accel.any(o, d, ray.tmin, ray.tmax, &mut |p, tmax| {
            prims[p as usize].hit(o, d, ray.tmin, tmax)
        });
        assert_eq!(any, expected.is_some(), "ray {k}: any_hit");
    }
    // The ray mix must exercise hits, not just misses.
    assert!(
        prims.len() < 10 || hits > rays / 10,
        "only {hits} hits of {rays}"
    );
}

/// Implements [`Traversal`] for a BVH type with `closest_hit` and `any_hit` methods.
macro_rules! impl_traversal {
    ($t:ty) => {
        impl $crate::accel::testing::Traversal for $t {
            fn closest(
                &self,
                o: glam::Vec3,
                d: glam::Vec3,
                tmin: f32,
                tmax: f32,
                hit: &mut dyn FnMut(u32, f32) -> Option<f32>,
            ) -> Option<(u32, f32)> {
                self.closest_hit(o, d, tmin, tmax, hit)
            }
            fn any(
                &self,
                o: glam::Vec3,
                d: glam::Vec3,
                tmin: f32,
                tmax: f32,
                hit: &mut dyn FnMut(u32, f32) -> Option<f32>,
            ) -> bool {
                self.any_hit(o, d, tmin, tmax, hit)
            }
        }
    };
}
pub(crate) use impl_traversal;

/// A scene to check rays on: its primitives, how many rays, and the rays' seed.
pub(crate) type Case = (Vec<Prim>, usize, u64);

/// Triangle soups of 1 to 20 000 triangles.
pub(crate) fn soup_cases(rng: &mut Rng) -> Vec<Case> {
    [
        (1, 2000, 10),
        (2, 2000, 11),
        (17, 4000, 12),
        (1000, 10_000, 13),
        // Brute force dominates the run time here: fewer rays.
        (20_000, 4000, 14),
    ]
    .into_iter()
    .map(|(n, rays, seed)| (random_triangles(rng, n, 10.0), rays, seed))
    .collect()
}

/// Triangles and ellipsoids, shuffled so that sphere indices are not all at the end.
pub(crate) fn mixed_cases(rng: &mut Rng) -> Vec<Case> {
    [
        (0, 1, 2000, 20),
        (0, 40, 4000, 21),
        (1, 1, 2000, 22),
        (500, 60, 10_000, 23),
        (5000, 300, 10_000, 24),
    ]
    .into_iter()
    .map(|(tris, spheres, rays, seed)| {
        let mut prims = random_triangles(rng, tris, 10.0);
        prims.extend(random_spheres(rng, spheres, 10.0));
        let len = prims.len();
        for i in (1..len).rev() {
            prims.swap(i, rng.below(i + 1));
        }
        (prims, rays, seed)
    })
    .collect()
}

/// 100 copies of one triangle (all centroids coincide), then geometrically spaced
/// clusters (node scales across many binades; deep SAH trees).
pub(crate) fn coincident_and_cluster_cases(rng: &mut Rng) -> Vec<Case> {
    let t = [Vec3::ZERO, Vec3::X, Vec3::Y];
    let mut clusters = Vec::new();
    for i in 0..100 {
        let c = Vec3::new(1.1f32.powi(i), 0.0, 0.0);
        for _ in 0..8 {
            let v = [
                c + rng.vec3(-0.1, 0.1),
                c + rng.vec3(-0.1, 0.1),
                c + rng.vec3(-0.1, 0.1),
            ];
            clusters.push(Prim::Triangle(v));
        }
    }
    vec![
        (vec![Prim::Triangle(t); 100], 2000, 30),
        (clusters, 4000, 31),
    ]
}

/// 500 small triangles in a unit cube 3000 units from the origin: box planes a few
/// ulps apart. (In a far smaller cube the triangle test itself misses by rounding, for
/// any traversal.)
pub(crate) fn far_from_origin_case(rng: &mut Rng) -> Case {
    let prims = random_triangles(rng, 500, 1.0)
        .into_iter()
        .map(|p| match p {
            Prim::Triangle(v) => Prim::Triangle(v.map(|x| x + Vec3::new(3000.0, -2000.0, 1000.0))),
            other => other,
        })
        .collect();
    (prims, 4000, 32)
}

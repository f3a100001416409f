//! Exact ray–primitive intersections and primitive bounds.
//!
//! These are the CPU mirror of `glsl/lib/geometry.glsl`: the GLSL follows them line
//! by line, so keep both shaped alike (no early returns the shader cannot take, no
//! library calls GLSL lacks, e.g. `copysign` or a `sign` that returns 0).
//!
//! Rays are `o + t d` with `d` of any non-zero length; every routine returns the
//! same parameter `t`, so hits from different primitive kinds compare directly.

use glam::{Mat4, Vec2, Vec3};

/// An axis-aligned box. The empty box has `min = +inf`, `max = -inf`, so growing it
/// by anything gives that thing's box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    pub min: Vec3,
    pub max: Vec3,
}

impl Aabb {
    /// The box containing nothing.
    pub const fn empty() -> Self {
        Self {
            min: Vec3::INFINITY,
            max: Vec3::NEG_INFINITY,
        }
    }

    /// The smallest box containing every point of `points`.
    pub fn from_points(points: &[Vec3]) -> Self {
        let mut b = Self::empty();
        for &p in points {
            b.grow(p);
        }
        b
    }

    /// True when the box contains no point (inverted along some axis, or NaN).
    pub fn is_empty(&self) -> bool {
        !(self.min.x <= self.max.x && self.min.y <= self.max.y && self.min.z <= self.max.z)
    }

    /// Extends the box to contain `p`.
    pub fn grow(&mut self, p: Vec3) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }

    /// The smallest box containing both boxes.
    pub fn union(self, other: Aabb) -> Aabb {
        Aabb {
            min: self.min.min(other.min),
            max: self.max.max(other.max),
        }
    }

    /// True when `other` lies inside this box (an empty `other` always does).
    pub fn contains(&self, other: &Aabb) -> bool {
        other.is_empty() || (self.min.cmple(other.min).all() && other.max.cmple(self.max).all())
    }

    /// Surface area; 0 for an empty or flat-in-two-axes box.
    pub fn surface_area(&self) -> f32 {
        let e = (self.max - self.min).max(Vec3::ZERO);
        2.0 * (e.x * e.y + e.y * e.z + e.z * e.x)
    }

    /// Centre of the box (meaningless, NaN or infinite, for an empty box).
    pub fn centroid(&self) -> Vec3 {
        0.5 * (self.min + self.max)
    }
}

/// Bounds of a triangle: the componentwise min and max of its vertices.
pub fn triangle_bounds(v: [Vec3; 3]) -> Aabb {
    Aabb {
        min: v[0].min(v[1]).min(v[2]),
        max: v[0].max(v[1]).max(v[2]),
    }
}

/// A box holding `b` under the affine `object_to_world`: its eight corners' box, widened
/// by a few ulps of its largest coordinate so that the corners' rounding cannot leave out
/// a point of the transformed box (an instance's box in the top tree).
pub fn transformed_bounds(b: &Aabb, object_to_world: &Mat4) -> Aabb {
    let mut out = Aabb::empty();
    for i in 0..8 {
        let c = Vec3::new(
            if i & 1 == 0 { b.min.x } else { b.max.x },
            if i & 2 == 0 { b.min.y } else { b.max.y },
            if i & 4 == 0 { b.min.z } else { b.max.z },
        );
        out.grow(object_to_world.transform_point3(c));
    }
    let m = out.min.abs().max(out.max.abs()).max_element();
    let pad = Vec3::splat(8.0 * f32::EPSILON * m);
    Aabb {
        min: out.min - pad,
        max: out.max + pad,
    }
}

/// Exact bounds of the unit sphere under the affine `object_to_world`: an ellipsoid
/// centred at the translation whose half-extent along world axis `i` is the length of
/// row `i` of the 3×3 linear part (the support function of the ellipsoid).
pub fn sphere_world_bounds(object_to_world: &Mat4) -> Aabb {
    let (c0, c1, c2) = (
        object_to_world.x_axis.truncate(),
        object_to_world.y_axis.truncate(),
        object_to_world.z_axis.truncate(),
    );
    // glam is column-major: row i of the linear part is (c0[i], c1[i], c2[i]).
    let half = (c0 * c0 + c1 * c1 + c2 * c2).map(f32::sqrt);
    let centre = object_to_world.w_axis.truncate();
    Aabb {
        min: centre - half,
        max: centre + half,
    }
}

/// Square of the smallest `|det| / (|e1| |e2| |d|)` that [`intersect_triangle`]
/// accepts. Below it `det` is rounding noise (its computed value can be off by about
/// 12 eps of that product), so `u`, `v` and `t` would be garbage that may lie far
/// outside the triangle and its bounds: the triangle is degenerate or sliver-thin, or
/// the ray is parallel to it within 1e-5 rad, and it is treated as missed.
pub const TRIANGLE_DET_REL_EPS_SQ: f32 = 1e-5 * 1e-5;

/// Möller–Trumbore ray–triangle intersection, two-sided (Möller & Trumbore 1997,
/// "Fast, minimum storage ray/triangle intersection").
///
/// Returns `t` in the open interval `(tmin, tmax)` and the barycentrics `(u, v)` of
/// `v1` and `v2` (the hit point is `v0 + u (v1 - v0) + v (v2 - v0)`).
///
/// Degenerate triangles and rays parallel to the plane miss: `det` within rounding
/// noise is rejected (see [`TRIANGLE_DET_REL_EPS_SQ`]), and so is `|det|` below the
/// smallest normal float, which keeps `1 / det` finite, so no `0 * inf` NaN can reach
/// the comparisons (GPUs are not bound to IEEE NaN comparison semantics).
// The range checks are spelled as in the GLSL.
#[allow(clippy::manual_range_contains)]
pub fn intersect_triangle(
    v0: Vec3,
    v1: Vec3,
    v2: Vec3,
    o: Vec3,
    d: Vec3,
    tmin: f32,
    tmax: f32,
) -> Option<(f32, Vec2)> {
    let e1 = v1 - v0;
    let e2 = v2 - v0;
    let p = d.cross(e2);
    let det = e1.dot(p);
    let scale2 = e1.dot(e1) * e2.dot(e2) * d.dot(d);
    if det.abs() < f32::MIN_POSITIVE || det * det <= TRIANGLE_DET_REL_EPS_SQ * scale2 {
        return None;
    }
    let inv_det = 1.0 / det;
    let s = o - v0;
    let u = s.dot(p) * inv_det;
    if u < 0.0 || u > 1.0 {
        return None;
    }
    let q = s.cross(e1);
    let v = d.dot(q) * inv_det;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = e2.dot(q) * inv_det;
    if t > tmin && t < tmax {
        Some((t, Vec2::new(u, v)))
    } else {
        None
    }
}

/// Ray against the unit sphere at the origin of object space, `world_to_object` being
/// the inverse of the sphere's affine object-to-world transform.
///
/// The object-space direction is not renormalised, so `t` is the world-space parameter.
/// Returns the nearest root in `(tmin, tmax)`: the far root when the near one is at or
/// below `tmin` (origin inside the sphere).
///
/// The discriminant is computed from the distance between the centre and the line
/// (Haines et al., "Precision Improvements for Ray/Sphere Intersection", Ray Tracing
/// Gems ch. 7, eq. 10), and the roots from `q = -(b + sign(b) sqrt(disc))`, `t = c / q`
/// and `t = q / a`, which avoids cancellation in either root (Press et al., Numerical
/// Recipes §5.6). `b` here is the half coefficient `o·d`.
pub fn intersect_unit_sphere(
    world_to_object: &Mat4,
    o: Vec3,
    d: Vec3,
    tmin: f32,
    tmax: f32,
) -> Option<f32> {
    let oo = world_to_object.transform_point3(o);
    let dd = world_to_object.transform_vector3(d);
    let a = dd.dot(dd);
    if a < f32::MIN_POSITIVE {
        return None;
    }
    let b = oo.dot(dd);
    let c = oo.dot(oo) - 1.0;
    let l = oo - (b / a) * dd;
    let disc = a * (1.0 - l.dot(l));
    if disc < 0.0 {
        return None;
    }
    let q = -b - (if b >= 0.0 { 1.0 } else { -1.0 }) * disc.sqrt();
    // q is 0 only for a tangent ray whose touching point is the origin (b = 0, disc = 0).
    let mut t0 = if q != 0.0 { c / q } else { 0.0 };
    let mut t1 = q / a;
    if t0 > t1 {
        std::mem::swap(&mut t0, &mut t1);
    }
    if t0 > tmin && t0 < tmax {
        Some(t0)
    } else if t1 > tmin && t1 < tmax {
        Some(t1)
    } else {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{DMat4, DVec3, Quat};

    /// SplitMix64: a tiny deterministic generator for tests.
    struct Rng(u64);
    impl Rng {
        fn next_u64(&mut self) -> u64 {
            self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^ (z >> 31)
        }
        fn f32(&mut self) -> f32 {
            (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
        }
        fn range(&mut self, lo: f32, hi: f32) -> f32 {
            lo + (hi - lo) * self.f32()
        }
        fn vec3(&mut self, lo: f32, hi: f32) -> Vec3 {
            Vec3::new(self.range(lo, hi), self.range(lo, hi), self.range(lo, hi))
        }
        fn unit_vec3(&mut self) -> Vec3 {
            loop {
                let v = self.vec3(-1.0, 1.0);
                let l = v.length_squared();
                if l > 1e-4 && l <= 1.0 {
                    return v / l.sqrt();
                }
            }
        }
    }

    fn random_affine(rng: &mut Rng) -> Mat4 {
        let rotation = Quat::from_axis_angle(rng.unit_vec3(), rng.range(0.0, 6.3));
        let scale = rng.vec3(0.2, 3.0);
        let translation = rng.vec3(-5.0, 5.0);
        Mat4::from_scale_rotation_translation(scale, rotation, translation)
    }

    fn assert_close(a: f32, b: f32, tol: f32) {
        assert!((a - b).abs() <= tol, "{a} vs {b}");
    }

    #[test]
    fn triangle_hits_known_barycentrics() {
        let (v0, v1, v2) = (Vec3::ZERO, Vec3::X, Vec3::Y);
        let o = Vec3::new(0.25, 0.5, 1.0);
        let (t, uv) = intersect_triangle(v0, v1, v2, o, -Vec3::Z, 0.0, f32::INFINITY).unwrap();
        assert_close(t, 1.0, 1e-6);
        assert_close(uv.x, 0.25, 1e-6);
        assert_close(uv.y, 0.5, 1e-6);
        // Non-unit direction: t scales inversely.
        let (t, _) = intersect_triangle(v0, v1, v2, o, -2.0 * Vec3::Z, 0.0, f32::INFINITY).unwrap();
        assert_close(t, 0.5, 1e-6);
        // Two-sided: from below.
        let below = Vec3::new(0.25, 0.5, -3.0);
        let (t, uv) = intersect_triangle(v0, v1, v2, below, Vec3::Z, 0.0, f32::INFINITY).unwrap();
        assert_close(t, 3.0, 1e-6);
        assert_close(uv.x, 0.25, 1e-6);
        // Outside the triangle (u + v > 1), behind the ray, beyond tmax, parallel.
        let outside = Vec3::new(0.6, 0.6, 1.0);
        assert!(intersect_triangle(v0, v1, v2, outside, -Vec3::Z, 0.0, f32::INFINITY).is_none());
        assert!(intersect_triangle(v0, v1, v2, o, Vec3::Z, 0.0, f32::INFINITY).is_none());
        assert!(intersect_triangle(v0, v1, v2, o, -Vec3::Z, 0.0, 1.0).is_none());
        assert!(intersect_triangle(v0, v1, v2, o, -Vec3::Z, 1.0, 2.0).is_none());
        assert!(intersect_triangle(v0, v1, v2, o, Vec3::X, 0.0, f32::INFINITY).is_none());
        // Degenerate triangles (repeated vertex, collinear) never hit.
        assert!(intersect_triangle(v0, v1, v1, o, -Vec3::Z, 0.0, f32::INFINITY).is_none());
        let collinear = intersect_triangle(v0, v1, 2.0 * v1, o, -Vec3::Z, 0.0, f32::INFINITY);
        assert!(collinear.is_none());
    }

    #[test]
    fn ellipsoid_hits_at_analytic_distance() {
        let m = Mat4::from_scale(Vec3::new(1.0, 2.0, 3.0));
        let w2o = m.inverse();
        // Along -y from distance 10: the surface is at y = 2, so t = 10 - 2.
        let o = Vec3::new(0.0, 10.0, 0.0);
        let t = intersect_unit_sphere(&w2o, o, -Vec3::Y, 0.0, f32::INFINITY).unwrap();
        assert_close(t, 8.0, 1e-5);
        // Non-unit direction keeps t the world-space parameter.
        let t = intersect_unit_sphere(&w2o, o, -2.0 * Vec3::Y, 0.0, f32::INFINITY).unwrap();
        assert_close(t, 4.0, 1e-5);
        // Along z from below: surface at z = -3.
        let o = Vec3::new(0.0, 0.0, -7.0);
        let t = intersect_unit_sphere(&w2o, o, Vec3::Z, 0.0, f32::INFINITY).unwrap();
        assert_close(t, 4.0, 1e-5);
        // Translated and rotated: a 90° turn about z maps the y semi-axis (2) onto -x.
        let m = Mat4::from_scale_rotation_translation(
            Vec3::new(1.0, 2.0, 3.0),
            Quat::from_rotation_z(std::f32::consts::FRAC_PI_2),
            Vec3::new(5.0, 0.0, 0.0),
        );
        let o = Vec3::new(-5.0, 0.0, 0.0);
        let w2o = m.inverse();
        let t = intersect_unit_sphere(&w2o, o, Vec3::X, 0.0, f32::INFINITY).unwrap();
        assert_close(t, 8.0, 1e-5);
        // tmax before the surface: miss.
        assert!(intersect_unit_sphere(&w2o, o, Vec3::X, 0.0, 7.9).is_none());
    }

    #[test]
    fn sphere_from_inside_hits_far_side() {
        let m = Mat4::from_scale(Vec3::new(1.0, 2.0, 3.0));
        let w2o = m.inverse();
        let t = intersect_unit_sphere(&w2o, Vec3::ZERO, Vec3::X, 0.0, f32::INFINITY).unwrap();
        assert_close(t, 1.0, 1e-6);
        let t = intersect_unit_sphere(&w2o, Vec3::ZERO, -Vec3::Z, 0.0, f32::INFINITY).unwrap();
        assert_close(t, 3.0, 1e-6);
        // From the near surface with tmin past it: the far side.
        let o = Vec3::new(0.0, -5.0, 0.0);
        let t = intersect_unit_sphere(&w2o, o, Vec3::Y, 3.5, f32::INFINITY).unwrap();
        assert_close(t, 7.0, 1e-5);
        // Both roots behind the ray.
        let o = Vec3::new(0.0, 5.0, 0.0);
        assert!(intersect_unit_sphere(&w2o, o, Vec3::Y, 0.0, f32::INFINITY).is_none());
    }

    #[test]
    fn sphere_tangent_and_miss() {
        let w2o = Mat4::IDENTITY;
        // Exactly tangent at (1, 0, 0): the double root.
        let o = Vec3::new(1.0, -5.0, 0.0);
        let t = intersect_unit_sphere(&w2o, o, Vec3::Y, 0.0, f32::INFINITY).unwrap();
        assert_close(t, 5.0, 1e-5);
        // Just outside: miss; just inside: a hit near the tangent point.
        let o = Vec3::new(1.001, -5.0, 0.0);
        assert!(intersect_unit_sphere(&w2o, o, Vec3::Y, 0.0, f32::INFINITY).is_none());
        let o = Vec3::new(0.999, -5.0, 0.0);
        let t = intersect_unit_sphere(&w2o, o, Vec3::Y, 0.0, f32::INFINITY).unwrap();
        assert_close(t, 5.0 - (1.0f32 - 0.999 * 0.999).sqrt(), 1e-4);
        // Zero direction never hits.
        assert!(intersect_unit_sphere(&w2o, o, Vec3::ZERO, 0.0, f32::INFINITY).is_none());
        // Far away and nearly grazing: the stable form keeps a hit that a naive
        // b² - 4ac loses to cancellation at this distance.
        let o = Vec3::new(0.999, -1.0e4, 0.0);
        let t = intersect_unit_sphere(&w2o, o, Vec3::Y, 0.0, f32::INFINITY).unwrap();
        assert_close(t / 1.0e4, 1.0, 1e-5);
    }

    #[test]
    fn sphere_bounds_are_exact() {
        let mut rng = Rng(7);
        for _ in 0..200 {
            let m = random_affine(&mut rng);
            let b = sphere_world_bounds(&m);
            // The support point along ±axis i is M (M_row_i / |M_row_i|): it lies on the
            // ellipsoid and touches the box face.
            let lin = glam::Mat3::from_mat4(m);
            for i in 0..3 {
                let row = lin.row(i);
                let n = row / row.length();
                let p = m.transform_point3(n);
                assert!((p[i] - b.max[i]).abs() < 1e-4 * (1.0 + b.max[i].abs()));
                let p = m.transform_point3(-n);
                assert!((p[i] - b.min[i]).abs() < 1e-4 * (1.0 + b.min[i].abs()));
            }
            // Random surface points stay inside the box.
            for _ in 0..20 {
                let p = m.transform_point3(rng.unit_vec3());
                let slack = 1e-4 * (1.0 + p.abs().max_element());
                assert!(p.cmpge(b.min - slack).all() && p.cmple(b.max + slack).all());
            }
        }
    }

    #[test]
    fn aabb_helpers() {
        let e = Aabb::empty();
        assert!(e.is_empty());
        assert_eq!(e.surface_area(), 0.0);
        let b = Aabb::from_points(&[Vec3::ZERO, Vec3::new(1.0, 2.0, 3.0)]);
        assert!(!b.is_empty());
        assert_eq!(b.surface_area(), 2.0 * (2.0 + 6.0 + 3.0));
        assert_eq!(b.centroid(), Vec3::new(0.5, 1.0, 1.5));
        assert_eq!(e.union(b), b);
        assert!(b.contains(&e));
        assert!(b.contains(&b));
        let t = triangle_bounds([Vec3::X, Vec3::Y, -Vec3::Z]);
        assert_eq!(t.min, Vec3::new(0.0, 0.0, -1.0));
        assert_eq!(t.max, Vec3::new(1.0, 1.0, 0.0));
    }

    /// Möller–Trumbore in f64, the reference for the f32 routine.
    fn triangle_t_f64(v: [DVec3; 3], o: DVec3, d: DVec3) -> Option<f64> {
        let (e1, e2) = (v[1] - v[0], v[2] - v[0]);
        let p = d.cross(e2);
        let det = e1.dot(p);
        let s = o - v[0];
        let q = s.cross(e1);
        let (u, w) = (s.dot(p) / det, d.dot(q) / det);
        (u >= 0.0 && w >= 0.0 && u + w <= 1.0).then(|| e2.dot(q) / det)
    }

    #[test]
    fn triangle_t_matches_f64() {
        let mut rng = Rng(11);
        let mut checked = 0;
        while checked < 5000 {
            let v = [
                rng.vec3(-5.0, 5.0),
                rng.vec3(-5.0, 5.0),
                rng.vec3(-5.0, 5.0),
            ];
            let n = (v[1] - v[0]).cross(v[2] - v[0]);
            if n.length() < 0.5 {
                continue;
            }
            // Aim at an interior point from a random origin, not grazing the plane.
            let (a, b) = (rng.range(0.05, 0.9), rng.range(0.05, 0.9));
            if a + b > 0.95 {
                continue;
            }
            let target = v[0] + a * (v[1] - v[0]) + b * (v[2] - v[0]);
            let o = rng.vec3(-20.0, 20.0);
            let d = (target - o) * rng.range(0.1, 10.0);
            if (n.normalize().dot(d.normalize())).abs() < 0.05 {
                continue;
            }
            let (t, _) = intersect_triangle(v[0], v[1], v[2], o, d, 0.0, f32::INFINITY)
                .expect("aimed at the interior");
            let vd = v.map(|x| x.as_dvec3());
            let reference = triangle_t_f64(vd, o.as_dvec3(), d.as_dvec3()).unwrap();
            let rel = ((t as f64 - reference) / reference).abs();
            assert!(rel < 1e-4, "t {t} vs {reference}");
            checked += 1;
        }
    }

    #[test]
    fn sphere_t_matches_f64() {
        let mut rng = Rng(13);
        for i in 0..5000 {
            let m = random_affine(&mut rng);
            let w2o = m.inverse();
            let md = DMat4::from_cols_array(&m.to_cols_array().map(f64::from));
            let w2o_d = md.inverse();
            // Through an object-space point well inside the sphere, from outside or
            // (every third ray) from inside.
            let target = m.transform_point3(rng.unit_vec3() * rng.range(0.0, 0.7));
            let o = if i % 3 == 0 {
                m.transform_point3(rng.unit_vec3() * rng.range(0.0, 0.5))
            } else {
                m.w_axis.truncate() + rng.unit_vec3() * rng.range(10.0, 30.0)
            };
            let d = (target - o) * rng.range(0.1, 10.0);
            let t = intersect_unit_sphere(&w2o, o, d, 0.0, f32::INFINITY).expect("aimed inside");
            let (oo, dd) = (
                w2o_d.transform_point3(o.as_dvec3()),
                w2o_d.transform_vector3(d.as_dvec3()),
            );
            let (a, b, c) = (dd.dot(dd), oo.dot(dd), oo.dot(oo) - 1.0);
            let sq = (b * b - a * c).sqrt();
            let (t0, t1) = ((-b - sq) / a, (-b + sq) / a);
            let reference = if t0 > 0.0 { t0 } else { t1 };
            let rel = ((t as f64 - reference) / reference).abs();
            assert!(rel < 1e-4, "t {t} vs {reference}");
        }
    }
}

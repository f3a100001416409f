//! pbrt-v4's `curve` shape, diced into triangles as pbrt-v4's GPU renderer dices it (its
//! OptiX aggregate turns every curve into bilinear patches rather than intersecting
//! curves): `flat` and `cylinder` curves become tubes of CURVE_SIDES sides whose vertex
//! normals point away from the axis, `ribbon` curves strips across the interpolated
//! normals; uv is (u along the curve, v across: around a tube, across a ribbon), so the
//! `hair` material's fiber direction (∂p/∂u) runs along the curve and its offset
//! h = −1 + 2v goes around the tube, as on pbrt-v4's GPU. Tubes are geometry that every
//! integrator sees alike (pbrt-v4's CPU curves face each ray, which a light subpath and a
//! camera subpath would see differently).

use glam::{Vec2, Vec3};

/// Vertices around a tube (pbrt-v4's GPU dicing: 5).
pub(super) const CURVE_SIDES: usize = 5;
/// Rings along each cubic Bézier segment (pbrt-v4's GPU dicing: 5 for the whole curve;
/// lightpath's per segment, so that a long B-spline keeps its shape).
pub(super) const CURVE_STEPS_PER_SEGMENT: usize = 5;

/// How a curve is shaped (pbrt-v4's `type`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum CurveType {
    Flat,
    Cylinder,
    Ribbon,
}

/// A curve as declared (object space).
#[derive(Clone, Debug)]
pub(super) struct Curve {
    pub(super) cp: Vec<Vec3>,
    pub(super) degree: usize,
    pub(super) bspline: bool,
    pub(super) width0: f32,
    pub(super) width1: f32,
    pub(super) ty: CurveType,
    /// Ribbons: a normal at each segment's ends (segments + 1).
    pub(super) normals: Vec<Vec3>,
}

/// A diced curve: positions, triangle indices, vertex normals (tubes) and uv.
pub(super) struct Diced {
    pub(super) p: Vec<Vec3>,
    pub(super) indices: Vec<u32>,
    pub(super) n: Option<Vec<Vec3>>,
    pub(super) uv: Vec<Vec2>,
}

fn lerp(t: f32, a: Vec3, b: Vec3) -> Vec3 {
    a + (b - a) * t
}

/// The cubic Bézier of a quadratic one (degree elevation).
fn elevate(q: [Vec3; 3]) -> [Vec3; 4] {
    [
        q[0],
        lerp(2.0 / 3.0, q[0], q[1]),
        lerp(1.0 / 3.0, q[1], q[2]),
        q[2],
    ]
}

/// The Bézier control points of a uniform quadratic B-spline segment.
fn quadratic_bspline_to_bezier(b: [Vec3; 3]) -> [Vec3; 3] {
    [(b[0] + b[1]) * 0.5, b[1], (b[1] + b[2]) * 0.5]
}

/// The Bézier control points of a uniform cubic B-spline segment (by blossoming: the
/// segment's ends are (b0 + 4 b1 + b2) / 6 and (b1 + 4 b2 + b3) / 6, its inner points
/// divide b1 b2 in thirds).
fn cubic_bspline_to_bezier(b: [Vec3; 4]) -> [Vec3; 4] {
    let inner0 = lerp(1.0 / 3.0, b[1], b[2]);
    let inner1 = lerp(2.0 / 3.0, b[1], b[2]);
    let start = (lerp(2.0 / 3.0, b[0], b[1]) + inner0) * 0.5;
    let end = (inner1 + lerp(1.0 / 3.0, b[2], b[3])) * 0.5;
    [start, inner0, inner1, end]
}

/// The point of a cubic Bézier at t and its derivative.
pub(super) fn bezier(c: &[Vec3; 4], t: f32) -> (Vec3, Vec3) {
    let s = 1.0 - t;
    let p = c[0] * (s * s * s)
        + c[1] * (3.0 * s * s * t)
        + c[2] * (3.0 * s * t * t)
        + c[3] * (t * t * t);
    let d = (c[1] - c[0]) * (3.0 * s * s)
        + (c[2] - c[1]) * (6.0 * s * t)
        + (c[3] - c[2]) * (3.0 * t * t);
    (p, d)
}

/// Two unit vectors perpendicular to unit `t` and to each other.
fn perpendiculars(t: Vec3) -> (Vec3, Vec3) {
    let a = if t.x.abs() > t.y.abs() {
        Vec3::new(-t.z, 0.0, t.x) / (t.x * t.x + t.z * t.z).sqrt()
    } else {
        Vec3::new(0.0, t.z, -t.y) / (t.y * t.y + t.z * t.z).sqrt()
    };
    (a, t.cross(a))
}

impl Curve {
    /// Its segments as cubic Béziers, or what is wrong with its control points.
    pub(super) fn segments(&self) -> Result<Vec<[Vec3; 4]>, String> {
        let (n, deg) = (self.cp.len(), self.degree);
        if deg != 2 && deg != 3 {
            return Err(format!("degree {deg}: only 2 and 3 are supported"));
        }
        let count = if self.bspline {
            if n < deg + 1 {
                return Err(format!(
                    "{n} control points: a degree {deg} b-spline needs at least {}",
                    deg + 1
                ));
            }
            n - deg
        } else {
            if n < deg + 1 || (n - 1 - deg) % deg != 0 {
                return Err(format!(
                    "{n} control points: a degree {deg} Bézier curve needs {} + k · {deg}",
                    deg + 1
                ));
            }
            (n - 1) / deg
        };
        let cp = &self.cp;
        Ok((0..count)
            .map(|s| match (self.bspline, deg) {
                (false, 3) => [cp[3 * s], cp[3 * s + 1], cp[3 * s + 2], cp[3 * s + 3]],
                (false, _) => elevate([cp[2 * s], cp[2 * s + 1], cp[2 * s + 2]]),
                (true, 3) => cubic_bspline_to_bezier([cp[s], cp[s + 1], cp[s + 2], cp[s + 3]]),
                (true, _) => elevate(quadratic_bspline_to_bezier([cp[s], cp[s + 1], cp[s + 2]])),
            })
            .collect())
    }

    /// The curve diced into triangles (the segments from `segments`).
    pub(super) fn dice(&self, segments: &[[Vec3; 4]]) -> Diced {
        let steps = segments.len() * CURVE_STEPS_PER_SEGMENT;
        let across = if self.ty == CurveType::Ribbon {
            1
        } else {
            CURVE_SIDES
        };
        let mut out = Diced {
            p: Vec::new(),
            indices: Vec::new(),
            n: (self.ty != CurveType::Ribbon).then(Vec::new),
            uv: Vec::new(),
        };
        for i in 0..=steps {
            let u = i as f32 / steps as f32;
            let width = self.width0 + (self.width1 - self.width0) * u;
            let seg = (i / CURVE_STEPS_PER_SEGMENT).min(segments.len() - 1);
            let t = (i - seg * CURVE_STEPS_PER_SEGMENT) as f32 / CURVE_STEPS_PER_SEGMENT as f32;
            let (p, dpdu) = bezier(&segments[seg], t);
            let dir = dpdu.normalize_or_zero();
            if self.ty == CurveType::Ribbon {
                // The normal between the segment's end normals (spherical interpolation).
                let (n0, n1) = (
                    self.normals[seg].normalize(),
                    self.normals[seg + 1].normalize(),
                );
                let angle = n0.dot(n1).clamp(-1.0, 1.0).acos();
                let n = if angle < 1e-6 {
                    n0
                } else {
                    (n0 * ((1.0 - t) * angle).sin() + n1 * (t * angle).sin()) / angle.sin()
                };
                let half = n.cross(dir).normalize_or_zero() * (width * 0.5);
                out.p.extend([p - half, p + half]);
                out.uv.extend([Vec2::new(u, 0.0), Vec2::new(u, 1.0)]);
            } else {
                let (a, b) = perpendiculars(if dir == Vec3::ZERO { Vec3::Z } else { dir });
                // The seam's vertex twice, with v = 0 and v = 1.
                for k in 0..=CURVE_SIDES {
                    let v = k as f32 / CURVE_SIDES as f32;
                    let (s, c) = (v * std::f32::consts::TAU).sin_cos();
                    let out_dir = a * c + b * s;
                    out.p.push(p + out_dir * (width * 0.5));
                    out.n.as_mut().unwrap().push(out_dir);
                    out.uv.push(Vec2::new(u, v));
                }
            }
            if i > 0 {
                let row = (across + 1) as u32;
                let (r0, r1) = ((i as u32 - 1) * row, i as u32 * row);
                for k in 0..across as u32 {
                    // The patch p00 p10 p01 p11 as two triangles, wound so that their
                    // normal leaves the tube (a ribbon's faces both ways).
                    let (p00, p10, p01, p11) = (r0 + k, r0 + k + 1, r1 + k, r1 + k + 1);
                    out.indices.extend([p00, p11, p01, p00, p10, p11]);
                }
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cubic(c: &[Vec3], t: f32) -> Vec3 {
        // The uniform cubic B-spline's basis at t of its first segment.
        let s = 1.0 - t;
        (c[0] * (s * s * s)
            + c[1] * (3.0 * t * t * t - 6.0 * t * t + 4.0)
            + c[2] * (-3.0 * t * t * t + 3.0 * t * t + 3.0 * t + 1.0)
            + c[3] * (t * t * t))
            / 6.0
    }

    #[test]
    fn bsplines_become_the_beziers_that_trace_them() {
        let b = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 2.0, 0.0),
            Vec3::new(3.0, -1.0, 1.0),
            Vec3::new(4.0, 0.5, 2.0),
        ];
        let z = cubic_bspline_to_bezier(b);
        for k in 0..=10 {
            let t = k as f32 / 10.0;
            assert!(bezier(&z, t).0.distance(cubic(&b, t)) < 1e-5, "t = {t}");
        }
        // Quadratic: the uniform B-spline (b0 + b1)/2 (1-t)^2 + ... as Bézier, elevated.
        let q = [b[0], b[1], b[2]];
        let e = elevate(quadratic_bspline_to_bezier(q));
        for k in 0..=10 {
            let t = k as f32 / 10.0;
            let s = 1.0 - t;
            let want = q[0] * (0.5 * s * s) + q[1] * (0.5 + t * s) + q[2] * (0.5 * t * t);
            assert!(bezier(&e, t).0.distance(want) < 1e-5, "t = {t}");
        }
    }

    #[test]
    fn control_point_counts_follow_pbrt() {
        let c = |n: usize, degree, bspline| Curve {
            cp: vec![Vec3::ZERO; n],
            degree,
            bspline,
            width0: 1.0,
            width1: 1.0,
            ty: CurveType::Flat,
            normals: Vec::new(),
        };
        assert_eq!(c(4, 3, false).segments().unwrap().len(), 1);
        assert_eq!(c(7, 3, false).segments().unwrap().len(), 2);
        assert!(c(6, 3, false).segments().is_err());
        assert_eq!(c(5, 2, false).segments().unwrap().len(), 2);
        assert_eq!(c(6, 3, true).segments().unwrap().len(), 3);
        assert_eq!(c(3, 2, true).segments().unwrap().len(), 1);
        assert!(c(2, 2, true).segments().is_err());
        assert!(c(4, 4, false).segments().is_err());
    }

    #[test]
    fn a_straight_tube_has_its_width_and_outward_faces() {
        let curve = Curve {
            cp: (0..4).map(|k| Vec3::new(0.0, 0.0, k as f32)).collect(),
            degree: 3,
            bspline: false,
            width0: 0.5,
            width1: 0.25,
            ty: CurveType::Cylinder,
            normals: Vec::new(),
        };
        let d = curve.dice(&curve.segments().unwrap());
        let n = d.n.as_ref().unwrap();
        assert_eq!(
            d.indices.len(),
            3 * 2 * CURVE_SIDES * CURVE_STEPS_PER_SEGMENT
        );
        for (k, p) in d.p.iter().enumerate() {
            // Radius width/2, tapering linearly along u; normals radial.
            let u = d.uv[k].x;
            let r = (0.5 + (0.25 - 0.5) * u) * 0.5;
            assert!((p.truncate().length() - r).abs() < 1e-5);
            assert!((p.z - 3.0 * u).abs() < 1e-5);
            assert!(n[k].dot(p.truncate().extend(0.0).normalize()) > 0.9999);
        }
        for t in d.indices.chunks(3) {
            let [a, b, c] = [0, 1, 2].map(|i| d.p[t[i] as usize]);
            let g = (b - a).cross(c - a);
            let mid = (a + b + c) / 3.0;
            assert!(
                g.dot(mid.truncate().extend(0.0)) > 0.0,
                "a face looks into the tube"
            );
        }
    }

    #[test]
    fn a_ribbon_spans_its_width_across_its_normals() {
        let curve = Curve {
            cp: (0..4).map(|k| Vec3::new(k as f32, 0.0, 0.0)).collect(),
            degree: 3,
            bspline: false,
            width0: 0.2,
            width1: 0.2,
            ty: CurveType::Ribbon,
            normals: vec![Vec3::Z, Vec3::Y],
        };
        let d = curve.dice(&curve.segments().unwrap());
        assert!(d.n.is_none());
        // Across the ribbon: perpendicular to the curve and to the normal, whose
        // interpolation turns from z to y.
        let (first, last) = (d.p[1] - d.p[0], d.p[d.p.len() - 1] - d.p[d.p.len() - 2]);
        assert!((first.length() - 0.2).abs() < 1e-5 && first.dot(Vec3::Z).abs() < 1e-5);
        assert!((last.length() - 0.2).abs() < 1e-5 && last.dot(Vec3::Y).abs() < 1e-5);
    }
}

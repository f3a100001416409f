//! Bump and normal maps: CPU mirror of glsl/lib/shading_map.glsl and of geometry.glsl's
//! `resolve_material_and_map`. A material's displacement texture (pbrt-v4's `BumpMap`) or normal
//! map (pbrt-v4's `NormalMap`) replaces the shading normal that surface_at gives; every
//! integrator then shades with it (and corrects importance for it, as for interpolated
//! normals).
//!
//! Choices (docs/pbrt.md): the bump map's finite differences step half the pixel
//! footprint in u and in v ([`bump_steps`], over the footprint of
//! [`crate::gpu_scene::surface_footprint`]), as pbrt-v4's; [`BUMP_DELTA`], pbrt-v4's step
//! for a point without a footprint, where it has none. A sphere's dn/du is the derivative of its unit world normal (pbrt-v4
//! transforms the object-space one as a normal, which differs under a scaling transform;
//! the term matters only where the displacement is comparable to the radius).
use crate::abi::BUMP_DELTA;
use crate::bsdf::sampling::{build_onb, PI, TWO_PI};
use crate::scene::{Scene, ShadingMap};
use crate::texture::{texture_value_in, Footprint};
use glam::{Mat3, Vec2, Vec3};

/// pbrt-v4's shading geometry at a point: the unit shading normal and the partial
/// derivatives of position and normal along u and v.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadingGeometry {
    pub n: Vec3,
    pub dpdu: Vec3,
    pub dpdv: Vec3,
    pub dndu: Vec3,
    pub dndv: Vec3,
}

/// A triangle's (corners `p`, texture coordinates `uv`, shading normals `normals`), with
/// `n` the shading normal at the point. With normals, dp/du is made perpendicular to n
/// and dp/dv is n × dp/du, as pbrt-v4's triangles make them.
pub fn triangle_shading_geometry(
    p: [Vec3; 3],
    uv: [Vec2; 3],
    normals: Option<[Vec3; 3]>,
    n: Vec3,
) -> ShadingGeometry {
    let duv02 = uv[0] - uv[2];
    let duv12 = uv[1] - uv[2];
    let dp02 = p[0] - p[2];
    let dp12 = p[1] - p[2];
    let det = duv02.x * duv12.y - duv02.y * duv12.x;
    let degenerate = det.abs() < 1e-9;
    let (mut dpdu, mut dpdv) = (Vec3::ZERO, Vec3::ZERO);
    if !degenerate {
        let inv = 1.0 / det;
        dpdu = (duv12.y * dp02 - duv02.y * dp12) * inv;
        dpdv = (duv02.x * dp12 - duv12.x * dp02) * inv;
    }
    if degenerate || dpdu.cross(dpdv).length_squared() == 0.0 {
        (dpdu, dpdv) = build_onb((p[1] - p[0]).cross(p[2] - p[0]).normalize());
    }
    let (mut dndu, mut dndv) = (Vec3::ZERO, Vec3::ZERO);
    if let Some(ns) = normals {
        let ts = n.cross(dpdu);
        if ts.length_squared() > 0.0 {
            dpdu = ts.cross(n);
            dpdv = ts;
        } else {
            (dpdu, dpdv) = build_onb(n);
        }
        if det.abs() >= 1e-32 {
            let dn1 = ns[0] - ns[2];
            let dn2 = ns[1] - ns[2];
            let inv = 1.0 / det;
            dndu = (duv12.y * dn1 - duv02.y * dn2) * inv;
            dndv = (duv02.x * dn2 - duv12.x * dn1) * inv;
        }
    }
    ShadingGeometry {
        n,
        dpdu,
        dpdv,
        dndu,
        dndv,
    }
}

/// A sphere's: the unit sphere under the affine map whose linear part is `linear`, at
/// the point `q` of the unit sphere, with unit normal `n`. pbrt's u = φ / 2π and
/// v = 1 − θ / π.
pub fn sphere_shading_geometry(linear: Mat3, q: Vec3, n: Vec3) -> ShadingGeometry {
    let mut q = q.normalize();
    if q.x == 0.0 && q.y == 0.0 {
        q.x = 1e-5;
    }
    let r_xy = q.truncate().length();
    let (cos_phi, sin_phi) = (q.x / r_xy, q.y / r_xy);
    let du = TWO_PI * Vec3::new(-q.y, q.x, 0.0);
    let dv = -PI * Vec3::new(q.z * cos_phi, q.z * sin_phi, -r_xy);
    let normal_matrix = linear.inverse().transpose();
    let nq = normal_matrix * q;
    let inv_len = 1.0 / nq.length();
    let m = nq * inv_len;
    let across = |v: Vec3| {
        let v = normal_matrix * v * inv_len;
        v - m * m.dot(v)
    };
    ShadingGeometry {
        n,
        dpdu: linear * du,
        dpdv: linear * dv,
        dndu: across(du),
        dndv: across(dv),
    }
}

fn facing(ns: Vec3, ng: Vec3) -> Vec3 {
    if ns.dot(ng) < 0.0 {
        -ns
    } else {
        ns
    }
}

/// The pixel footprint in (u, v) (geometry.glsl's `uv_footprint`, pbrt-v4's
/// ComputeDifferentials): the least-squares (du/dx, dv/dx) and (du/dy, dv/dy) of dp/dx and
/// dp/dy over dp/du and dp/dv, each clamped to ±1e8; zero where dp/du, dp/dv are
/// degenerate.
pub fn uv_footprint(g: &ShadingGeometry, dpdx: Vec3, dpdy: Vec3) -> (Vec2, Vec2) {
    let a00 = g.dpdu.dot(g.dpdu);
    let a01 = g.dpdu.dot(g.dpdv);
    let a11 = g.dpdv.dot(g.dpdv);
    let det = a00 * a11 - a01 * a01;
    let inv = if det != 0.0 && (1.0 / det).is_finite() {
        1.0 / det
    } else {
        0.0
    };
    let solve = |d: Vec3| {
        let (b0, b1) = (g.dpdu.dot(d), g.dpdv.dot(d));
        (Vec2::new(a11 * b0 - a01 * b1, a00 * b1 - a01 * b0) * inv)
            .clamp(Vec2::splat(-1e8), Vec2::splat(1e8))
    };
    (solve(dpdx), solve(dpdy))
}

/// pbrt-v4's steps in u and v for a bump map's differences (shading_map.glsl's
/// `bump_steps`): half the pixel footprint's extent in u and in v ([`uv_footprint`]);
/// [`BUMP_DELTA`] where that is 0.
pub fn bump_steps(g: &ShadingGeometry, dpdx: Vec3, dpdy: Vec3) -> Vec2 {
    let (ddx, ddy) = uv_footprint(g, dpdx, dpdy);
    let steps = 0.5 * (ddx.abs() + ddy.abs());
    Vec2::new(
        if steps.x > 0.0 { steps.x } else { BUMP_DELTA },
        if steps.y > 0.0 { steps.y } else { BUMP_DELTA },
    )
}

/// pbrt-v4's `BumpMap`: `displacement(uv, p)` is the height along n; the shading normal is
/// the displaced surface's, on `ng`'s side (n where that is degenerate). The lookups step
/// `delta` ([`bump_steps`]) as the GLSL's (`p + su dp/du + sv dp/dv`).
pub fn bump_mapped_normal(
    g: &ShadingGeometry,
    displacement: impl Fn(Vec2, Vec3) -> f32,
    uv: Vec2,
    p: Vec3,
    ng: Vec3,
    delta: Vec2,
) -> Vec3 {
    let h = |su: f32, sv: f32| displacement(uv + Vec2::new(su, sv), p + su * g.dpdu + sv * g.dpdv);
    let d = h(0.0, 0.0);
    let d_u = h(delta.x, 0.0);
    let d_v = h(0.0, delta.y);
    let dpdu = g.dpdu + (d_u - d) / delta.x * g.n + d * g.dndu;
    let dpdv = g.dpdv + (d_v - d) / delta.y * g.n + d * g.dndv;
    let ns = dpdu.cross(dpdv);
    let l = ns.length();
    // (Zero, infinite or NaN: degenerate.)
    if !(l.is_finite() && l > 0.0) {
        return g.n;
    }
    facing(ns / l, ng)
}

/// pbrt-v4's `NormalMap`: the texel colour c gives the normal 2c − 1 in the frame
/// (x = dp/du, y = n × x, z = n); on `ng`'s side.
pub fn normal_mapped_normal(g: &ShadingGeometry, c: Vec3, ng: Vec3) -> Vec3 {
    let c = 2.0 * c - Vec3::ONE;
    let l = c.length();
    if l.is_nan() || l <= 0.0 {
        return g.n;
    }
    let c = c / l;
    let x = g.dpdu.normalize();
    facing((c.x * x + c.y * g.n.cross(x) + c.z * g.n).normalize(), ng)
}

/// The shading normal surface_at gives at the point `p` of primitive `prim` (the
/// scene's numbering: triangles, then spheres), bump or normal map included; mixes are
/// not resolved (the primitive's own material).
pub fn shading_normal(scene: &Scene, prim: usize, p: Vec3) -> Vec3 {
    let ntri = scene.triangles.len();
    let (material, ng, ns, uv, geometry): (
        u32,
        Vec3,
        Vec3,
        Vec2,
        Box<dyn Fn() -> ShadingGeometry>,
    );
    if prim < ntri {
        let t = scene.triangles.get(prim);
        let e1 = t.v[1] - t.v[0];
        let e2 = t.v[2] - t.v[0];
        let ng_ = e1.cross(e2).normalize();
        // Barycentrics of p (by areas in the triangle's plane).
        let full = e1.cross(e2);
        let w = p - t.v[0];
        let b1 = w.cross(e2).dot(full) / full.length_squared();
        let b2 = e1.cross(w).dot(full) / full.length_squared();
        let b0 = 1.0 - b1 - b2;
        let uvs = t.uv.unwrap_or(crate::scene::DEFAULT_UV);
        let ns_ = match t.normals {
            Some(n) => {
                let s = b0 * n[0] + b1 * n[1] + b2 * n[2];
                if s.length() > 0.0 {
                    s.normalize()
                } else {
                    ng_
                }
            }
            None => ng_,
        };
        material = t.material;
        ng = ng_;
        ns = ns_;
        uv = b0 * uvs[0] + b1 * uvs[1] + b2 * uvs[2];
        geometry = Box::new(move || triangle_shading_geometry(t.v, uvs, t.normals, ns_));
    } else {
        let s = scene.spheres[prim - ntri];
        let q = s.object_to_world.inverse().transform_point3(p);
        let linear = Mat3::from_mat4(s.object_to_world);
        let n = (linear.inverse().transpose() * q).normalize();
        let n = if s.inward { -n } else { n };
        let qn = q.normalize();
        let mut phi = qn.y.atan2(qn.x);
        if phi < 0.0 {
            phi += TWO_PI;
        }
        material = s.material;
        ng = n;
        ns = n;
        uv = Vec2::new(phi / TWO_PI, 1.0 - qn.z.clamp(-1.0, 1.0).acos() / PI);
        geometry = Box::new(move || sphere_shading_geometry(linear, q, n));
    }
    // The pixel footprint there, as the kernels find it with the scene's camera.
    let (dpdx, dpdy) =
        crate::gpu_scene::surface_footprint(&crate::gpu_scene::scene_params(scene, 0), p, ng);
    let g = geometry();
    let (duvdx, duvdy) = uv_footprint(&g, dpdx, dpdy);
    let footprint = Footprint {
        dpdx,
        dpdy,
        duvdx,
        duvdy,
    };
    match scene.materials[material as usize].shading_map {
        None => ns,
        Some(ShadingMap::Bump(tex)) => {
            let t = &scene.textures[tex as usize];
            let delta = bump_steps(&g, dpdx, dpdy);
            bump_mapped_normal(
                &g,
                |uv, p| texture_value_in(t, uv, p, ng, footprint).x,
                uv,
                p,
                ng,
                delta,
            )
        }
        Some(ShadingMap::Normal(tex)) => {
            let t = &scene.textures[tex as usize];
            normal_mapped_normal(&g, texture_value_in(t, uv, p, ng, footprint), ng)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A plane z = 0 with u along x and v along y (dp/du = (L, 0, 0)) displaced by
    /// d = k u has the normal (−k, 0, L) / |…|.
    /// The steps are half the footprint's extent in u and v: a plane with dp/du = (2, 0, 0)
    /// and dp/dv = (0, 4, 0) under a footprint of (0.1, 0, 0) and (0, 0.2, 0) steps
    /// u by (0.05 + 0) / 2 and v by (0 + 0.05) / 2; no footprint steps BUMP_DELTA.
    #[test]
    fn bump_steps_are_half_the_footprint_in_u_and_v() {
        let g = ShadingGeometry {
            n: Vec3::Z,
            dpdu: Vec3::new(2.0, 0.0, 0.0),
            dpdv: Vec3::new(0.0, 4.0, 0.0),
            dndu: Vec3::ZERO,
            dndv: Vec3::ZERO,
        };
        let s = bump_steps(&g, Vec3::new(0.1, 0.0, 0.0), Vec3::new(0.0, 0.2, 0.0));
        assert!((s - Vec2::new(0.025, 0.025)).length() < 1e-7, "{s}");
        // A footprint turned 90 degrees: the same steps.
        let s = bump_steps(&g, Vec3::new(0.0, 0.2, 0.0), Vec3::new(0.1, 0.0, 0.0));
        assert!((s - Vec2::new(0.025, 0.025)).length() < 1e-7, "{s}");
        assert_eq!(
            bump_steps(&g, Vec3::ZERO, Vec3::ZERO),
            Vec2::splat(BUMP_DELTA)
        );
    }

    #[test]
    fn a_linear_displacement_tilts_the_normal_by_its_slope() {
        let l = 2.0;
        let g = triangle_shading_geometry(
            [Vec3::ZERO, Vec3::new(l, 0.0, 0.0), Vec3::new(l, l, 0.0)],
            [Vec2::ZERO, Vec2::X, Vec2::ONE],
            None,
            Vec3::Z,
        );
        assert!((g.dpdu - Vec3::new(l, 0.0, 0.0)).length() < 1e-6);
        assert!((g.dpdv - Vec3::new(0.0, l, 0.0)).length() < 1e-6);
        let k = 0.7;
        let delta = Vec2::splat(BUMP_DELTA);
        let n = bump_mapped_normal(
            &g,
            |uv, _| k * uv.x,
            Vec2::splat(0.3),
            Vec3::ZERO,
            Vec3::Z,
            delta,
        );
        let want = Vec3::new(-k, 0.0, l).normalize();
        assert!((n - want).length() < 1e-3, "{n} vs {want}");
        // Seen from the other side (ng = -z) the tilt is the same, the normal flipped.
        let g2 = ShadingGeometry { n: -Vec3::Z, ..g };
        let n2 = bump_mapped_normal(
            &g2,
            |uv, _| k * uv.x,
            Vec2::splat(0.3),
            Vec3::ZERO,
            -Vec3::Z,
            delta,
        );
        assert!(
            (n2 - Vec3::new(-k, 0.0, -l).normalize()).length() < 1e-3,
            "{n2}"
        );
    }

    #[test]
    fn a_flat_normal_map_keeps_the_normal_and_a_tilted_one_turns_it_about_dpdv() {
        let g = ShadingGeometry {
            n: Vec3::Y,
            dpdu: Vec3::new(3.0, 0.0, 0.0),
            dpdv: Vec3::new(0.0, 0.0, -1.0),
            dndu: Vec3::ZERO,
            dndv: Vec3::ZERO,
        };
        let flat = normal_mapped_normal(&g, Vec3::new(0.5, 0.5, 1.0), Vec3::Y);
        assert!((flat - Vec3::Y).length() < 1e-6);
        // (0.5 + s/2, 0.5, 0.5 + c/2) is the normal (s, 0, c) in the frame: x = +x world.
        let a = 0.4f32;
        let c = Vec3::new(0.5 + 0.5 * a.sin(), 0.5, 0.5 + 0.5 * a.cos());
        let n = normal_mapped_normal(&g, c, Vec3::Y);
        assert!(
            (n - Vec3::new(a.sin(), a.cos(), 0.0)).length() < 1e-5,
            "{n}"
        );
    }

    /// The sphere's derivatives against finite differences of its parameterization.
    #[test]
    fn sphere_derivatives_match_finite_differences() {
        let m = glam::Mat4::from_scale_rotation_translation(
            Vec3::new(2.0, 1.0, 0.5),
            glam::Quat::from_rotation_x(0.3),
            Vec3::ZERO,
        );
        let linear = Mat3::from_mat4(m);
        let point = |u: f32, v: f32| {
            let phi = u * TWO_PI;
            let theta = (1.0 - v) * PI;
            Vec3::new(
                theta.sin() * phi.cos(),
                theta.sin() * phi.sin(),
                theta.cos(),
            )
        };
        let normal = |q: Vec3| (linear.inverse().transpose() * q).normalize();
        let (u, v, h) = (0.2f32, 0.65f32, 1e-3f32);
        let q = point(u, v);
        let g = sphere_shading_geometry(linear, q, normal(q));
        let fd = |f: &dyn Fn(f32, f32) -> Vec3, du: f32, dv: f32| {
            (f(u + du, v + dv) - f(u - du, v - dv)) / (2.0 * h)
        };
        let p = |u, v| linear * point(u, v);
        let nn = |u, v| normal(point(u, v));
        for (got, want) in [
            (g.dpdu, fd(&p, h, 0.0)),
            (g.dpdv, fd(&p, 0.0, h)),
            (g.dndu, fd(&nn, h, 0.0)),
            (g.dndv, fd(&nn, 0.0, h)),
        ] {
            assert!(
                (got - want).length() < 2e-2 * want.length().max(1.0),
                "{got} vs {want}"
            );
        }
    }
}

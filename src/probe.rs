//! The traversal probe: traces given rays on the device through the kernels'
//! `trace_closest` and `trace_occluded` (glsl/trace_probe.comp), so that tests can check
//! every visibility backend against brute force where it runs, not only its CPU mirror.
use crate::gpu::abi::*;
use crate::gpu::buffer::Buffer;
use crate::render::{Prepared, Renderer};
use crate::scene::Scene;
use crate::trace::Trace;
use anyhow::Result;
use ash::vk;
use glam::Vec3;

/// What the device found for one ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProbeHit {
    /// The closest hit: primitive (the scene's numbering: triangles, then spheres) and t.
    pub closest: Option<(u32, f32)>,
    /// What `trace_occluded` answered.
    pub occluded: bool,
}

impl Renderer {
    /// Traces each ray `(origin, direction, tmax)` (from t = 0) through `scene` with the
    /// kernels' visibility functions of this renderer's backend.
    pub fn trace_probe(
        &mut self,
        scene: &Scene,
        rays: &[(Vec3, Vec3, f32)],
    ) -> Result<Vec<ProbeHit>> {
        let mut trace = Trace::new();
        let Prepared {
            gpu_scene,
            rq,
            triangle_order,
        } = self.prepare(scene, 0, 0, &mut trace)?;
        let input: Vec<[f32; 4]> = rays
            .iter()
            .flat_map(|(o, d, tmax)| [o.extend(*tmax).to_array(), d.extend(0.0).to_array()])
            .collect();
        let rays_buffer = Buffer::with_data(
            &self.device,
            "probe rays",
            bytemuck::cast_slice(&input),
            vk::BufferUsageFlags::STORAGE_BUFFER,
        )?;
        let out_bytes = (16 * rays.len() as u64).max(16);
        let out = self.storage_buffer("probe hits", out_bytes)?;
        let set = self.descriptor_set(
            &gpu_scene,
            &[(BINDING_FILM, &rays_buffer), (BINDING_SPLAT, &out)],
            rq.as_ref(),
        )?;
        let pipeline = self.kernels.pipeline("trace_probe")?;
        let params = PassParams {
            pass: [0, rays.len() as u32, 0, 0],
        };
        self.device
            .run_commands("tracing the probe rays", |cmd| unsafe {
                self.bind_kernel(cmd, pipeline, set);
                self.device.raw.cmd_push_constants(
                    cmd,
                    self.kernels.layout,
                    vk::ShaderStageFlags::COMPUTE,
                    0,
                    bytemuck::bytes_of(&params),
                );
                self.device
                    .raw
                    .cmd_dispatch(cmd, (rays.len() as u32).div_ceil(64).max(1), 1, 1);
            })?;
        let data = out.download(out_bytes)?;
        let words: &[[u32; 4]] = bytemuck::cast_slice(&data);
        let ntri = triangle_order.len() as u32;
        Ok(words[..rays.len()]
            .iter()
            .map(|w| ProbeHit {
                closest: (w[0] != u32::MAX).then(|| {
                    let prim = if w[0] < ntri {
                        triangle_order[w[0] as usize]
                    } else {
                        w[0]
                    };
                    (prim, f32::from_bits(w[1]))
                }),
                occluded: w[2] != 0,
            })
            .collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::geometry::intersect_triangle;
    use crate::accel::testing::{
        random_ray, random_spheres, random_triangles, scene_bounds, Prim, Rng,
    };
    use crate::render::AccelChoice;
    use crate::scene::{Sphere, Triangle};

    /// A scene holding `prims` (material 0), and each prim's id in it (triangles first).
    fn scene_of(prims: &[Prim]) -> (Scene, Vec<u32>) {
        let mut scene = crate::scene::parse_str(
            "size 8 8\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\ntri 0 1 2\n",
            "probe",
        )
        .unwrap();
        scene.triangles.clear();
        let ntri = prims
            .iter()
            .filter(|p| matches!(p, Prim::Triangle(_)))
            .count() as u32;
        let mut ids = Vec::new();
        for p in prims {
            match p {
                Prim::Triangle(v) => {
                    ids.push(scene.triangles.len() as u32);
                    scene.triangles.push(Triangle { v: *v, material: 0 });
                }
                Prim::Sphere(s) => {
                    ids.push(ntri + scene.spheres.len() as u32);
                    scene.spheres.push(Sphere {
                        object_to_world: s.object_to_world,
                        material: 0,
                    });
                }
            }
        }
        (scene, ids)
    }

    /// How far inside its primitive a hit lies: the smallest barycentric of a
    /// triangle hit, 0 for a sliver triangle or a grazing ray (where ray query's own
    /// triangle test may decide otherwise than ours), 1 - (distance of the line from
    /// the centre)^2 for an ellipsoid. Near 0, the device's and the CPU's rounding may
    /// disagree about the hit.
    fn margin(p: &Prim, o: Vec3, d: Vec3, tmax: f32) -> f32 {
        match p {
            Prim::Triangle(v) => {
                let (e1, e2) = (v[1] - v[0], v[2] - v[0]);
                let n = e1.cross(e2);
                let sliver = n.length() < 1e-2 * e1.length() * e2.length();
                let grazing = n.dot(d).abs() < 1e-3 * n.length() * d.length();
                match intersect_triangle(v[0], v[1], v[2], o, d, 0.0, tmax) {
                    Some((_, b)) if !sliver && !grazing => b.x.min(b.y).min(1.0 - b.x - b.y),
                    _ => 0.0,
                }
            }
            Prim::Sphere(s) => {
                let oo = s.world_to_object.transform_point3(o);
                let dd = s.world_to_object.transform_vector3(d);
                let l = oo - (oo.dot(dd) / dd.dot(dd)) * dd;
                1.0 - l.dot(l)
            }
        }
    }

    /// Every backend's device traversal finds the brute-force closest hit (same
    /// distance up to the device's rounding, on a primitive that has it) and
    /// `trace_occluded` agrees. Disagreements are allowed only for hits the device's
    /// rounding can decide otherwise (on an edge, a silhouette, at `tmax`), and few.
    fn check_device(accel: AccelChoice, prims: &[Prim], rays: usize, seed: u64) {
        let (scene, ids) = scene_of(prims);
        let mut by_id = vec![0usize; prims.len()];
        for (i, &id) in ids.iter().enumerate() {
            by_id[id as usize] = i;
        }
        let sb = scene_bounds(prims);
        let diag = (sb.max - sb.min).length();
        let mut rng = Rng(seed);
        let rays: Vec<(Vec3, Vec3, f32)> = (0..rays)
            .map(|_| {
                let r = random_ray(&mut rng, prims, &sb);
                (r.o, r.d, r.tmax)
            })
            .collect();
        let mut renderer = Renderer::new(None, accel).unwrap_or_else(|e| {
            panic!(
                "this test needs a Vulkan device (for the {accel:?} backend) and none could be opened: {e:#}\n\
                 On a machine without a GPU install Mesa's lavapipe: run scripts/setup-system.sh"
            )
        });
        let got = renderer.trace_probe(&scene, &rays).unwrap();
        let (mut hits, mut borderline) = (0, 0);
        for (k, (&(o, d, tmax), g)) in rays.iter().zip(&got).enumerate() {
            let mut expected: Option<(usize, f32)> = None;
            for (i, p) in prims.iter().enumerate() {
                if let Some(t) = p.hit(o, d, 0.0, expected.map_or(tmax, |e| e.1)) {
                    expected = Some((i, t));
                }
            }
            let tol = |t: f32| 1e-4 * (t + 1e-2 * diag / d.length());
            let agree = match (expected, g.closest) {
                (None, None) => true,
                (Some((_, te)), Some((id, tg))) => {
                    let p = &prims[by_id[id as usize]];
                    let t_cpu = p.hit(o, d, 0.0, f32::INFINITY);
                    (tg - te).abs() <= tol(te) && t_cpu.is_some_and(|t| (t - te).abs() <= tol(te))
                }
                _ => false,
            };
            hits += expected.is_some() as usize;
            assert_eq!(
                g.occluded,
                g.closest.is_some(),
                "ray {k}: trace_occluded vs trace_closest ({accel:?})"
            );
            if agree {
                continue;
            }
            // Which hits could rounding decide either way?
            let near = |(i, t): (usize, f32)| {
                margin(&prims[i], o, d, f32::INFINITY) < 1e-3 || (tmax - t).abs() <= tol(t)
            };
            let edge = expected.is_some_and(near)
                || g.closest
                    .is_some_and(|(id, t)| near((by_id[id as usize], t)));
            assert!(
                edge,
                "ray {k} ({accel:?}): device {:?} vs brute force {expected:?} (o {o} d {d} tmax {tmax})",
                g.closest.map(|(id, t)| (by_id[id as usize], t))
            );
            borderline += 1;
        }
        assert!(hits > rays.len() / 10, "only {hits} hits of {}", rays.len());
        assert!(
            borderline * 100 <= rays.len(),
            "{borderline} borderline disagreements of {} rays",
            rays.len()
        );
    }

    fn soup(seed: u64) -> Vec<Prim> {
        let mut rng = Rng(seed);
        let mut prims = random_triangles(&mut rng, 3000, 10.0);
        prims.extend(random_spheres(&mut rng, 100, 10.0));
        let len = prims.len();
        for i in (1..len).rev() {
            prims.swap(i, rng.below(i + 1));
        }
        prims
    }

    #[test]
    fn device_traversal_matches_brute_force_on_every_backend() {
        let prims = soup(7);
        for accel in [AccelChoice::Cwbvh, AccelChoice::Bvh2, AccelChoice::RayQuery] {
            check_device(accel, &prims, 20_000, 70);
        }
    }
}

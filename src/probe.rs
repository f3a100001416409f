//! Device probes: the kernels' GLSL run on given inputs, so that tests check it where it
//! runs against its CPU mirror, not only the mirror. `trace_rays` traces rays through
//! `trace_closest` and `trace_occluded` (glsl/trace_probe.comp) for every visibility
//! backend; `bsdf` evaluates, samples and takes pdfs of the BSDFs (glsl/bsdf_probe.comp);
//! `mmlt_sampler` runs MMLT's primary-sample-space chains on a synthetic path
//! (glsl/mmlt_probe.comp, with the chains' code of the renders: lib/mmlt_chain.glsl). Each runs through the engine like any render.
use crate::abi::*;
use crate::engine::{Dispatch, Engine, Specialization};
use crate::integrators::mmlt_sampler::stream_sizes;
use crate::scene::Scene;
use crate::trace::Trace;
use anyhow::Result;
use glam::Vec3;

/// What the device found for one ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProbeHit {
    /// The closest hit: primitive (the scene's numbering, `PreparedScene::scene_id`:
    /// triangles, each instance's triangles, then spheres) and t.
    pub closest: Option<(u32, f32)>,
    /// What `trace_occluded` answered.
    pub occluded: bool,
    /// surface_at's shading normal at the closest hit (zero without one).
    pub shading_normal: Vec3,
}

/// Traces each ray `(origin, direction, tmax)` (from t = 0) through `scene` with the
/// kernels' visibility functions of the engine's backend.
pub fn trace_rays(
    engine: &mut Engine,
    scene: &Scene,
    rays: &[(Vec3, Vec3, f32)],
) -> Result<Vec<ProbeHit>> {
    let mut trace = Trace::new();
    let prepared = engine.prepare(scene, 0, |_| {}, &mut trace)?;
    let input: Vec<[f32; 4]> = rays
        .iter()
        .flat_map(|(o, d, tmax)| [o.extend(*tmax).to_array(), d.extend(0.0).to_array()])
        .collect();
    let rays_buffer = engine.buffer_with("probe rays", bytemuck::cast_slice(&input))?;
    let out_bytes = (32 * rays.len() as u64).max(32);
    let out = engine.storage_buffer("probe hits", out_bytes)?;
    let kernel = engine.kernel(
        "trace_probe",
        None,
        crate::engine::scene_specialization(scene),
    )?;
    let set = engine.bind(
        &kernel,
        Some(&prepared),
        &[
            (BINDING_PROBE_RAYS, &rays_buffer),
            (BINDING_PROBE_HITS, &out),
        ],
    )?;
    let params = PassParams {
        first_sample: 0,
        samples: rays.len() as u32,
        row_begin: 0,
        row_end: 0,
    };
    let groups = [
        (rays.len() as u32).div_ceil(PROBE_WORKGROUP_SIZE).max(1),
        1,
        1,
    ];
    engine.submit(
        &[Dispatch::new(&kernel, set, &params, groups)],
        "tracing the probe rays",
        &mut trace,
    )?;
    let data = out.download(out_bytes)?;
    let words: &[[u32; 4]] = bytemuck::cast_slice(&data);
    Ok(words[..2 * rays.len()]
        .chunks(2)
        .map(|w| (w[0], w[1]))
        .map(|(w, s)| ProbeHit {
            closest: (w[0] != u32::MAX).then(|| (prepared.scene_id(w[0]), f32::from_bits(w[1]))),
            occluded: w[2] != 0,
            shading_normal: Vec3::new(
                f32::from_bits(s[0]),
                f32::from_bits(s[1]),
                f32::from_bits(s[2]),
            ),
        })
        .collect())
}

/// Runs the GLSL BSDFs on `inputs` (each names a material of `materials` by index) and
/// returns what they gave (abi.h `BsdfProbeOutput`). `texels` holds the measured
/// materials' tables (`MeasuredBsdf::pack`, at the texel index in their records' base.x);
/// it may be empty.
pub fn bsdf(
    engine: &mut Engine,
    materials: &[GpuMaterial],
    texels: &[f32],
    inputs: &[BsdfProbeInput],
) -> Result<Vec<BsdfProbeOutput>> {
    engine.kernels.reset_sets()?;
    let materials_buffer =
        engine.buffer_with("probe materials", bytemuck::cast_slice(materials))?;
    let data = engine.float_data(&[(DATA_TEXELS, texels)])?;
    // (The probe's materials have no textures: surfaces look textures up, and the probe
    // has none.)
    let features = crate::abi::FEATURE_ALL;
    let what = "running the BSDF probe";
    run_bsdf_probe(
        engine,
        "bsdf_probe",
        features,
        &[
            (BINDING_MATERIALS, &materials_buffer),
            (BINDING_SCENE_DATA, &data.table),
        ],
        inputs,
        what,
    )
}

/// Runs the measured-material probe (glsl/measured_probe.comp) on `inputs` for the
/// material `packed` (`MeasuredBsdf::pack`; each input's `info.x` its texel index, 0 here):
/// f, the pdf and a sample, as `bsdf` returns them (no lobe flags or combined queries).
pub fn measured(
    engine: &mut Engine,
    packed: &[f32],
    inputs: &[BsdfProbeInput],
) -> Result<Vec<BsdfProbeOutput>> {
    engine.kernels.reset_sets()?;
    let data = engine.float_data(&[(DATA_TEXELS, packed)])?;
    let what = "running the measured-material probe";
    run_bsdf_probe(
        engine,
        "measured_probe",
        0,
        &[(BINDING_SCENE_DATA, &data.table)],
        inputs,
        what,
    )
}

/// Runs the medium probe (glsl/medium_probe.comp) on `inputs` with the media `media`:
/// free flights and the phase function as lib/media.glsl has them, in the BSDF probe's
/// records (the kernel says how it reads them).
pub fn medium(
    engine: &mut Engine,
    media: &[crate::scene::Medium],
    inputs: &[BsdfProbeInput],
) -> Result<Vec<BsdfProbeOutput>> {
    engine.kernels.reset_sets()?;
    // (Clouds' noise table at texel 0, the blackbody table after it.)
    let mut tables = crate::noise::noise_table();
    let blackbody = tables.len() as u32;
    tables.extend_from_slice(crate::media::blackbody_table());
    let (records, grids) = crate::gpu_scene::medium_data(media, 0, blackbody);
    let buffer = engine.buffer_with("probe media", bytemuck::cast_slice(&records))?;
    let data = engine.float_data(&[(crate::abi::DATA_GRIDS, &grids), (DATA_TEXELS, &tables)])?;
    run_bsdf_probe(
        engine,
        "medium_probe",
        crate::abi::FEATURE_MEDIA
            | crate::abi::FEATURE_GRID_MEDIA
            | crate::abi::FEATURE_CLOUD_MEDIA
            | crate::abi::FEATURE_RGB_GRID_MEDIA
            | crate::abi::FEATURE_TEMPERATURE_MEDIA
            | crate::abi::FEATURE_NANOVDB_MEDIA,
        &[
            (crate::abi::BINDING_MEDIA, &buffer),
            (BINDING_SCENE_DATA, &data.table),
        ],
        inputs,
        "running the medium probe",
    )
}

/// Runs the texture probe (glsl/texture_probe.comp) on `inputs` with the textures of
/// `scene`: texture.glsl's `texture_value` at each input's point and footprint (the
/// kernel says how it reads the records), every texture feature compiled in.
pub fn texture(
    engine: &mut Engine,
    scene: &crate::scene::Scene,
    inputs: &[BsdfProbeInput],
) -> Result<Vec<BsdfProbeOutput>> {
    engine.kernels.reset_sets()?;
    let data = crate::gpu_scene::texture_data(scene);
    let records = engine.buffer_with("probe textures", bytemuck::cast_slice(&data.textures))?;
    let texels: Vec<f32> = data.texel_words().collect();
    let texels = engine.float_data(&[(DATA_TEXELS, &texels)])?;
    run_bsdf_probe(
        engine,
        "texture_probe",
        crate::abi::FEATURE_ALL,
        &[
            (crate::abi::BINDING_TEXTURES, &records),
            (BINDING_SCENE_DATA, &texels.table),
        ],
        inputs,
        "running the texture probe",
    )
}

/// One dispatch of a BSDF probe kernel over `inputs`, with its material data at `data`
/// (binding, buffer):
/// the outputs, one per input.
fn run_bsdf_probe(
    engine: &mut Engine,
    kernel: &'static str,
    features: u32,
    data: &[(u32, &crate::gpu::buffer::Buffer)],
    inputs: &[BsdfProbeInput],
    what: &str,
) -> Result<Vec<BsdfProbeOutput>> {
    let mut trace = Trace::new();
    let inputs_buffer = engine.buffer_with("probe inputs", bytemuck::cast_slice(inputs))?;
    let out_bytes = (inputs.len() * std::mem::size_of::<BsdfProbeOutput>()).max(16) as u64;
    let out = engine.storage_buffer("probe outputs", out_bytes)?;
    // (Every MORE_FEATURE_* with every feature: the probes serve any scene.)
    let more_features = if features == crate::abi::FEATURE_ALL {
        u32::MAX
    } else {
        0
    };
    let kernel = engine.kernel(
        kernel,
        None,
        Specialization {
            features,
            more_features,
        },
    )?;
    let mut bindings = data.to_vec();
    bindings.push((BINDING_BSDF_PROBE_INPUTS, &inputs_buffer));
    bindings.push((BINDING_BSDF_PROBE_OUTPUTS, &out));
    let set = engine.bind(&kernel, None, &bindings)?;
    let params = PassParams {
        first_sample: 0,
        samples: inputs.len() as u32,
        row_begin: 0,
        row_end: 0,
    };
    let groups = [
        (inputs.len() as u32).div_ceil(PROBE_WORKGROUP_SIZE).max(1),
        1,
        1,
    ];
    engine.submit(
        &[Dispatch::new(&kernel, set, &params, groups)],
        what,
        &mut trace,
    )?;
    let data = out.download(out_bytes)?;
    Ok(bytemuck::cast_slice::<u8, BsdfProbeOutput>(&data)[..inputs.len()].to_vec())
}

/// MMLT's sampler against its CPU mirror: `chains` chains (chain c started on bootstrap
/// sample c of depth `depth_cap`) make `proposals` proposals on mmlt_probe.comp's synthetic
/// probe path. Returns every chain's primary numbers (dimension-major, as the kernel
/// keeps them) and the chains' state.
pub fn mmlt_sampler(
    engine: &mut Engine,
    chains: u32,
    depth_cap: u32,
    proposals: u32,
    seed: u32,
    sigma: f32,
    large_step: f32,
) -> Result<(Vec<[u32; 4]>, Vec<GpuChain>)> {
    let mut scene = crate::scene::parse_str(
        "size 4 4\nvertex 0 0 -1\nvertex 1 0 -1\nvertex 0 1 -1\ntri 0 1 2\n",
        "sampler probe",
    )?;
    scene.settings.max_depth = depth_cap as i32;
    let mut trace = Trace::new();
    let prepared = engine.prepare(&scene, seed, |_| {}, &mut trace)?;
    let streams = stream_sizes(depth_cap, false, false);
    let numbers: u32 = streams.iter().sum();
    let samples =
        engine.device_buffer("probe primary samples", chains as u64 * numbers as u64 * 16)?;
    let init: Vec<GpuChain> = (0..chains)
        .map(|c| GpuChain {
            state: [0, depth_cap, 0, 0],
            start: [c, 0, 0, 0],
            ..Default::default()
        })
        .collect();
    let chain_buffer = engine.storage_buffer(
        "probe chains",
        chains as u64 * std::mem::size_of::<GpuChain>() as u64,
    )?;
    chain_buffer.upload(bytemuck::cast_slice(&init))?;
    let stats = engine.storage_buffer("stats", 4 * STAT_COUNT as u64)?;
    // The probe modes touch no film, splat or bootstrap targets; mmlt_probe.comp binds them.
    let unused = engine.storage_buffer("unused", 16)?;
    let kernel = engine.kernel("mmlt_probe", None, prepared.specialization())?;
    let set = engine.bind(
        &kernel,
        Some(&prepared),
        &[
            (BINDING_STATS, &stats),
            (BINDING_SPLAT, &unused),
            (BINDING_DEPTH_FILMS, &unused),
            (BINDING_BOOTSTRAP, &unused),
            (BINDING_CHAIN_SAMPLES, &samples),
            (BINDING_CHAINS, &chain_buffer),
        ],
    )?;
    let mut p = MmltParams {
        mode: MMLT_MODE_PROBE_START,
        first_item: 0,
        items: chains,
        mutations: 0,
        chains,
        bootstrap_per_depth: 1,
        depths: depth_cap + 1,
        record_depths: 0,
        camera_numbers: streams[0],
        light_numbers: streams[1],
        connect_numbers: streams[2],
        numbers,
        sigma,
        large_step,
        reserved0: 0.0,
        reserved1: 0.0,
    };
    let groups = [chains.div_ceil(MMLT_WORKGROUP_SIZE), 1, 1];
    engine.submit(
        &[Dispatch::new(&kernel, set, &p, groups)],
        "running the sampler probe's start",
        &mut trace,
    )?;
    p.mode = MMLT_MODE_PROBE_CHAINS;
    p.mutations = proposals;
    engine.submit(
        &[Dispatch::new(&kernel, set, &p, groups)],
        "running the sampler probe's chains",
        &mut trace,
    )?;
    let numbers_data = samples.download(chains as u64 * numbers as u64 * 16)?;
    let chain_data =
        chain_buffer.download(chains as u64 * std::mem::size_of::<GpuChain>() as u64)?;
    Ok((
        bytemuck::cast_slice(&numbers_data).to_vec(),
        bytemuck::cast_slice(&chain_data).to_vec(),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::geometry::intersect_triangle;
    use crate::accel::testing::{
        random_ray, random_spheres, random_triangles, scene_bounds, Prim, Rng,
    };
    use crate::engine::{AccelChoice, Validation};
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
                    scene.triangles.push(Triangle::new(*v, 0));
                }
                Prim::Sphere(s) => {
                    ids.push(ntri + scene.spheres.len() as u32);
                    scene.spheres.push(Sphere {
                        object_to_world: s.object_to_world,
                        material: 0,
                        inward: false,
                        hidden: false,
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
        check_scene(accel, &scene, prims, &ids, rays, seed, 1e-3);
    }

    /// `check_device` on `scene`, whose primitives as the world sees them are `prims`
    /// (each with its scene id in `ids`); hits within `edge` (of `margin`) of an edge may
    /// go either way.
    fn check_scene(
        accel: AccelChoice,
        scene: &Scene,
        prims: &[Prim],
        ids: &[u32],
        rays: usize,
        seed: u64,
        edge: f32,
    ) {
        let instanced = !scene.instances.is_empty();
        let max_id = ids.iter().copied().max().unwrap_or(0) as usize;
        let mut by_id = vec![usize::MAX; max_id + 1];
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
        let mut engine = Engine::open(None, accel, Validation::Off).unwrap_or_else(|e| {
            panic!(
                "this test needs a Vulkan device (for the {accel:?} backend) and none could be opened: {e:#}\n\
                 On a machine without a GPU install Mesa's lavapipe: run scripts/setup-system.sh"
            )
        });
        let got = trace_rays(&mut engine, scene, &rays).unwrap();
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
                margin(&prims[i], o, d, f32::INFINITY) < edge || (tmax - t).abs() <= tol(t)
            };
            let edge = expected.is_some_and(near)
                || g.closest
                    .is_some_and(|(id, t)| near((by_id[id as usize], t)));
            assert!(
                edge,
                "ray {k} ({accel:?}): device {:?} vs brute force {expected:?} (o {o} d {d} tmax {tmax})",
                g.closest.map(|(id, t)| (by_id[id as usize], t))
            );
            // A ray that starts on an instance's triangle (whose rounded world copy the
            // brute force meets) may or may not meet it again at t ~ 0: not counted.
            let at_origin = |t: f32| t * d.length() <= 1e-5 * diag;
            if instanced
                && (expected.is_some_and(|(_, t)| at_origin(t))
                    || g.closest.is_some_and(|(_, t)| at_origin(t)))
            {
                continue;
            }
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

    /// A world of `soup` primitives and instances of three objects (random triangles in
    /// a unit box), under transforms that rotate, scale non-uniformly (up to 1:4), mirror
    /// (every third) and translate; the world's primitives as the brute force sees them
    /// (each instance's triangles carried to the world) and their scene ids.
    fn instanced_world(seed: u64) -> (Scene, Vec<Prim>, Vec<u32>) {
        let mut rng = Rng(seed);
        let flat = soup(seed);
        let (mut scene, _) = scene_of(&flat);
        let objects: Vec<Vec<[Vec3; 3]>> = [150, 400, 60]
            .iter()
            .map(|&n| {
                random_triangles(&mut rng, n, 1.0)
                    .into_iter()
                    .map(|p| match p {
                        Prim::Triangle(v) => v,
                        Prim::Sphere(_) => unreachable!(),
                    })
                    .collect()
            })
            .collect();
        for (k, o) in objects.iter().enumerate() {
            scene.objects.push(crate::scene::Object {
                name: format!("o{k}"),
                triangles: o.iter().map(|v| Triangle::new(*v, 0)).collect(),
            });
        }
        for k in 0..60 {
            let axis = rng.unit_vec3();
            let scale = Vec3::new(
                rng.range(0.5, 2.0),
                rng.range(0.5, 2.0),
                rng.range(0.5, 2.0),
            ) * if k % 3 == 0 {
                Vec3::new(-1.0, 1.0, 1.0)
            } else {
                Vec3::ONE
            };
            let m = glam::Mat4::from_translation(rng.vec3(-10.0, 10.0))
                * glam::Mat4::from_axis_angle(axis, rng.range(0.0, std::f32::consts::TAU))
                * glam::Mat4::from_scale(scale);
            scene.instances.push(crate::scene::Instance {
                object: (k % 3) as u32,
                object_to_world: m,
            });
        }
        // Ids: the world's triangles, each instance's, then the spheres.
        let ntri = scene.triangles.len() as u32;
        let instanced = scene.instanced_triangle_count() as u32;
        let mut prims = Vec::new();
        let mut ids = Vec::new();
        let mut next_sphere = ntri + instanced;
        let mut next_triangle = 0;
        for p in &flat {
            match p {
                Prim::Triangle(_) => {
                    ids.push(next_triangle);
                    next_triangle += 1;
                }
                Prim::Sphere(_) => {
                    ids.push(next_sphere);
                    next_sphere += 1;
                }
            }
            prims.push(p.clone());
        }
        let mut id = ntri;
        for i in &scene.instances {
            for t in scene.objects[i.object as usize].triangles.all() {
                prims.push(Prim::Triangle(
                    t.v.map(|v| i.object_to_world.transform_point3(v)),
                ));
                ids.push(id);
                id += 1;
            }
        }
        (scene, prims, ids)
    }

    /// The two-level walks (and ray query's instances) find what brute force finds over
    /// the instances' triangles carried to the world, mirrored and non-uniformly scaled
    /// ones included, beside the world's own triangles and spheres. (The device meets an
    /// instance's triangle in object space, the brute force its rounded world copy: near
    /// an edge, seen at a grazing angle, they may disagree; hence the wider edge.)
    #[test]
    fn device_traversal_of_instances_matches_brute_force_on_every_backend() {
        let (scene, prims, ids) = instanced_world(11);
        for accel in [AccelChoice::Bvh2, AccelChoice::RayQuery, AccelChoice::Cwbvh] {
            check_scene(accel, &scene, &prims, &ids, 20_000, 71, 2e-2);
        }
    }

    #[test]
    fn device_traversal_matches_brute_force_on_every_backend() {
        let prims = soup(7);
        for accel in [AccelChoice::Cwbvh, AccelChoice::Bvh2, AccelChoice::RayQuery] {
            check_device(accel, &prims, 20_000, 70);
        }
    }
}

//! The host/GLSL interface: every struct the Rust side mirrors has the same member
//! offsets in every compiled kernel, is built of 16-byte rows, and every kernel is
//! compiled for every backend; each kernel's descriptor bindings (read from its SPIR-V)
//! are the abi.h numbers, once each.
use lightpath::abi::{self, layouts};
use lightpath::accel::bvh::BvhNode;
use lightpath::gpu::kernels::KERNELS;
use lightpath::gpu::reflect::{kernel_bindings, struct_member_offsets};
use std::collections::{BTreeSet, HashSet};

#[test]
fn layouts_match_spirv() {
    let mut mirrored = layouts();
    mirrored.push((
        "BvhNode",
        vec![("min_left", 0, 16), ("max_count", 16, 16)],
        std::mem::size_of::<BvhNode>(),
    ));
    let mut seen = HashSet::new();
    for (kernel, backend, code) in KERNELS {
        for (st, member, offset) in struct_member_offsets(code) {
            let Some((_, members, _)) = mirrored.iter().find(|(n, _, _)| *n == st) else {
                continue;
            };
            let rust = members
                .iter()
                .find(|(m, _, _)| *m == member)
                .unwrap_or_else(|| {
                    panic!("{kernel} ({backend}): {st}.{member} has no Rust mirror")
                });
            assert_eq!(
                rust.1 as u32, offset,
                "{kernel} ({backend}): {st}.{member} is at {offset} in SPIR-V, {} in Rust",
                rust.1
            );
            seen.insert(st.clone());
        }
    }
    for (name, members, size) in &mirrored {
        assert!(
            seen.contains(*name),
            "struct {name} was not found in any kernel's SPIR-V"
        );
        // Members are 16-byte vectors, or 4-byte scalars in whole rows of four: no vec3,
        // and nothing std140/std430 would pad differently from Rust.
        assert_eq!(size % 16, 0, "{name}: size {size} is not a multiple of 16");
        let mut row = 0;
        for (member, offset, bytes) in members {
            match bytes {
                16 => assert_eq!(
                    offset % 16,
                    0,
                    "{name}.{member}: a vector not on a 16-byte row"
                ),
                4 => row += 4,
                _ => panic!("{name}.{member}: {bytes} bytes (members are vec4s or scalars)"),
            }
            if *bytes == 16 {
                assert_eq!(
                    row % 16,
                    0,
                    "{name}.{member}: scalars before it do not fill a row"
                );
            }
        }
        assert_eq!(row % 16, 0, "{name}: its scalars do not fill whole rows");
    }
}

#[test]
fn every_kernel_is_compiled_for_every_backend() {
    let kernels: BTreeSet<_> = KERNELS.iter().map(|(k, _, _)| *k).collect();
    for k in kernels {
        for b in ["rayquery", "cwbvh", "bvh2"] {
            assert!(
                KERNELS.iter().any(|(kk, bb, _)| *kk == k && *bb == b),
                "{k} is not compiled for {b}"
            );
        }
    }
}

/// Whether the SPIR-V names `name` (a type or variable: the kernels keep their debug
/// names), as a whole nul-terminated string.
fn holds(code: &[u8], name: &str) -> bool {
    let mut want = name.as_bytes().to_vec();
    want.push(0);
    code.windows(want.len()).any(|w| w == want.as_slice())
}

/// The descriptor bindings each kernel uses, as read from its SPIR-V: numbers from
/// abi.h, each resource at its own number, and the visibility backend's own resources
/// (the TLAS for ray query, the BVH buffers otherwise) only where they belong.
#[test]
fn kernel_bindings_come_from_the_spirv() {
    for (kernel, backend, code) in KERNELS {
        let bindings =
            kernel_bindings(code).unwrap_or_else(|e| panic!("{kernel} ({backend}): {e}"));
        let numbers: Vec<u32> = bindings.iter().map(|b| b.binding).collect();
        let has = |n: u32| numbers.contains(&n);
        if kernel.starts_with("measured_probe") {
            assert_eq!(
                numbers,
                vec![
                    abi::BINDING_BSDF_PROBE_INPUTS,
                    abi::BINDING_BSDF_PROBE_OUTPUTS,
                    abi::BINDING_SCENE_DATA
                ],
                "{kernel} ({backend})"
            );
            continue;
        }
        if kernel.starts_with("texture_probe") {
            assert_eq!(
                numbers,
                vec![
                    abi::BINDING_BSDF_PROBE_INPUTS,
                    abi::BINDING_BSDF_PROBE_OUTPUTS,
                    abi::BINDING_TEXTURES,
                    abi::BINDING_SCENE_DATA
                ],
                "{kernel} ({backend})"
            );
            continue;
        }
        if kernel.starts_with("medium_probe") {
            assert_eq!(
                numbers,
                vec![
                    abi::BINDING_BSDF_PROBE_INPUTS,
                    abi::BINDING_BSDF_PROBE_OUTPUTS,
                    abi::BINDING_MEDIA,
                    abi::BINDING_SCENE_DATA
                ],
                "{kernel} ({backend})"
            );
            continue;
        }
        if kernel.starts_with("bsdf_probe") {
            assert_eq!(
                numbers,
                vec![
                    abi::BINDING_MATERIALS,
                    abi::BINDING_BSDF_PROBE_INPUTS,
                    abi::BINDING_BSDF_PROBE_OUTPUTS,
                    abi::BINDING_SCENE_DATA
                ],
                "{kernel} ({backend})"
            );
            continue;
        }
        // Every other kernel reads the scene; the visibility backend is only in those
        // that trace rays (of the wavefront path tracer's stages, pt_trace and pt_shadow;
        // of BDPT's wavefront, bdpt_trace; of MMLT's, mmlt_trace; of the gbuffer film's
        // stages, gbuffer_hit).
        let base = kernel.split('+').next().unwrap_or(kernel);
        let traces = matches!(
            base,
            "direct"
                | "gbuffer_hit"
                | "analytic"
                | "bdpt_trace"
                | "mmlt_trace"
                | "trace_probe"
                | "pt_trace"
                | "pt_shadow"
        );
        let wavefront = base.starts_with("pt_") || base == "wf_queues";
        if !wavefront {
            assert!(has(abi::BINDING_SCENE), "{kernel} ({backend}): {numbers:?}");
        }
        // (The BVH's nodes are read by address: the walk's node type names it.)
        let bvh = holds(code, "BvhNodeChunk") || holds(code, "CwbvhNodeChunk");
        if !traces {
            assert!(
                !has(abi::BINDING_TLAS) && !bvh,
                "{kernel} ({backend}) holds the visibility backend: {numbers:?}"
            );
        } else if *backend == "rayquery" {
            assert!(
                has(abi::BINDING_TLAS) && !bvh,
                "{kernel} ({backend}): {numbers:?}"
            );
        } else {
            assert!(
                !has(abi::BINDING_TLAS) && bvh,
                "{kernel} ({backend}): {numbers:?}"
            );
        }
        // The wavefront's stages keep their paths and queues in the wavefront's buffers;
        // only pt_finish writes the film.
        if wavefront {
            let finish = base == "pt_finish";
            assert_eq!(
                has(abi::BINDING_WF_QUEUES),
                !finish,
                "{kernel}: {numbers:?}"
            );
            assert_eq!(
                has(abi::BINDING_WF_PATHS),
                base != "wf_queues",
                "{kernel}: {numbers:?}"
            );
            assert_eq!(has(abi::BINDING_FILM), finish, "{kernel}: {numbers:?}");
            assert!(!has(abi::BINDING_SPLAT), "{kernel}: {numbers:?}");
            continue;
        }
        match base {
            "direct" | "analytic" => {
                assert!(has(abi::BINDING_FILM) && !has(abi::BINDING_SPLAT))
            }
            // The gbuffer film's stages: the hit stage keeps each pixel's surface for the
            // albedo stages, which hold their class's BSDFs and no traversal (above) and
            // no texture: the surface's texture values come with it.
            "gbuffer_hit" => assert!(
                has(abi::BINDING_FILM)
                    && has(abi::BINDING_GBUFFER_SURFACES)
                    && !has(abi::BINDING_SPLAT),
                "{kernel} ({backend}): {numbers:?}"
            ),
            k if k.starts_with("gbuffer_albedo_") => assert!(
                has(abi::BINDING_FILM)
                    && has(abi::BINDING_GBUFFER_SURFACES)
                    && has(abi::BINDING_MATERIALS)
                    && !has(abi::BINDING_TEXTURES)
                    && !holds(code, "TriangleChunk")
                    && !has(abi::BINDING_SPLAT),
                "{kernel} ({backend}): {numbers:?}"
            ),
            // BDPT's wavefront: every stage keeps its walk in the walk buffer; the trace
            // stage adds what its shadow rays decide to the splat film (t = 1) or to the
            // walk's sums (with the connections, from the shade stages' BSDF answers), which
            // only bdpt_finish adds to the film; finish holds no material and no ray.
            "bdpt_trace" => assert!(
                has(abi::BINDING_BDPT_WALKS)
                    && !has(abi::BINDING_FILM)
                    && has(abi::BINDING_SPLAT)
                    && has(abi::BINDING_STRATEGIES)
                    && has(abi::BINDING_PATH_VERTICES)
                    && has(abi::BINDING_BDPT_ANSWERS),
                "{kernel} ({backend}): {numbers:?}"
            ),
            "bdpt_finish" => assert!(
                has(abi::BINDING_BDPT_WALKS)
                    && has(abi::BINDING_FILM)
                    && !has(abi::BINDING_SPLAT)
                    && !has(abi::BINDING_MATERIALS)
                    && !has(abi::BINDING_TEXTURES)
                    && !has(abi::BINDING_BDPT_ANSWERS),
                "{kernel} ({backend}): {numbers:?}"
            ),
            "bdpt_start" | "bdpt_hit" => assert!(
                has(abi::BINDING_BDPT_WALKS)
                    && has(abi::BINDING_PATH_VERTICES)
                    && !has(abi::BINDING_FILM)
                    && !has(abi::BINDING_SPLAT)
                    // (The emitters' code is bdpt_emit's: no light is picked in the hit stage.)
                    && (base == "bdpt_start" || !has(abi::BINDING_EMITTER_CDF)),
                "{kernel} ({backend}): {numbers:?}"
            ),
            "bdpt_emit" => assert!(
                has(abi::BINDING_BDPT_WALKS)
                    && has(abi::BINDING_EMITTER_CDF)
                    && !has(abi::BINDING_FILM)
                    && !has(abi::BINDING_SPLAT),
                "{kernel} ({backend}): {numbers:?}"
            ),
            k if k.starts_with("bdpt_shade_") => assert!(
                has(abi::BINDING_BDPT_WALKS)
                    && has(abi::BINDING_BDPT_ANSWERS)
                    && has(abi::BINDING_PATH_VERTICES)
                    && !has(abi::BINDING_FILM)
                    && !has(abi::BINDING_SPLAT)
                    && !has(abi::BINDING_STRATEGIES)
                    && !has(abi::BINDING_EMITTER_CDF)
                    && !has(abi::BINDING_EMITTERS),
                "{kernel} ({backend}): {numbers:?}"
            ),
            // MMLT's wavefront: every stage keeps its path in the walk and path buffers;
            // only mmlt_accept splats and touches the chains' state beyond reading it; the
            // shade stages hold no emitter, the accept stage no material.
            "mmlt_start" | "mmlt_hit" | "mmlt_emit" | "mmlt_end" | "mmlt_trace" => assert!(
                has(abi::BINDING_BDPT_WALKS)
                    && has(abi::BINDING_MMLT_PATHS)
                    && !has(abi::BINDING_SPLAT)
                    && !has(abi::BINDING_FILM)
                    // (The emitters' code is mmlt_emit's, and mmlt_start's.)
                    && (base != "mmlt_hit" || !has(abi::BINDING_EMITTER_CDF))
                    && (base != "mmlt_emit" || has(abi::BINDING_EMITTER_CDF)),
                "{kernel} ({backend}): {numbers:?}"
            ),
            k if k.starts_with("mmlt_shade_") => assert!(
                has(abi::BINDING_BDPT_WALKS)
                    && has(abi::BINDING_MMLT_PATHS)
                    && !has(abi::BINDING_SPLAT)
                    && !has(abi::BINDING_FILM)
                    && !has(abi::BINDING_EMITTER_CDF)
                    && !has(abi::BINDING_EMITTERS)
                    && !has(abi::BINDING_CHAINS),
                "{kernel} ({backend}): {numbers:?}"
            ),
            "mmlt_accept" => assert!(
                has(abi::BINDING_MMLT_PATHS)
                    && has(abi::BINDING_CHAINS)
                    && has(abi::BINDING_SPLAT)
                    && has(abi::BINDING_DEPTH_FILMS)
                    && !has(abi::BINDING_MATERIALS)
                    && !has(abi::BINDING_FILM),
                "{kernel} ({backend}): {numbers:?}"
            ),
            "mmlt_probe" => assert!(
                has(abi::BINDING_CHAINS)
                    && has(abi::BINDING_CHAIN_SAMPLES)
                    && !has(abi::BINDING_MATERIALS)
                    && !has(abi::BINDING_FILM),
                "{kernel} ({backend}): {numbers:?}"
            ),
            "trace_probe" => assert!(
                has(abi::BINDING_PROBE_RAYS)
                    && has(abi::BINDING_PROBE_HITS)
                    && !has(abi::BINDING_FILM)
            ),
            other => panic!("a kernel this test does not know: {other}"),
        }
    }
}

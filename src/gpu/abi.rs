//! Rust side of glsl/lib/abi.h: the constants (generated from the header by build.rs)
//! and `#[repr(C)]` mirrors of the buffer structs. `tests::layouts_match_spirv` checks
//! the offsets against the compiled kernels.
#![allow(dead_code)]

include!(concat!(env!("OUT_DIR"), "/abi_constants.rs"));

use bytemuck::{Pod, Zeroable};

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct GpuTriangle {
    pub v0: [f32; 4],
    pub v1: [f32; 4],
    pub v2: [f32; 4],
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct GpuSphere {
    pub o2w0: [f32; 4],
    pub o2w1: [f32; 4],
    pub o2w2: [f32; 4],
    pub w2o0: [f32; 4],
    pub w2o1: [f32; 4],
    pub w2o2: [f32; 4],
    pub info: [u32; 4],
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct GpuMaterial {
    pub diffuse: [f32; 4],
    pub specular: [f32; 4],
    pub emission: [f32; 4],
    pub params: [f32; 4],
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct GpuEmitter {
    pub p0: [f32; 4],
    pub p1: [f32; 4],
    pub p2: [f32; 4],
    pub radiance: [f32; 4],
    pub info: [u32; 4],
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct SceneParams {
    pub cam_eye: [f32; 4],
    pub cam_right: [f32; 4],
    pub cam_up: [f32; 4],
    pub cam_forward: [f32; 4],
    pub bounds: [f32; 4],
    pub dims: [u32; 4],
    pub counts: [u32; 4],
    pub options: [u32; 4],
    pub direct: [u32; 4],
    pub bdpt: [u32; 4],
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct GpuPathVertex {
    pub p: [f32; 4],
    pub n: [f32; 4],
    pub wi: [f32; 4],
    pub beta: [f32; 4],
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct PassParams {
    pub pass: [u32; 4],
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct MmltParams {
    pub run: [u32; 4],
    pub sizes: [u32; 4],
    pub streams: [u32; 4],
    pub mutation: [f32; 4],
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct GpuChain {
    pub current: [f32; 4],
    pub state: [u32; 4],
    pub counts: [u32; 4],
    pub start: [u32; 4],
}

pub use crate::accel::bvh::BvhNode;

/// A struct's name in GLSL, its members' (name, Rust offset) and its Rust size.
pub type StructLayout = (&'static str, Vec<(&'static str, usize)>, usize);

/// The layouts of every mirrored struct, for the layout test.
pub fn layouts() -> Vec<StructLayout> {
    use std::mem::{offset_of, size_of};
    macro_rules! layout {
        ($t:ident, $($f:ident),*) => {
            (stringify!($t), vec![$((stringify!($f), offset_of!($t, $f))),*], size_of::<$t>())
        };
    }
    vec![
        layout!(GpuTriangle, v0, v1, v2),
        layout!(GpuSphere, o2w0, o2w1, o2w2, w2o0, w2o1, w2o2, info),
        layout!(GpuMaterial, diffuse, specular, emission, params),
        layout!(GpuEmitter, p0, p1, p2, radiance, info),
        layout!(
            SceneParams,
            cam_eye,
            cam_right,
            cam_up,
            cam_forward,
            bounds,
            dims,
            counts,
            options,
            direct,
            bdpt
        ),
        layout!(GpuPathVertex, p, n, wi, beta),
        layout!(PassParams, pass),
        layout!(MmltParams, run, sizes, streams, mutation),
        layout!(GpuChain, current, state, counts, start),
    ]
}

const _: () = assert!(std::mem::size_of::<GpuTriangle>() == 48);
const _: () = assert!(std::mem::size_of::<GpuSphere>() == 112);
const _: () = assert!(std::mem::size_of::<GpuMaterial>() == 64);
const _: () = assert!(std::mem::size_of::<GpuEmitter>() == 80);
const _: () = assert!(std::mem::size_of::<SceneParams>() == 160);
const _: () = assert!(std::mem::size_of::<BvhNode>() == 32);
const _: () = assert!(std::mem::size_of::<GpuPathVertex>() == 64);

/// Member offsets of named structs in a SPIR-V module: (struct name, member name, offset).
pub fn spirv_member_offsets(code: &[u8]) -> Vec<(String, String, u32)> {
    use std::collections::HashMap;
    let words: Vec<u32> = code
        .chunks_exact(4)
        .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    let string_at = |w: &[u32]| -> String {
        let bytes: Vec<u8> = w
            .iter()
            .flat_map(|x| x.to_le_bytes())
            .take_while(|&b| b != 0)
            .collect();
        String::from_utf8_lossy(&bytes).to_string()
    };
    let mut names: HashMap<u32, String> = HashMap::new();
    let mut member_names: HashMap<(u32, u32), String> = HashMap::new();
    let mut offsets: Vec<(u32, u32, u32)> = Vec::new();
    let mut i = 5;
    while i < words.len() {
        let count = (words[i] >> 16) as usize;
        let op = words[i] & 0xffff;
        if count == 0 || i + count > words.len() {
            break;
        }
        let inst = &words[i..i + count];
        match op {
            5 => {
                names.insert(inst[1], string_at(&inst[2..]));
            }
            6 => {
                member_names.insert((inst[1], inst[2]), string_at(&inst[3..]));
            }
            72 if inst[3] == 35 => offsets.push((inst[1], inst[2], inst[4])),
            _ => {}
        }
        i += count;
    }
    offsets
        .into_iter()
        .filter_map(|(ty, member, offset)| {
            Some((
                names.get(&ty)?.clone(),
                member_names.get(&(ty, member))?.clone(),
                offset,
            ))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::kernels::KERNELS;

    #[test]
    fn layouts_match_spirv() {
        let mut mirrored: Vec<_> = layouts();
        mirrored.push((
            "BvhNode",
            vec![("min_left", 0), ("max_count", 16)],
            std::mem::size_of::<BvhNode>(),
        ));
        let mut seen = std::collections::HashSet::new();
        for (kernel, backend, code) in KERNELS {
            for (st, member, offset) in spirv_member_offsets(code) {
                let Some((_, members, _)) = mirrored.iter().find(|(n, _, _)| *n == st) else {
                    continue;
                };
                let rust = members
                    .iter()
                    .find(|(m, _)| *m == member)
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
            // Every member is a 16-byte vector, so the size is 16 per member.
            assert_eq!(
                *size,
                members.len() * 16,
                "{name}: size is not 16 bytes per member"
            );
        }
    }

    #[test]
    fn every_kernel_is_compiled_for_every_backend() {
        let kernels: std::collections::BTreeSet<_> = KERNELS.iter().map(|(k, _, _)| *k).collect();
        for k in kernels {
            for b in ["rayquery", "cwbvh", "bvh2"] {
                assert!(
                    KERNELS.iter().any(|(kk, bb, _)| *kk == k && *bb == b),
                    "{k} is not compiled for {b}"
                );
            }
        }
    }
}

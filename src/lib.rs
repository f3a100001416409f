//! lightpath: a GPU renderer on raw Vulkan. Path tracing, bidirectional path tracing
//! and multiplexed Metropolis light transport, converging to the same image.
pub mod abi;
pub mod accel;
pub mod alpha;
pub mod bench;
pub mod bsdf;
pub mod cli;
pub mod engine;
pub mod gpu;
pub mod gpu_scene;
pub mod hair;
pub mod integrators;
pub mod io;
pub mod measured;
pub mod media;
pub mod mipmap;
pub mod nanovdb;
pub mod noise;
pub mod plinear2d;
pub mod probe;
pub mod profile;
pub mod render;
pub mod scene;
pub mod shading_map;
pub mod tensor;
pub mod texture;
pub mod trace;

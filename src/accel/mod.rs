//! Acceleration structures built on the CPU: the two BVHs the kernels traverse from
//! storage buffers (the compressed 8-wide one and the binary SAH one, which also gives
//! the ray-query backend its coherent triangle order), and the exact intersections that
//! mirror the kernels'. (The ray-query BLAS/TLAS are device objects: `gpu::rayquery`.)
pub mod bvh;
pub mod cwbvh;
pub mod geometry;
pub(crate) mod testing;

use crate::scene::Scene;
use bvh::{Aabb, Bvh};
use cwbvh::Cwbvh;

/// The deepest binary BVH the kernels' traversal stack can hold.
pub const MAX_BVH_DEPTH: usize = 64;

/// Which tree to build: the binary SAH BVH or the compressed 8-wide one.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BvhKind {
    Binary,
    Compressed,
}

/// A built tree, as the kernels read it: node bytes and leaf primitive references.
pub struct BvhData {
    pub nodes: Vec<u8>,
    pub prim_refs: Vec<u32>,
    /// The scene's index, before reordering, of each triangle (in the new order).
    pub triangle_order: Vec<u32>,
}

/// Build the tree over the scene's triangles and spheres, and reorder the scene's
/// triangles into its leaf order, so that every backend (and lavapipe's BLAS builder,
/// which splits index ranges without sorting) sees spatially coherent geometry.
/// Primitive ids: triangles `0..n`, then spheres `n..n+m`.
pub fn prepare(scene: &mut Scene, kind: BvhKind) -> anyhow::Result<BvhData> {
    let ntri = scene.triangles.len();
    let mut bounds: Vec<Aabb> = scene
        .triangles
        .iter()
        .map(|t| geometry::triangle_bounds(t.v))
        .collect();
    // (Hidden spheres — invisible lights — are left out: no ray meets them. `ids` maps
    // the builders' primitive indices back to primitive ids.)
    let mut ids: Vec<u32> = (0..ntri as u32).collect();
    for (i, s) in scene.spheres.iter().enumerate() {
        if !s.hidden {
            bounds.push(geometry::sphere_world_bounds(&s.object_to_world));
            ids.push((ntri + i) as u32);
        }
    }
    let (nodes, prim_refs) = match kind {
        BvhKind::Binary => {
            let bvh = Bvh::build(&bounds);
            let depth = bvh_depth(&bvh);
            if depth > MAX_BVH_DEPTH {
                anyhow::bail!(
                    "the BVH is {depth} levels deep; the kernels' traversal stack holds {MAX_BVH_DEPTH}"
                );
            }
            (bytemuck::cast_slice(&bvh.nodes).to_vec(), bvh.prim_refs)
        }
        BvhKind::Compressed => {
            let bvh = Cwbvh::build(&bounds);
            let depth = bvh.depth();
            if depth > cwbvh::STACK_SIZE {
                anyhow::bail!(
                    "the compressed BVH is {depth} levels deep; the kernels' traversal stack holds {} (try --accel bvh2)",
                    cwbvh::STACK_SIZE
                );
            }
            (bytemuck::cast_slice(&bvh.nodes).to_vec(), bvh.prim_refs)
        }
    };
    let prim_refs = prim_refs.into_iter().map(|p| ids[p as usize]).collect();
    let mut data = BvhData {
        nodes,
        prim_refs,
        triangle_order: Vec::with_capacity(ntri),
    };
    // Leaf order of the triangles.
    let mut new_index = vec![u32::MAX; ntri];
    let mut reordered = Vec::with_capacity(ntri);
    for &p in &data.prim_refs {
        let p = p as usize;
        if p < ntri && new_index[p] == u32::MAX {
            new_index[p] = reordered.len() as u32;
            reordered.push(scene.triangles[p]);
            data.triangle_order.push(p as u32);
        }
    }
    if reordered.len() != ntri {
        anyhow::bail!(
            "internal error: the BVH lost {} triangles",
            ntri - reordered.len()
        );
    }
    scene.triangles = reordered;
    for p in data.prim_refs.iter_mut() {
        if (*p as usize) < ntri {
            *p = new_index[*p as usize];
        }
    }
    Ok(data)
}

/// Depth of the BVH (the root alone is 1).
pub fn bvh_depth(bvh: &Bvh) -> usize {
    let mut max = 0;
    let mut stack = vec![(0usize, 1usize)];
    while let Some((i, d)) = stack.pop() {
        max = max.max(d);
        let n = &bvh.nodes[i];
        if n.count == 0 && bvh.nodes.len() > 1 {
            stack.push((i + 1, d + 1));
            stack.push((n.left_or_first as usize, d + 1));
        }
    }
    max
}

//! Acceleration structures: the CPU-built SAH BVH (traversed by the kernels from a
//! storage buffer, and the source of a coherent triangle order) and the ray-query
//! BLAS/TLAS.
pub mod bvh;
pub mod cwbvh;
pub mod geometry;
pub mod rayquery;
mod testing;

use crate::scene::Scene;
use bvh::{Aabb, Bvh};

/// The deepest BVH the kernels' traversal stack can hold.
pub const MAX_BVH_DEPTH: usize = 64;

/// Build the BVH over the scene's triangles and spheres, and reorder the scene's
/// triangles into the BVH's leaf order, so that every backend (and lavapipe's BLAS
/// builder, which splits index ranges without sorting) sees spatially coherent
/// geometry. Primitive ids: triangles `0..n`, then spheres `n..n+m`.
pub fn prepare(scene: &mut Scene) -> anyhow::Result<Bvh> {
    let ntri = scene.triangles.len();
    let mut bounds: Vec<Aabb> = scene
        .triangles
        .iter()
        .map(|t| geometry::triangle_bounds(t.v))
        .collect();
    bounds.extend(
        scene
            .spheres
            .iter()
            .map(|s| geometry::sphere_world_bounds(&s.object_to_world)),
    );
    let mut bvh = Bvh::build(&bounds);
    // Leaf order of the triangles.
    let mut new_index = vec![u32::MAX; ntri];
    let mut reordered = Vec::with_capacity(ntri);
    for &p in &bvh.prim_refs {
        let p = p as usize;
        if p < ntri && new_index[p] == u32::MAX {
            new_index[p] = reordered.len() as u32;
            reordered.push(scene.triangles[p]);
        }
    }
    if reordered.len() != ntri {
        anyhow::bail!(
            "internal error: the BVH lost {} triangles",
            ntri - reordered.len()
        );
    }
    scene.triangles = reordered;
    for p in bvh.prim_refs.iter_mut() {
        if (*p as usize) < ntri {
            *p = new_index[*p as usize];
        }
    }
    let depth = bvh_depth(&bvh);
    if depth > MAX_BVH_DEPTH {
        anyhow::bail!(
            "the BVH is {depth} levels deep; the kernels' traversal stack holds {MAX_BVH_DEPTH}"
        );
    }
    Ok(bvh)
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

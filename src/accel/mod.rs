//! Acceleration structures built on the CPU: the two BVHs the kernels traverse from
//! storage buffers (the compressed 8-wide one and the binary SAH one, which also gives
//! the ray-query backend its coherent triangle order), and the exact intersections that
//! mirror the kernels'. (The ray-query BLAS/TLAS are device objects: `gpu::rayquery`.)
pub mod bvh;
mod clusters;
mod collapse;
pub mod cwbvh;
pub mod geometry;
pub(crate) mod testing;

use crate::abi::GpuInstance;
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
    /// Each object's: its triangles' indices before reordering, in the new order.
    pub object_orders: Vec<Vec<u32>>,
    /// The instances' records (abi.h `GpuInstance`), in the scene's order.
    pub instances: Vec<GpuInstance>,
    /// Triangle ids: the world's, then each instance's (`SceneParams::triangle_count`).
    pub triangle_ids: u32,
}

/// The largest id space of triangles and spheres: ids above are the kernels' markers
/// (abi.h MEDIUM_HIT, NO_HIT) and the storage-buffer walks' instance entries.
pub const MAX_PRIMITIVE_IDS: u64 = 0xffff_ff00;

/// A tree of either kind, before it is laid out in bytes.
enum Tree {
    Binary(Vec<bvh::BvhNode>),
    Compressed(Vec<obvhs::cwbvh::node::CwBvhNode>),
}

struct Built {
    tree: Tree,
    prim_refs: Vec<u32>,
    depth: usize,
}

impl Tree {
    fn len(&self) -> usize {
        match self {
            Tree::Binary(n) => n.len(),
            Tree::Compressed(n) => n.len(),
        }
    }

    /// Moves the tree to node `nodes` and primitive reference `refs` of the buffers.
    fn rebase(&mut self, nodes: u32, refs: u32) {
        match self {
            Tree::Binary(list) => {
                for n in list {
                    n.left_or_first += if n.count == 0 { nodes } else { refs };
                }
            }
            Tree::Compressed(list) => {
                for n in list {
                    n.child_base_idx += nodes;
                    n.primitive_base_idx += refs;
                }
            }
        }
    }

    fn bytes(&self) -> &[u8] {
        match self {
            Tree::Binary(n) => bytemuck::cast_slice(n),
            Tree::Compressed(n) => bytemuck::cast_slice(n),
        }
    }
}

fn build_tree(bounds: &[Aabb], kind: BvhKind) -> Built {
    match kind {
        BvhKind::Binary => {
            let bvh = Bvh::build(bounds);
            let depth = bvh_depth(&bvh);
            Built {
                tree: Tree::Binary(bvh.nodes),
                prim_refs: bvh.prim_refs,
                depth,
            }
        }
        BvhKind::Compressed => {
            let bvh = Cwbvh::build(bounds);
            let depth = bvh.depth();
            Built {
                tree: Tree::Compressed(bvh.nodes),
                prim_refs: bvh.prim_refs,
                depth,
            }
        }
    }
}

/// The leaf order of `n` triangles by `refs` (indices into them; other values, at or
/// above `n`, are left alone): the old index of each triangle in the new order (the
/// order their references first appear in), `refs` renumbered to it. The triangles
/// themselves are not moved: their records are made in this order
/// (`gpu_scene::GpuScene::new`), with no reordered copy of the scene.
fn leaf_order(n: usize, refs: &mut [u32]) -> anyhow::Result<Vec<u32>> {
    let mut new_index = vec![u32::MAX; n];
    let mut order = Vec::with_capacity(n);
    for &p in refs.iter() {
        let p = p as usize;
        if p < n && new_index[p] == u32::MAX {
            new_index[p] = order.len() as u32;
            order.push(p as u32);
        }
    }
    if order.len() != n {
        anyhow::bail!("internal error: the BVH lost {} triangles", n - order.len());
    }
    for p in refs.iter_mut() {
        if (*p as usize) < n {
            *p = new_index[*p as usize];
        }
    }
    Ok(order)
}

/// `f` of each item, on `threads` threads (at least one), in the items' order: each
/// thread takes the next item left until none is. (The trees' builds; a result depends
/// on its item alone, never on which thread made it.)
pub(crate) fn map_in_parallel<T: Send, R: Send>(
    items: &mut [T],
    threads: usize,
    f: impl Fn(&mut T) -> R + Sync,
) -> Vec<R> {
    let results: Vec<std::sync::Mutex<Option<R>>> = (0..items.len())
        .map(|_| std::sync::Mutex::new(None))
        .collect();
    let work = std::sync::Mutex::new(items.iter_mut().enumerate());
    std::thread::scope(|s| {
        for _ in 0..threads.clamp(1, results.len().max(1)) {
            s.spawn(|| loop {
                let next = work.lock().unwrap().next();
                let Some((i, item)) = next else { break };
                *results[i].lock().unwrap() = Some(f(item));
            });
        }
    });
    results
        .into_iter()
        .map(|r| r.into_inner().unwrap().expect("every item done"))
        .collect()
}

/// `f` of each piece of `items` (`piece` long, the last one shorter) on `threads`
/// threads, in the pieces' order (a pass over a large array on every core, whose results
/// the caller folds).
pub(crate) fn map_pieces<T: Sync, R: Send>(
    items: &[T],
    piece: usize,
    threads: usize,
    f: impl Fn(&[T]) -> R + Sync,
) -> Vec<R> {
    let mut pieces: Vec<&[T]> = items.chunks(piece.max(1)).collect();
    map_in_parallel(&mut pieces, threads, |p| f(p))
}

/// Each triangle's box, made a piece per core.
fn triangle_bounds(triangles: &[crate::scene::TriangleCorners]) -> Vec<Aabb> {
    let mut bounds = vec![Aabb::empty(); triangles.len()];
    let piece = triangles.len().div_ceil(threads()).max(1 << 16);
    let mut pieces: Vec<_> = bounds
        .chunks_mut(piece)
        .zip(triangles.chunks(piece))
        .collect();
    map_in_parallel(&mut pieces, threads(), |(out, triangles)| {
        for (b, t) in out.iter_mut().zip(triangles.iter()) {
            *b = geometry::triangle_bounds(t.v);
        }
    });
    bounds
}

/// The threads the builds use: every core.
pub(crate) fn threads() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// Build the trees over the scene's triangles, spheres and instances, and the leaf order
/// of the triangles (the world's, each object's: `BvhData::triangle_order`,
/// `object_orders`), the order their records are made in, so that every backend (and
/// lavapipe's BLAS builder, which splits index ranges without sorting) sees spatially
/// coherent geometry.
///
/// Primitive ids: the world's triangles `0..n`, then each instance's triangles (its
/// object's, in their order; `GpuInstance::info[0]` the first), then spheres. Triangle
/// records (the triangle buffer): the world's, then each object's once. One tree at node
/// 0 holds the world's primitives and the instances (instance k's reference `n + k`: never
/// a primitive of the top tree, whose triangle ids stop at n); each object's tree follows,
/// its leaves holding the records of the object's triangles.
pub fn prepare(scene: &Scene, kind: BvhKind) -> anyhow::Result<BvhData> {
    let ntri = scene.triangles.len();
    // The objects' records and the instances' ids.
    let mut object_first = Vec::with_capacity(scene.objects.len());
    let mut records = ntri as u64;
    for o in &scene.objects {
        object_first.push(records);
        records += o.triangles.len() as u64;
    }
    let mut instance_first = Vec::with_capacity(scene.instances.len());
    let mut ids = ntri as u64;
    for i in &scene.instances {
        let n = scene.objects[i.object as usize].triangles.len() as u64;
        if n == 0 {
            anyhow::bail!("internal error: an instance of an object without triangles");
        }
        instance_first.push(ids);
        ids += n;
    }
    if ids + scene.spheres.len() as u64 > MAX_PRIMITIVE_IDS {
        anyhow::bail!(
            "the scene draws {ids} triangles (its instances' counted once per instance) and {} spheres: more than the {MAX_PRIMITIVE_IDS} primitives a 32-bit id names",
            scene.spheres.len()
        );
    }
    let triangle_ids = ids as u32;
    // The objects' trees first: the top tree bounds each instance by its object's box.
    let mut object_trees = Vec::with_capacity(scene.objects.len());
    let mut object_orders = Vec::with_capacity(scene.objects.len());
    let mut object_bounds = Vec::with_capacity(scene.objects.len());
    // Each object's tree on its own, the objects shared out to every core (a tree
    // depends on its object alone, so the order of the work does not matter).
    let mut objects: Vec<&crate::scene::Object> = scene.objects.iter().collect();
    let built = map_in_parallel(&mut objects, threads(), |o| {
        let bounds: Vec<Aabb> = o
            .triangles
            .iter()
            .map(|t| geometry::triangle_bounds(t.v))
            .collect();
        let whole = bounds.iter().fold(Aabb::empty(), |a, &b| a.union(b));
        let mut built = build_tree(&bounds, kind);
        let order = leaf_order(o.triangles.len(), &mut built.prim_refs)?;
        anyhow::Ok((whole, built, order))
    });
    for b in built {
        let (whole, built, order) = b?;
        object_bounds.push(whole);
        object_orders.push(order);
        object_trees.push(built);
    }
    // The top tree. (Hidden spheres — invisible lights — are left out: no ray meets
    // them. `ids` maps the builder's primitive indices back to references.)
    let mut bounds = triangle_bounds(&scene.triangles);
    let mut refs: Vec<u32> = (0..ntri as u32).collect();
    for (i, s) in scene.spheres.iter().enumerate() {
        if !s.hidden {
            bounds.push(geometry::sphere_world_bounds(&s.object_to_world));
            refs.push(triangle_ids + i as u32);
        }
    }
    for (k, inst) in scene.instances.iter().enumerate() {
        bounds.push(geometry::transformed_bounds(
            &object_bounds[inst.object as usize],
            &inst.object_to_world,
        ));
        refs.push((ntri + k) as u32);
    }
    let mut top = build_tree(&bounds, kind);
    top.prim_refs = top.prim_refs.iter().map(|&p| refs[p as usize]).collect();
    let deepest_object = object_trees.iter().map(|t| t.depth).max().unwrap_or(0);
    match kind {
        BvhKind::Binary => {
            // A walk holds at most a node per level of each tree and a leaf's instances.
            let deepest = top.depth
                + deepest_object
                + bvh::MAX_LEAF_SIZE as usize * (deepest_object > 0) as usize;
            if deepest > MAX_BVH_DEPTH {
                anyhow::bail!(
                    "the BVH is {deepest} levels deep (its instances' trees included); the kernels' traversal stack holds {MAX_BVH_DEPTH}"
                );
            }
        }
        BvhKind::Compressed => {
            // Entering an instance keeps a leaf's and a node's rest and the instance's end.
            let deepest = top.depth
                + if deepest_object > 0 {
                    deepest_object + 3
                } else {
                    0
                };
            if deepest > cwbvh::STACK_SIZE {
                anyhow::bail!(
                    "the compressed BVH is {deepest} levels deep (its instances' trees included); the kernels' traversal stack holds {} (try --accel bvh2)",
                    cwbvh::STACK_SIZE
                );
            }
        }
    }
    let triangle_order = leaf_order(ntri, &mut top.prim_refs)?;
    // Lay the trees out: the top tree at node 0, each object's after it.
    let mut nodes = top.tree.bytes().to_vec();
    let mut prim_refs = top.prim_refs;
    let mut node_count = top.tree.len() as u32;
    let mut roots = Vec::with_capacity(object_trees.len());
    for (o, mut t) in object_trees.into_iter().enumerate() {
        let first = object_first[o] as u32;
        t.tree.rebase(node_count, prim_refs.len() as u32);
        roots.push(node_count);
        node_count += t.tree.len() as u32;
        nodes.extend_from_slice(t.tree.bytes());
        prim_refs.extend(t.prim_refs.iter().map(|&p| first + p));
    }
    let instances = scene
        .instances
        .iter()
        .enumerate()
        .map(|(k, inst)| {
            let o = inst.object as usize;
            let o2w = inst.object_to_world.transpose().to_cols_array_2d(); // rows
            let w2o = inst
                .object_to_world
                .inverse()
                .transpose()
                .to_cols_array_2d();
            let first_id = instance_first[k] as u32;
            GpuInstance {
                w2o0: w2o[0],
                w2o1: w2o[1],
                w2o2: w2o[2],
                o2w0: o2w[0],
                o2w1: o2w[1],
                o2w2: o2w[2],
                info: [
                    first_id,
                    first_id.wrapping_sub(object_first[o] as u32),
                    roots[o],
                    inst.swaps_handedness() as u32,
                ],
            }
        })
        .collect();
    Ok(BvhData {
        nodes,
        prim_refs,
        triangle_order,
        object_orders,
        instances,
        triangle_ids,
    })
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The leaf order is the references' first-seen order: the references name the new
    /// slots of the triangles they named, ids past the triangles (spheres, instances) are
    /// left alone, and a lost triangle is an error.
    #[test]
    fn leaf_order_is_the_references_first_seen_order() {
        let n = 1000;
        // A permutation of long and short cycles, with repeats and ids past the end.
        let mut refs: Vec<u32> = (0..n).map(|i| (i * 389 + 17) % n).collect();
        refs.insert(10, refs[3]);
        refs.insert(500, n + 4);
        let before = refs.clone();
        let order = leaf_order(n as usize, &mut refs).unwrap();
        let mut seen = std::collections::HashSet::new();
        let first_seen: Vec<u32> = before
            .iter()
            .copied()
            .filter(|&p| p < n && seen.insert(p))
            .collect();
        assert_eq!(order, first_seen);
        for (new, old) in refs.iter().zip(&before) {
            if *old >= n {
                assert_eq!(new, old);
            } else {
                assert_eq!(order[*new as usize], *old);
            }
        }
        assert!(leaf_order(n as usize, &mut [0, 1, 2]).is_err());
    }
}

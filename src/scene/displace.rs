//! Displaced meshes (pbrt-v4's `plymesh` with a `displacement` texture): the mesh is
//! refined until no edge is longer than an edge length (measured in rendering space),
//! then every vertex moves along its normal by the displacement texture's value at its
//! (u, v), and the normals are made again from the displaced faces.
//!
//! Refinement follows pbrt-v4's rule: a triangle with an edge at least the edge length
//! long is halved across its longest edge (the new vertex at the edge's midpoint, its
//! normal and (u, v) the edge's averages), and both halves are refined again. A split
//! edge is remembered, so the triangle on its other side splits at the same vertex and
//! the displaced surface has no cracks.
use glam::{Vec2, Vec3};
use std::collections::HashMap;

/// The most triangles a displaced mesh may be refined into.
pub const MAX_DISPLACED_TRIANGLES: usize = 8_000_000;

/// A mesh to displace: its points, normals, (u, v) and three indices per triangle.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DisplacedMesh {
    pub p: Vec<Vec3>,
    pub n: Vec<Vec3>,
    pub uv: Vec<Vec2>,
    pub indices: Vec<u32>,
}

/// Each vertex's normal: the mean of the unit normals of the faces around it, each
/// face's normal (p1 − p0) × (p2 − p1) (pbrt-v4's `ComputeNormals`, unweighted by area);
/// a vertex on no face of non-zero area has a zero normal.
pub fn vertex_normals(p: &[Vec3], indices: &[u32]) -> Vec<Vec3> {
    let mut n = vec![Vec3::ZERO; p.len()];
    for t in indices.chunks_exact(3) {
        let [a, b, c] = [t[0], t[1], t[2]].map(|i| i as usize);
        let face = (p[b] - p[a]).cross(p[c] - p[b]);
        if face.length_squared() > 0.0 {
            let face = face.normalize();
            n[a] += face;
            n[b] += face;
            n[c] += face;
        }
    }
    for v in &mut n {
        *v = v.normalize_or_zero();
    }
    n
}

/// Refine `mesh` until every edge is shorter than `edge_length` (as `distance` measures
/// it), displace each vertex along its normal by `displacement(p, n, uv)` and make the
/// normals again. Errors when the refined mesh would pass `max_triangles`
/// ([`MAX_DISPLACED_TRIANGLES`] for scenes).
pub fn displace(
    mesh: &DisplacedMesh,
    edge_length: f32,
    max_triangles: usize,
    distance: impl Fn(Vec3, Vec3) -> f32,
    displacement: impl Fn(Vec3, Vec3, Vec2) -> f32,
) -> Result<DisplacedMesh, String> {
    if !(edge_length > 0.0) {
        return Err(format!("edge length {edge_length} (expected more than 0)"));
    }
    let mut out = DisplacedMesh {
        p: mesh.p.clone(),
        n: mesh.n.clone(),
        uv: mesh.uv.clone(),
        indices: Vec::with_capacity(mesh.indices.len()),
    };
    let mut split: HashMap<(u32, u32), u32> = HashMap::new();
    // Each triangle to refine, on a stack (deep refinement would be deep recursion).
    let mut stack: Vec<[u32; 3]> = Vec::new();
    for t in mesh.indices.chunks_exact(3) {
        stack.push([t[0], t[1], t[2]]);
        while let Some(v) = stack.pop() {
            let [p0, p1, p2] = v.map(|i| out.p[i as usize]);
            let d = [distance(p0, p1), distance(p1, p2), distance(p2, p0)];
            if d.iter().all(|&x| x < edge_length) {
                if out.indices.len() / 3 >= max_triangles {
                    return Err(format!(
                        "refined to edges shorter than {edge_length}, the mesh would pass \
                         {max_triangles} triangles (a larger edgelength makes fewer)"
                    ));
                }
                out.indices.extend_from_slice(&v);
                continue;
            }
            // Rotate so that the longest edge is v[0]–v[1] (the first longest, as
            // pbrt-v4 orders ties).
            let [a, b, c] = if d[0] > d[1] {
                if d[0] > d[2] {
                    v
                } else {
                    [v[2], v[0], v[1]]
                }
            } else if d[1] > d[2] {
                [v[1], v[2], v[0]]
            } else {
                [v[2], v[0], v[1]]
            };
            let key = (a.min(b), a.max(b));
            let mid = *split.entry(key).or_insert_with(|| {
                let (ia, ib) = (a as usize, b as usize);
                out.p.push((out.p[ia] + out.p[ib]) / 2.0);
                out.n.push((out.n[ia] + out.n[ib]).normalize_or_zero());
                out.uv.push((out.uv[ia] + out.uv[ib]) / 2.0);
                out.p.len() as u32 - 1
            });
            // The second half first on the stack: the first is refined first, as a
            // recursion would.
            stack.push([mid, b, c]);
            stack.push([a, mid, c]);
        }
    }
    for i in 0..out.p.len() {
        let d = displacement(out.p[i], out.n[i], out.uv[i]);
        out.p[i] += d * out.n[i];
    }
    out.n = vertex_normals(&out.p, &out.indices);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    const N: usize = MAX_DISPLACED_TRIANGLES;

    /// A square of side `side` in the z = 0 plane, two triangles, (u, v) = (x, y) / side,
    /// normals +z.
    fn square(side: f32) -> DisplacedMesh {
        DisplacedMesh {
            p: vec![
                Vec3::ZERO,
                Vec3::new(side, 0.0, 0.0),
                Vec3::new(side, side, 0.0),
                Vec3::new(0.0, side, 0.0),
            ],
            n: vec![Vec3::Z; 4],
            uv: vec![Vec2::ZERO, Vec2::X, Vec2::ONE, Vec2::Y],
            indices: vec![0, 1, 2, 0, 2, 3],
        }
    }

    fn edges(m: &DisplacedMesh) -> HashMap<(u32, u32), u32> {
        let mut count = HashMap::new();
        for t in m.indices.chunks_exact(3) {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                *count.entry((a.min(b), a.max(b))).or_insert(0) += 1;
            }
        }
        count
    }

    #[test]
    fn a_constant_displacement_lifts_a_refined_square_without_cracks() {
        let m = displace(&square(4.0), 0.7, N, |a, b| a.distance(b), |_, _, _| 0.25).unwrap();
        assert!(
            m.indices.len() / 3 > 2 * 36,
            "{} triangles",
            m.indices.len() / 3
        );
        let mut area = 0.0;
        for t in m.indices.chunks_exact(3) {
            let [a, b, c] = [t[0], t[1], t[2]].map(|i| m.p[i as usize]);
            for (x, y) in [(a, b), (b, c), (c, a)] {
                assert!(x.distance(y) < 0.7, "an edge of {}", x.distance(y));
            }
            let n = (b - a).cross(c - b);
            assert!(n.z > 0.0, "a triangle turned over");
            area += 0.5 * n.length();
        }
        assert!((area - 16.0).abs() < 1e-3, "area {area}");
        for (i, p) in m.p.iter().enumerate() {
            assert_eq!(p.z, 0.25, "vertex {i} at {p}");
            assert!((m.n[i] - Vec3::Z).length() < 1e-6, "normal {}", m.n[i]);
            // (u, v) still follows the point.
            assert!((m.uv[i] * 4.0 - p.truncate()).length() < 1e-5);
        }
        // Crack-free: each edge borders two triangles, but those of the square's sides
        // (one), and the sides' edges add up to its perimeter.
        let mut border = 0.0;
        for (&(a, b), &k) in &edges(&m) {
            let (pa, pb) = (m.p[a as usize], m.p[b as usize]);
            let on_side = |p: Vec3| p.x == 0.0 || p.x == 4.0 || p.y == 0.0 || p.y == 4.0;
            let side = on_side(pa) && on_side(pb) && (pa.x == pb.x || pa.y == pb.y);
            assert_eq!(k, if side { 1 } else { 2 }, "edge {pa} {pb}");
            if side {
                border += pa.distance(pb);
            }
        }
        assert!((border - 16.0).abs() < 1e-4, "border {border}");
    }

    #[test]
    fn a_ramp_tilts_the_square_and_its_normals() {
        // d = u: the square becomes the plane z = x / 4.
        let m = displace(&square(4.0), 1.0, N, |a, b| a.distance(b), |_, _, uv| uv.x).unwrap();
        let want = Vec3::new(-0.25, 0.0, 1.0).normalize();
        for (p, n) in m.p.iter().zip(&m.n) {
            assert!((p.z - p.x / 4.0).abs() < 1e-6, "{p}");
            assert!((*n - want).length() < 1e-5, "normal {n}");
        }
    }

    #[test]
    fn edges_are_measured_as_the_caller_measures_them() {
        // Distances doubled (a scale of 2 to rendering space): edges half as long.
        let once = displace(&square(4.0), 1.0, N, |a, b| a.distance(b), |_, _, _| 0.0).unwrap();
        let twice = displace(
            &square(4.0),
            1.0,
            N,
            |a, b| 2.0 * a.distance(b),
            |_, _, _| 0.0,
        )
        .unwrap();
        assert!(twice.indices.len() >= 3 * once.indices.len());
        // Short enough already: the mesh as it was (normals made again).
        let same = displace(&square(4.0), 10.0, N, |a, b| a.distance(b), |_, _, _| 0.0).unwrap();
        assert_eq!(same.indices, square(4.0).indices);
        assert_eq!(same.p, square(4.0).p);
    }

    #[test]
    fn too_fine_a_refinement_is_an_error() {
        let e = displace(
            &square(4.0),
            0.01,
            1000,
            |a, b| a.distance(b),
            |_, _, _| 0.0,
        )
        .unwrap_err();
        assert!(e.contains("1000 triangles"), "{e}");
        assert!(displace(&square(1.0), 0.0, N, |a, b| a.distance(b), |_, _, _| 0.0).is_err());
    }
}

//! Loop subdivision (Loop 1987) for pbrt's `loopsubdiv` shape: each level splits every
//! triangle in four, moving old vertices by Loop's vertex mask and placing new ones on
//! edges by the edge mask (boundary edges and vertices by the cubic B-spline's boundary
//! rules, so an open mesh keeps its border curve); after the last level every vertex is
//! moved to its limit position. Shading normals are the area-weighted averages of the
//! limit mesh's face normals.
use glam::Vec3;
use std::collections::HashMap;

/// An edge's key: its two vertices, smaller first.
fn key(a: u32, b: u32) -> (u32, u32) {
    (a.min(b), a.max(b))
}

/// What one level needs to know about the mesh's connectivity.
struct Topology {
    /// Each vertex's neighbours (over any edge).
    ring: Vec<Vec<u32>>,
    /// Each vertex's neighbours over boundary edges (two for a border vertex).
    border: Vec<Vec<u32>>,
    /// Each edge's opposite vertices (one per face; two inside, one on the border).
    edges: HashMap<(u32, u32), Vec<u32>>,
}

fn topology(vertices: usize, tris: &[[u32; 3]]) -> Result<Topology, String> {
    let mut edges: HashMap<(u32, u32), Vec<u32>> = HashMap::new();
    for t in tris {
        for k in 0..3 {
            let (a, b, c) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
            if a == b {
                return Err(format!("a degenerate triangle repeats vertex {a}"));
            }
            let opposite = edges.entry(key(a, b)).or_default();
            opposite.push(c);
            if opposite.len() > 2 {
                return Err(format!(
                    "the edge between vertices {a} and {b} has more than two triangles \
                     (Loop subdivision needs a manifold mesh)"
                ));
            }
        }
    }
    let mut ring = vec![Vec::new(); vertices];
    let mut border = vec![Vec::new(); vertices];
    // (Sorted keys keep the neighbour order, and so the rounding, the same every run.)
    let mut keys: Vec<_> = edges.keys().copied().collect();
    keys.sort_unstable();
    for (a, b) in keys {
        ring[a as usize].push(b);
        ring[b as usize].push(a);
        if edges[&(a, b)].len() == 1 {
            border[a as usize].push(b);
            border[b as usize].push(a);
        }
    }
    Ok(Topology {
        ring,
        border,
        edges,
    })
}

/// Loop's weight of each neighbour of an interior vertex of valence n.
fn beta(n: usize) -> f32 {
    if n == 3 {
        3.0 / 16.0
    } else {
        3.0 / (8.0 * n as f32)
    }
}

/// The vertex rule with neighbour weight w: (1 - n w) v + w Σ neighbours.
fn one_ring(p: &[Vec3], v: usize, ring: &[u32], w: f32) -> Vec3 {
    let sum: Vec3 = ring.iter().map(|&i| p[i as usize]).sum();
    p[v] * (1.0 - ring.len() as f32 * w) + sum * w
}

/// One level: old vertices moved, a vertex per edge, four triangles per triangle.
fn refine(p: &[Vec3], tris: &[[u32; 3]]) -> Result<(Vec<Vec3>, Vec<[u32; 3]>), String> {
    let top = topology(p.len(), tris)?;
    let mut out: Vec<Vec3> = (0..p.len())
        .map(|v| {
            let (ring, border) = (&top.ring[v], &top.border[v]);
            if border.is_empty() {
                if ring.is_empty() {
                    p[v]
                } else {
                    one_ring(p, v, ring, beta(ring.len()))
                }
            } else if border.len() == 2 {
                p[v] * 0.75 + (p[border[0] as usize] + p[border[1] as usize]) * 0.125
            } else {
                // A corner where the border meets itself: kept in place.
                p[v]
            }
        })
        .collect();
    let mut edge_vertex: HashMap<(u32, u32), u32> = HashMap::with_capacity(top.edges.len());
    let mut keys: Vec<_> = top.edges.keys().copied().collect();
    keys.sort_unstable();
    for (a, b) in keys {
        let opposite = &top.edges[&(a, b)];
        let (pa, pb) = (p[a as usize], p[b as usize]);
        let q = if opposite.len() == 2 {
            (pa + pb) * 0.375 + (p[opposite[0] as usize] + p[opposite[1] as usize]) * 0.125
        } else {
            (pa + pb) * 0.5
        };
        edge_vertex.insert((a, b), out.len() as u32);
        out.push(q);
    }
    let mut new_tris = Vec::with_capacity(tris.len() * 4);
    for t in tris {
        let [a, b, c] = *t;
        let ab = edge_vertex[&key(a, b)];
        let bc = edge_vertex[&key(b, c)];
        let ca = edge_vertex[&key(c, a)];
        new_tris.extend([[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]);
    }
    Ok((out, new_tris))
}

/// Subdivides the triangle mesh (p, indices) `levels` times and moves its vertices to
/// the limit surface; returns the points, the indices and per-vertex normals.
pub fn loop_subdivide(
    p: &[Vec3],
    indices: &[u32],
    levels: u32,
) -> Result<(Vec<Vec3>, Vec<u32>, Vec<Vec3>), String> {
    if indices.len() % 3 != 0 {
        return Err(format!("{} indices, not a multiple of 3", indices.len()));
    }
    if let Some(bad) = indices.iter().find(|&&i| i as usize >= p.len()) {
        return Err(format!("index {bad} out of range ({} points)", p.len()));
    }
    let mut tris: Vec<[u32; 3]> = indices.chunks(3).map(|c| [c[0], c[1], c[2]]).collect();
    let mut p = p.to_vec();
    for _ in 0..levels {
        (p, tris) = refine(&p, &tris)?;
    }
    // The limit positions: interior vertices by Loop's limit mask, border vertices by
    // the B-spline's (1/5, 3/5, 1/5).
    let top = topology(p.len(), &tris)?;
    let limit: Vec<Vec3> = (0..p.len())
        .map(|v| {
            let (ring, border) = (&top.ring[v], &top.border[v]);
            if border.is_empty() && !ring.is_empty() {
                let n = ring.len();
                one_ring(&p, v, ring, 1.0 / (n as f32 + 3.0 / (8.0 * beta(n))))
            } else if border.len() == 2 {
                p[v] * 0.6 + (p[border[0] as usize] + p[border[1] as usize]) * 0.2
            } else {
                p[v]
            }
        })
        .collect();
    let mut normals = vec![Vec3::ZERO; limit.len()];
    for t in &tris {
        let [a, b, c] = t.map(|i| i as usize);
        let n = (limit[b] - limit[a]).cross(limit[c] - limit[a]);
        for v in [a, b, c] {
            normals[v] += n;
        }
    }
    let normals = normals
        .into_iter()
        .map(|n| n.try_normalize().unwrap_or(Vec3::Z))
        .collect();
    Ok((limit, tris.into_iter().flatten().collect(), normals))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn octahedron() -> (Vec<Vec3>, Vec<u32>) {
        let p = vec![Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z];
        let indices = vec![
            0, 2, 4, 2, 1, 4, 1, 3, 4, 3, 0, 4, 2, 0, 5, 1, 2, 5, 3, 1, 5, 0, 3, 5,
        ];
        (p, indices)
    }

    #[test]
    fn a_closed_octahedron_becomes_a_smooth_round_surface() {
        let (p, indices) = octahedron();
        let (q, tris, n) = loop_subdivide(&p, &indices, 4).unwrap();
        assert_eq!(tris.len(), indices.len() * 256);
        // Euler: V - E + F = 2 with F = 8·4^4 triangles and E = 3F/2.
        let f = tris.len() / 3;
        assert_eq!(q.len(), 2 + f / 2);
        let r: Vec<f32> = q.iter().map(|v| v.length()).collect();
        let (lo, hi) = r
            .iter()
            .fold((f32::MAX, 0.0f32), |(a, b), &x| (a.min(x), b.max(x)));
        // The limit surface of the octahedron is a rounded octahedron: the control
        // points (radius 1) go to radius 1/2, the faces' centres to about 0.42 (the
        // control polygon's radius varies by 73%, the limit's by 20%).
        assert!(hi / lo < 1.25, "radius from {lo} to {hi}");
        assert!(
            lo > 0.4 && (hi - 0.5).abs() < 1e-5,
            "radius from {lo} to {hi}"
        );
        // Its normals point outward, within 18° of the position (it is nearly round), and
        // each triangle keeps the orientation of the face it came from.
        for (v, n) in q.iter().zip(&n) {
            assert!(n.dot(v.normalize()) > 0.95, "normal {n} at {v}");
        }
        for t in tris.chunks(3) {
            let [a, b, c] = [t[0], t[1], t[2]].map(|i| q[i as usize]);
            assert!((b - a).cross(c - a).dot(a + b + c) > 0.0);
        }
    }

    #[test]
    fn a_flat_open_patch_stays_flat_and_keeps_its_border() {
        // A 3x3 grid of squares in z = 0, split into triangles.
        let mut p = Vec::new();
        for y in 0..4 {
            for x in 0..4 {
                p.push(Vec3::new(x as f32, y as f32, 0.0));
            }
        }
        let mut indices = Vec::new();
        for y in 0..3u32 {
            for x in 0..3u32 {
                let i = y * 4 + x;
                indices.extend([i, i + 1, i + 5, i, i + 5, i + 4]);
            }
        }
        let (q, tris, n) = loop_subdivide(&p, &indices, 3).unwrap();
        assert_eq!(tris.len(), indices.len() * 64);
        for (v, n) in q.iter().zip(&n) {
            assert_eq!(v.z, 0.0);
            assert!((*n - Vec3::Z).length() < 1e-5);
            // (The border's corners are kept; its edges stay on the square's sides.)
            assert!(v.x >= -1e-5 && v.x <= 3.0 + 1e-5 && v.y >= -1e-5 && v.y <= 3.0 + 1e-5);
        }
        // Affine invariance: an interior vertex of a regular grid stays where it is.
        let centre = q
            .iter()
            .any(|v| (*v - Vec3::new(1.0, 1.0, 0.0)).length() < 1e-5);
        assert!(centre);
    }

    #[test]
    fn no_levels_is_the_limit_of_the_control_mesh_and_bad_meshes_are_errors() {
        let (p, indices) = octahedron();
        let (q, tris, _) = loop_subdivide(&p, &indices, 0).unwrap();
        assert_eq!(tris, indices);
        // Valence 4: the limit mask keeps 1 - 4χ of the vertex with χ = 1/(4 + 3/(8β)).
        let chi = 1.0 / (4.0 + 3.0 / (8.0 * beta(4)));
        assert!((q[4].z - (1.0 - 4.0 * chi)).abs() < 1e-6);
        assert!(loop_subdivide(&p, &[0, 1], 1).is_err());
        assert!(loop_subdivide(&p, &[0, 1, 9], 1).is_err());
        assert!(loop_subdivide(&p, &[0, 0, 1], 1).is_err());
        // Three triangles on one edge.
        assert!(loop_subdivide(&p, &[0, 1, 2, 0, 1, 3, 0, 1, 4], 1)
            .unwrap_err()
            .contains("manifold"));
    }
}

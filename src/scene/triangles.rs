//! A list of triangles kept compactly: corners and material in one record, texture
//! coordinates beside it, shading normals and alpha only for the triangles that have them
//! (as the device keeps them, gpu_scene.rs `triangle_uv` and `triangle_shading`). A mesh
//! of millions of triangles with texture coordinates costs 68 bytes a triangle here, not
//! the 116 of a [`Triangle`] with every attribute in place.

use super::{Alpha, Triangle};
use glam::{Vec2, Vec3};

/// pbrt's texture coordinates for a triangle without its own: (0,0), (1,0), (1,1).
pub const DEFAULT_UV: [Vec2; 3] = [Vec2::ZERO, Vec2::X, Vec2::ONE];

/// A stored triangle's corners and material, and which attributes it has.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleCorners {
    pub v: [Vec3; 3],
    pub material: u32,
    /// `HAS_UV` if it has texture coordinates of its own; the rest, its shading record's
    /// index, or `NO_SHADING`.
    attributes: u32,
}

const HAS_UV: u32 = 1 << 31;
const NO_SHADING: u32 = HAS_UV - 1;

/// A triangle's shading normals and alpha (stored for those that have either).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Shading {
    normals: Option<[Vec3; 3]>,
    alpha: Option<Alpha>,
}

impl TriangleCorners {
    /// Whether it has texture coordinates, shading normals or alpha (a device
    /// texture-coordinate record).
    pub fn has_attributes(&self) -> bool {
        self.attributes != NO_SHADING
    }

    /// Whether it has shading normals or alpha (a device shading record).
    pub fn has_shading(&self) -> bool {
        self.attributes & NO_SHADING != NO_SHADING
    }
}

/// The triangles of the world or of an object, in order. Reads as a slice of
/// [`TriangleCorners`] (corners and material); [`Triangles::get`] gives a whole
/// [`Triangle`].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Triangles {
    corners: Vec<TriangleCorners>,
    /// Each triangle's texture coordinates (`DEFAULT_UV` where it has none).
    uv: Vec<[Vec2; 3]>,
    shading: Vec<Shading>,
}

impl std::ops::Deref for Triangles {
    type Target = [TriangleCorners];
    fn deref(&self) -> &[TriangleCorners] {
        &self.corners
    }
}

impl<'a> IntoIterator for &'a Triangles {
    type Item = &'a TriangleCorners;
    type IntoIter = std::slice::Iter<'a, TriangleCorners>;
    fn into_iter(self) -> Self::IntoIter {
        self.corners.iter()
    }
}

impl FromIterator<Triangle> for Triangles {
    fn from_iter<I: IntoIterator<Item = Triangle>>(iter: I) -> Triangles {
        let mut list = Triangles::default();
        list.extend(iter);
        list
    }
}

impl Extend<Triangle> for Triangles {
    fn extend<I: IntoIterator<Item = Triangle>>(&mut self, iter: I) {
        for t in iter {
            self.push(t);
        }
    }
}

impl Triangles {
    /// Triangle `t`'s record, its shading record (if any) being `shading`.
    fn corners(t: &Triangle, shading: u32) -> TriangleCorners {
        TriangleCorners {
            v: t.v,
            material: t.material,
            attributes: if t.uv.is_some() { HAS_UV } else { 0 } | shading,
        }
    }

    fn shading_of(t: &Triangle) -> Option<Shading> {
        t.has_shading().then_some(Shading {
            normals: t.normals,
            alpha: t.alpha,
        })
    }

    pub fn push(&mut self, t: Triangle) {
        let s = match Self::shading_of(&t) {
            Some(s) => {
                self.shading.push(s);
                (self.shading.len() - 1) as u32
            }
            None => NO_SHADING,
        };
        assert!(
            s <= NO_SHADING,
            "more than 2^31 - 1 triangles with shading records"
        );
        self.corners.push(Self::corners(&t, s));
        self.uv.push(t.uv.unwrap_or(DEFAULT_UV));
    }

    /// Triangle `i`, whole.
    pub fn get(&self, i: usize) -> Triangle {
        let c = &self.corners[i];
        let s = c.attributes & NO_SHADING;
        let shading = (s != NO_SHADING).then(|| self.shading[s as usize]);
        Triangle {
            v: c.v,
            material: c.material,
            uv: (c.attributes & HAS_UV != 0).then_some(self.uv[i]),
            normals: shading.and_then(|s| s.normals),
            alpha: shading.and_then(|s| s.alpha),
        }
    }

    /// Triangle `i`'s texture coordinates (pbrt's default where it has none of its own).
    pub fn uv(&self, i: usize) -> [Vec2; 3] {
        self.uv[i]
    }

    /// Triangle `i`'s shading normals.
    pub fn normals(&self, i: usize) -> Option<[Vec3; 3]> {
        let s = self.corners[i].attributes & NO_SHADING;
        (s != NO_SHADING).then(|| self.shading[s as usize].normals)?
    }

    /// Triangle `i`'s alpha.
    pub fn alpha(&self, i: usize) -> Option<Alpha> {
        let s = self.corners[i].attributes & NO_SHADING;
        (s != NO_SHADING).then(|| self.shading[s as usize].alpha)?
    }

    /// The triangles' alphas (one for each triangle that has one; read from the shading
    /// records alone).
    pub fn alphas(&self) -> impl Iterator<Item = Alpha> + '_ {
        self.shading.iter().filter_map(|s| s.alpha)
    }

    /// Every triangle, whole.
    pub fn all(&self) -> impl Iterator<Item = Triangle> + '_ {
        (0..self.len()).map(|i| self.get(i))
    }

    /// Triangle `i` replaced by `t` (its old shading record reused, or one added).
    pub fn set(&mut self, i: usize, t: Triangle) {
        let old = self.corners[i].attributes & NO_SHADING;
        let s = match Self::shading_of(&t) {
            Some(s) if old != NO_SHADING => {
                self.shading[old as usize] = s;
                old
            }
            Some(s) => {
                self.shading.push(s);
                (self.shading.len() - 1) as u32
            }
            None => {
                // (Left unused, with no alpha for `alphas` to find.)
                if old != NO_SHADING {
                    self.shading[old as usize] = Shading {
                        normals: None,
                        alpha: None,
                    };
                }
                NO_SHADING
            }
        };
        self.corners[i] = Self::corners(&t, s);
        self.uv[i] = t.uv.unwrap_or(DEFAULT_UV);
    }

    pub fn reserve(&mut self, n: usize) {
        self.corners.reserve(n);
        self.uv.reserve(n);
    }

    pub fn clear(&mut self) {
        self.corners.clear();
        self.uv.clear();
        self.shading.clear();
    }

    /// Appends `make` of each of `inputs`' pieces of `3 * piece` words (every third word
    /// a corner index: a triangle's three), skipping the Nones, in order: the pieces made
    /// on every core, each written at its start in the lists' spare capacity, then moved
    /// down over the gaps the Nones left and their shading records' indices shifted by
    /// the records the pieces before them made: the same list as one by one. (Straight
    /// into the list: a copy of a mesh of millions of triangles costs its memory twice,
    /// and the time to touch it.)
    pub fn extend_in_parallel(
        &mut self,
        indices: &[u32],
        piece: usize,
        make: impl Fn(&[u32]) -> Option<Triangle> + Sync,
    ) {
        let count = indices.len() / 3;
        self.reserve(count);
        let start = self.corners.len();
        let corners = &mut self.corners.spare_capacity_mut()[..count];
        let uvs = &mut self.uv.spare_capacity_mut()[..count];
        let mut pieces: Vec<_> = corners
            .chunks_mut(piece)
            .zip(uvs.chunks_mut(piece))
            .zip(indices.chunks(3 * piece))
            .collect();
        let made = crate::accel::map_in_parallel(
            &mut pieces,
            crate::accel::threads(),
            |((corners, uvs), indices)| {
                let mut shading = Vec::new();
                let mut n = 0;
                for t in indices.chunks(3).filter_map(&make) {
                    let s = match Self::shading_of(&t) {
                        Some(s) => {
                            shading.push(s);
                            (shading.len() - 1) as u32
                        }
                        None => NO_SHADING,
                    };
                    corners[n].write(Self::corners(&t, s));
                    uvs[n].write(t.uv.unwrap_or(DEFAULT_UV));
                    n += 1;
                }
                (n, shading)
            },
        );
        let mut end = 0;
        // Each piece's count and the shading records before its own (0: none to shift).
        let mut shifts = Vec::with_capacity(made.len());
        for (k, (n, shading)) in made.into_iter().enumerate() {
            if end != k * piece {
                let from = k * piece..k * piece + n;
                corners.copy_within(from.clone(), end);
                uvs.copy_within(from, end);
            }
            let before = if shading.is_empty() {
                0
            } else {
                self.shading.len() as u32
            };
            shifts.push((n, before));
            assert!(
                self.shading.len() + shading.len() <= NO_SHADING as usize,
                "more than 2^31 - 1 triangles with shading records"
            );
            self.shading.extend(shading);
            end += n;
        }
        // Each piece's shading indices shifted by the records before it, every piece at
        // once.
        let mut rest = &mut corners[..end];
        let mut parts = Vec::new();
        for (n, before) in shifts {
            let (part, tail) = std::mem::take(&mut rest).split_at_mut(n);
            if before > 0 {
                parts.push((part, before));
            }
            rest = tail;
        }
        crate::accel::map_in_parallel(&mut parts, crate::accel::threads(), |(part, before)| {
            for c in part.iter_mut() {
                // SAFETY: written by the piece's maker and moved here above.
                let c = unsafe { c.assume_init_mut() };
                if c.attributes & NO_SHADING != NO_SHADING {
                    c.attributes += *before;
                }
            }
        });
        // SAFETY: the first `end` spare records of both lists were written just above (each
        // piece's first n, moved down in order).
        unsafe {
            self.corners.set_len(start + end);
            self.uv.set_len(start + end);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Triangle `i` of a made-up list: texture coordinates, normals and alpha on and off in
    /// patterns that do not line up; None for every 7th (no area, say).
    fn made(i: u32) -> Option<Triangle> {
        if i % 7 == 3 {
            return None;
        }
        let x = i as f32;
        let mut t = Triangle::new([Vec3::new(x, 0.0, 0.0), Vec3::X, Vec3::Y], i % 5);
        if i % 2 == 0 {
            t.uv = Some([Vec2::splat(x), Vec2::X, Vec2::Y]);
        }
        if i % 3 == 0 {
            t.normals = Some([Vec3::Z, Vec3::new(0.0, x, 1.0).normalize(), Vec3::Z]);
        }
        if i % 11 < 2 {
            t.alpha = Some(if i % 11 == 0 {
                Alpha::Constant(x / 1000.0)
            } else {
                Alpha::Texture(i)
            });
        }
        Some(t)
    }

    #[test]
    fn every_triangle_reads_back_whole_and_knows_its_attributes() {
        let wanted: Vec<Triangle> = (0..500).filter_map(made).collect();
        let list: Triangles = wanted.iter().copied().collect();
        assert_eq!(list.len(), wanted.len());
        for (i, t) in wanted.iter().enumerate() {
            assert_eq!(list.get(i), *t, "triangle {i}");
            assert_eq!(list[i].v, t.v);
            assert_eq!(list[i].material, t.material);
            assert_eq!(list[i].has_attributes(), t.has_attributes(), "triangle {i}");
            assert_eq!(list[i].has_shading(), t.has_shading(), "triangle {i}");
            assert_eq!(list.uv(i), t.uv.unwrap_or(DEFAULT_UV));
            assert_eq!((list.normals(i), list.alpha(i)), (t.normals, t.alpha));
        }
        let alphas: Vec<Alpha> = wanted.iter().filter_map(|t| t.alpha).collect();
        assert_eq!(list.alphas().collect::<Vec<_>>(), alphas);
        // Replaced: with shading over shading, none over shading, shading over none.
        let mut list = list;
        let (a, b, c) = (0, 1, 2);
        assert!(list[a].has_shading() && list[b].has_shading() && !list[c].has_shading());
        let mut t = wanted[a];
        t.alpha = Some(Alpha::Constant(0.25));
        list.set(a, t);
        assert_eq!(list.get(a), t);
        list.set(b, Triangle::new(wanted[b].v, 9));
        assert_eq!(list.get(b), Triangle::new(wanted[b].v, 9));
        let mut t = wanted[c];
        t.normals = Some([Vec3::X; 3]);
        list.set(c, t);
        assert_eq!(list.get(c), t);
        let mut wanted = wanted;
        wanted[a].alpha = Some(Alpha::Constant(0.25));
        wanted[b] = Triangle::new(wanted[b].v, 9);
        wanted[c] = t;
        let alphas: Vec<Alpha> = wanted.iter().filter_map(|t| t.alpha).collect();
        let mut found: Vec<Alpha> = list.alphas().collect();
        let key = |a: &Alpha| format!("{a:?}");
        found.sort_by_key(key);
        let mut alphas = alphas;
        alphas.sort_by_key(key);
        assert_eq!(found, alphas);
    }

    #[test]
    fn made_in_parallel_pieces_is_the_list_made_one_by_one() {
        // Pieces of 8 triangles (a few hundred pieces on every core), after a start that
        // already holds triangles and shading records.
        let indices: Vec<u32> = (0..2000u32).flat_map(|i| [i, 0, 0]).collect();
        let make = |c: &[u32]| made(c[0]);
        for piece in [1, 8, 1 << 16] {
            let mut one_by_one: Triangles = (5000..5030).filter_map(made).collect();
            let mut parallel = one_by_one.clone();
            one_by_one.extend(indices.chunks(3).filter_map(make));
            parallel.extend_in_parallel(&indices, piece, make);
            assert!(parallel == one_by_one, "pieces of {piece}");
        }
    }
}

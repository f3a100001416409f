//! pbrt-v4's realistic camera (`Camera "realistic"`): a system of spherical lens
//! elements and an aperture stop, read from a lens file, focused by a thick-lens
//! approximation, with the film behind it; camera rays go from a film point through the
//! lens system into the scene (the pbr-book, 4th edition, section 5.3; Kolb et al. 1995).
//!
//! Conventions (pbrt-v4's): camera space has the film on the plane z = 0 and the scene
//! ahead along +z; x is the image's right, y its up. The lens file lists the interfaces
//! from the front (the scene's side) to the rear (the film's side); the last one's
//! thickness is the distance from the rear element to the film, which focusing sets.
//! The camera ray's weight is cos⁴θ / (p · d²): θ the angle of the ray from the film
//! point to the sampled point of the exit pupil, p that point's density (per area of the
//! plane z = d tangent to the rear element) and d the film's distance from the rear
//! element (the pbr-book's eq. 5.5): images are the film's irradiance, times pbrt-v4's
//! exposure, as pbrt-v4's are.
//!
//! The GLSL mirror is camera.glsl's `realistic_camera_ray`; `LensSystem::pack` lays the
//! system out for it.

use glam::{Vec2, Vec3};

/// The exit pupil's bounds are kept for this many intervals of the film point's distance
/// from the axis (pbrt-v4's count).
pub const PUPIL_INTERVALS: usize = crate::abi::LENS_PUPIL_INTERVALS as usize;

/// One interface of a lens system (lengths in metres).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LensElement {
    /// The signed radius of curvature (positive: the centre lies toward the film); 0: the
    /// aperture stop.
    pub radius: f32,
    /// The distance along the axis to the next interface toward the film (the last
    /// interface's: to the film).
    pub thickness: f32,
    /// The index of refraction of the medium behind the interface (toward the film); 0 on
    /// the stop's row means air.
    pub eta: f32,
    /// The radius of the interface's clear aperture.
    pub aperture: f32,
}

/// A realistic camera's lens system, focused, with its film and its exit pupil's bounds.
#[derive(Clone, Debug, PartialEq)]
pub struct LensSystem {
    /// Front (the scene's side) to rear (the film's side).
    pub elements: Vec<LensElement>,
    /// Half the film's width and height (metres).
    pub film_half: Vec2,
    /// Per interval of the film point's distance from the axis (`PUPIL_INTERVALS` over
    /// [0, half the film's diagonal]): the bounds [x0, y0, x1, y1] on the plane tangent to
    /// the rear element of the points through which rays from a film point on the +x axis
    /// in that interval pass the whole system (empty: x0 > x1).
    pub pupils: Vec<[f32; 4]>,
}

/// The rows of a lens file: four numbers per interface (radius, thickness and aperture
/// diameter in millimetres, index of refraction), `#` starting a comment.
pub fn parse_lens_file(text: &str) -> Result<Vec<[f32; 4]>, String> {
    let mut numbers = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let line = line.split('#').next().unwrap_or("");
        for token in line.split_whitespace() {
            let x: f32 = token
                .parse()
                .ok()
                .filter(|x: &f32| x.is_finite())
                .ok_or_else(|| format!("line {}: \"{token}\" is not a number", n + 1))?;
            numbers.push(x);
        }
    }
    if numbers.is_empty() || numbers.len() % 4 != 0 {
        return Err(format!(
            "a lens file has four numbers per interface (radius, thickness, index of \
             refraction, aperture diameter), this one {} numbers",
            numbers.len()
        ));
    }
    Ok(numbers
        .chunks(4)
        .map(|c| [c[0], c[1], c[2], c[3]])
        .collect())
}

/// Half the width and height of a film of diagonal `d` for an image of `width` ×
/// `height` pixels.
fn film_half(d: f32, width: u32, height: u32) -> Vec2 {
    let aspect = height as f32 / width as f32;
    let x = (d * d / (1.0 + aspect * aspect)).sqrt();
    Vec2::new(0.5 * x, 0.5 * aspect * x)
}

/// Where the ray o + t d meets the sphere of signed radius `radius` centred on the axis
/// at z = `center`, on the cap that holds the interface's vertex: t and the unit normal
/// facing back along the ray.
fn intersect_interface(o: Vec3, d: Vec3, radius: f32, center: f32) -> Option<(f32, Vec3)> {
    let oc = o - Vec3::new(0.0, 0.0, center);
    let a = d.dot(d);
    let b = 2.0 * d.dot(oc);
    let c = oc.dot(oc) - radius * radius;
    let disc = b as f64 * b as f64 - 4.0 * a as f64 * c as f64;
    if disc < 0.0 {
        return None;
    }
    let root = disc.sqrt();
    // (The stable form of the two roots.)
    let q = if b < 0.0 {
        -0.5 * (b as f64 - root)
    } else {
        -0.5 * (b as f64 + root)
    };
    let (mut t0, mut t1) = ((q / a as f64) as f32, (c as f64 / q) as f32);
    if t0 > t1 {
        std::mem::swap(&mut t0, &mut t1);
    }
    let closer = (d.z > 0.0) != (radius < 0.0);
    let t = if closer { t0 } else { t1 };
    if !(t >= 0.0) {
        return None;
    }
    let mut n = (oc + t * d).normalize();
    if n.dot(d) > 0.0 {
        n = -n;
    }
    Some((t, n))
}

/// The direction refracted from the unit direction `wi` (pointing away from the surface)
/// across the unit normal n on its side, for the ratio eta of the indices (transmitted
/// over incident); None for total internal reflection.
fn refract(wi: Vec3, n: Vec3, eta: f32) -> Option<Vec3> {
    let cos_i = n.dot(wi);
    let sin2_t = (1.0 - cos_i * cos_i).max(0.0) / (eta * eta);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    Some(-wi / eta + (cos_i / eta - cos_t) * n)
}

impl LensSystem {
    /// The lens system of `rows` (a lens file's), its stop's diameter `aperture_mm` where
    /// that is smaller than the file's, focused at `focus_distance` (metres from the
    /// film), with a film of `diagonal_mm` for an image of `width` × `height` pixels.
    pub fn new(
        rows: &[[f32; 4]],
        aperture_mm: f32,
        focus_distance: f32,
        diagonal_mm: f32,
        width: u32,
        height: u32,
    ) -> Result<LensSystem, String> {
        let elements = rows
            .iter()
            .map(|r| {
                let mut diameter = r[3];
                if r[0] == 0.0 && aperture_mm <= diameter {
                    diameter = aperture_mm;
                }
                LensElement {
                    radius: r[0] * 0.001,
                    thickness: r[1] * 0.001,
                    eta: r[2],
                    aperture: diameter * 0.0005,
                }
            })
            .collect::<Vec<_>>();
        if elements
            .iter()
            .any(|e| !(e.aperture > 0.0) || e.thickness < 0.0 || e.eta < 0.0)
        {
            return Err(
                "every interface needs a positive aperture diameter, a thickness and an index \
                 of refraction that are not negative"
                    .into(),
            );
        }
        let mut lens = LensSystem {
            elements,
            film_half: film_half(diagonal_mm * 0.001, width, height),
            pupils: Vec::new(),
        };
        lens.focus(focus_distance)?;
        let half_diagonal = lens.film_half.length();
        lens.pupils = (0..PUPIL_INTERVALS)
            .map(|i| {
                let r0 = half_diagonal * i as f32 / PUPIL_INTERVALS as f32;
                let r1 = half_diagonal * (i + 1) as f32 / PUPIL_INTERVALS as f32;
                lens.bound_exit_pupil(r0, r1)
            })
            .collect();
        Ok(lens)
    }

    /// The system with its film (of the same diagonal) cut to the aspect of an image of
    /// `width` × `height` pixels (a render at another size than the scene's).
    pub fn for_image(&self, width: u32, height: u32) -> LensSystem {
        LensSystem {
            film_half: film_half(2.0 * self.film_half.length(), width, height),
            ..self.clone()
        }
    }

    /// The film's distance from the rear element.
    pub fn rear_z(&self) -> f32 {
        self.elements.last().map_or(0.0, |e| e.thickness)
    }

    /// The front element's distance from the film.
    pub fn front_z(&self) -> f32 {
        self.elements.iter().map(|e| e.thickness).sum()
    }

    /// The rear element's aperture radius.
    pub fn rear_radius(&self) -> f32 {
        self.elements.last().map_or(0.0, |e| e.aperture)
    }

    /// The index of refraction behind interface i (toward the film); air behind the stop
    /// (its 0) and in front of the front element (None).
    fn eta_behind(&self, i: Option<usize>) -> f32 {
        match i.map(|j| self.elements[j].eta) {
            Some(x) if x != 0.0 => x,
            _ => 1.0,
        }
    }

    /// The lens-space ray (o, d) across interface i, whose vertex is at z, going toward
    /// the film or toward the scene: where it meets the interface and its direction
    /// after it; None where the aperture or a total internal reflection stops it.
    fn cross(&self, i: usize, z: f32, o: Vec3, d: Vec3, toward_film: bool) -> Option<(Vec3, Vec3)> {
        let e = self.elements[i];
        let (t, n) = if e.radius == 0.0 {
            let away = if toward_film { d.z >= 0.0 } else { d.z <= 0.0 };
            if away {
                return None;
            }
            ((z - o.z) / d.z, None)
        } else {
            let (t, n) = intersect_interface(o, d, e.radius, z + e.radius)?;
            (t, Some(n))
        };
        let p = o + t * d;
        if p.x * p.x + p.y * p.y > e.aperture * e.aperture {
            return None;
        }
        let Some(n) = n else {
            return Some((p, d));
        };
        let (before, behind) = (self.eta_behind(i.checked_sub(1)), self.eta_behind(Some(i)));
        let (eta_i, eta_t) = if toward_film {
            (behind, before)
        } else {
            (before, behind)
        };
        Some((p, refract(-d.normalize(), n, eta_t / eta_i)?))
    }

    /// The ray (camera space) from the film side through every interface, rear to front:
    /// the ray leaving the front element, or None where an aperture or a total internal
    /// reflection stops it.
    pub fn trace_from_film(&self, o: Vec3, d: Vec3) -> Option<(Vec3, Vec3)> {
        // (Lens space: z negated, the film at 0 and the lens toward -z.)
        let flip = Vec3::new(1.0, 1.0, -1.0);
        let (mut o, mut d) = (o * flip, d * flip);
        let mut z = 0.0;
        for i in (0..self.elements.len()).rev() {
            z -= self.elements[i].thickness;
            (o, d) = self.cross(i, z, o, d, true)?;
        }
        Some((o * flip, d * flip))
    }

    /// The ray (camera space) from the scene side through every interface, front to rear.
    pub fn trace_from_scene(&self, o: Vec3, d: Vec3) -> Option<(Vec3, Vec3)> {
        let flip = Vec3::new(1.0, 1.0, -1.0);
        let (mut o, mut d) = (o * flip, d * flip);
        let mut z = -self.front_z();
        for (i, e) in self.elements.iter().enumerate() {
            (o, d) = self.cross(i, z, o, d, false)?;
            z += e.thickness;
        }
        Some((o * flip, d * flip))
    }

    /// The principal plane and the focal point (lens-space z) of the ray r_in that
    /// left the system as r_out, parallel to the axis at height h.
    fn cardinal_points(r_in: (Vec3, Vec3), r_out: (Vec3, Vec3)) -> (f32, f32) {
        let (o_in, _) = r_in;
        let (o, d) = r_out;
        let tf = -o.x / d.x;
        let tp = (o_in.x - o.x) / d.x;
        (-(o.z + tp * d.z), -(o.z + tf * d.z))
    }

    /// The thick lens's principal planes and focal points, on the film's side then on
    /// the scene's (lens-space z), from two rays parallel to the axis, near it.
    pub fn thick_lens(&self) -> Result<([f32; 2], [f32; 2]), String> {
        let h = 0.001 * 2.0 * self.film_half.length();
        let blocked = || {
            "the lens system lets no ray near its axis through (is the aperture stop very small?)"
                .to_string()
        };
        let a = (Vec3::new(h, 0.0, self.front_z() + 1.0), Vec3::NEG_Z);
        let a_out = self.trace_from_scene(a.0, a.1).ok_or_else(blocked)?;
        let (pz0, fz0) = Self::cardinal_points(a, a_out);
        let b = (Vec3::new(h, 0.0, self.rear_z() - 1.0), Vec3::Z);
        let b_out = self.trace_from_film(b.0, b.1).ok_or_else(blocked)?;
        let (pz1, fz1) = Self::cardinal_points(b, b_out);
        Ok(([pz0, pz1], [fz0, fz1]))
    }

    /// The effective focal length of the thick-lens approximation.
    pub fn focal_length(&self) -> Result<f32, String> {
        let (pz, fz) = self.thick_lens()?;
        Ok(fz[0] - pz[0])
    }

    /// Moves the film so that the plane at `distance` from it is in focus (the rear
    /// element's thickness changes).
    fn focus(&mut self, distance: f32) -> Result<(), String> {
        let (pz, fz) = self.thick_lens()?;
        let f = (fz[0] - pz[0]) as f64;
        let z = -distance as f64;
        let (p0, p1) = (pz[0] as f64, pz[1] as f64);
        let c = (p1 - z - p0) * (p1 - z - 4.0 * f - p0);
        if c <= 0.0 {
            return Err(format!(
                "focusdistance {distance} is too short for this lens (its focal length is {:.4} m)",
                f
            ));
        }
        let delta = 0.5 * (p1 - z + p0 - c.sqrt());
        let last = self.elements.last_mut().expect("a lens has interfaces");
        last.thickness += delta as f32;
        if !(last.thickness > 0.0) {
            return Err(format!(
                "focusdistance {distance} puts the film inside the lens"
            ));
        }
        Ok(())
    }

    /// The bounds, on the plane tangent to the rear element, of the points through which
    /// rays from film points (x, 0, 0), x in [r0, r1], pass the system: a grid over a
    /// square of 1.5 times the rear element's radius, from film points across the
    /// interval, grown by two grid cells (the pupil's edge moves smoothly with the film
    /// point, by less than a cell between the film points taken).
    fn bound_exit_pupil(&self, r0: f32, r1: f32) -> [f32; 4] {
        const GRID: usize = 96;
        const FILM_POINTS: usize = 9;
        let s = 1.5 * self.rear_radius();
        let cell = 2.0 * s / GRID as f32;
        let rear = self.rear_z();
        let (mut lo, mut hi) = (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY));
        for k in 0..FILM_POINTS {
            let x = r0 + (r1 - r0) * k as f32 / (FILM_POINTS - 1) as f32;
            let film = Vec3::new(x, 0.0, 0.0);
            for j in 0..GRID {
                for i in 0..GRID {
                    let p = Vec2::new(-s + (i as f32 + 0.5) * cell, -s + (j as f32 + 0.5) * cell);
                    if p.cmpge(lo).all() && p.cmple(hi).all() {
                        continue;
                    }
                    if self.trace_from_film(film, p.extend(rear) - film).is_some() {
                        lo = lo.min(p);
                        hi = hi.max(p);
                    }
                }
            }
        }
        if lo.x > hi.x {
            return [1.0, 1.0, 0.0, 0.0];
        }
        let m = 2.0 * cell;
        [lo.x - m, lo.y - m, hi.x + m, hi.y + m]
    }

    /// The camera ray (camera space: origin, unit direction) and its weight through the
    /// film position `film` in [0,1)² ((0,0) the top-left corner) for the numbers u
    /// (the exit pupil's point); None where the lens stops it. Mirrors camera.glsl's
    /// `realistic_camera_ray`.
    pub fn camera_ray(&self, film: Vec2, u: Vec2) -> Option<(Vec3, Vec3, f32)> {
        let f = Vec2::new(
            -self.film_half.x + 2.0 * self.film_half.x * film.x,
            -self.film_half.y + 2.0 * self.film_half.y * film.y,
        );
        // (The lens turns the image over: the film point of the image's top left lies
        // right of and below the axis.)
        let p_film = Vec3::new(-f.x, f.y, 0.0);
        let r = p_film.truncate().length();
        let interval = ((r / self.film_half.length() * PUPIL_INTERVALS as f32) as usize)
            .min(PUPIL_INTERVALS - 1);
        let b = self.pupils[interval];
        if !(b[0] < b[2] && b[1] < b[3]) {
            return None;
        }
        let q = Vec2::new(b[0] + (b[2] - b[0]) * u.x, b[1] + (b[3] - b[1]) * u.y);
        let pdf = 1.0 / ((b[2] - b[0]) * (b[3] - b[1]));
        let (sin, cos) = if r > 0.0 {
            (p_film.y / r, p_film.x / r)
        } else {
            (0.0, 1.0)
        };
        let pupil = Vec3::new(cos * q.x - sin * q.y, sin * q.x + cos * q.y, self.rear_z());
        let dir = pupil - p_film;
        let (o, d) = self.trace_from_film(p_film, dir)?;
        let cos_theta = dir.normalize().z;
        let rear = self.rear_z();
        let weight = cos_theta.powi(4) / (pdf * rear * rear);
        Some((o, d.normalize(), weight))
    }

    /// The floats camera.glsl reads (abi.h `SceneParams.lens`): half the film's width and
    /// height, the film's distance from the rear element, the interface count; per
    /// interface its radius, thickness, index and aperture radius (front to rear); per
    /// pupil interval its bounds.
    pub fn pack(&self) -> Vec<f32> {
        let mut v = vec![
            self.film_half.x,
            self.film_half.y,
            self.rear_z(),
            self.elements.len() as f32,
        ];
        for e in &self.elements {
            v.extend([e.radius, e.thickness, e.eta, e.aperture]);
        }
        for b in &self.pupils {
            v.extend(b);
        }
        v
    }

    /// The vertical field of view (degrees) of a pinhole at the film's distance from the
    /// rear element seeing the same film: for texture filtering's footprints.
    pub fn equivalent_fovy_degrees(&self) -> f32 {
        2.0 * (self.film_half.y / self.rear_z().max(1e-6))
            .atan()
            .to_degrees()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A biconvex singlet (n 1.5, radii ±50 mm, 6 mm thick) with a stop 4 mm in front,
    /// as a lens file.
    const SINGLET: &str = "# radius thickness eta diameter\n\
                           0 4 0 10\n\
                           50 6 1.5 20\n\
                           -50 0 1 20\n";

    #[test]
    fn a_lens_file_is_read_with_its_errors() {
        let rows = parse_lens_file(SINGLET).unwrap();
        assert_eq!(rows.len(), 3);
        assert_eq!(rows[1], [50.0, 6.0, 1.5, 20.0]);
        let e = parse_lens_file("1 2 3\n").unwrap_err();
        assert!(e.contains("3 numbers"), "{e}");
        let e = parse_lens_file("1 2 3 x\n").unwrap_err();
        assert!(e.contains("line 1") && e.contains("\"x\""), "{e}");
    }

    /// The thick-lens approximation of the singlet has the lensmaker's focal length:
    /// 1/f = (n − 1) (1/R1 − 1/R2 + (n − 1) d / (n R1 R2)).
    #[test]
    fn the_focal_length_is_the_lensmakers() {
        let rows = parse_lens_file(SINGLET).unwrap();
        let lens = LensSystem::new(&rows, 10.0, 5.0, 35.0, 30, 20).unwrap();
        let (n, r1, r2, d) = (1.5f64, 0.05, -0.05, 0.006);
        let f = 1.0 / ((n - 1.0) * (1.0 / r1 - 1.0 / r2 + (n - 1.0) * d / (n * r1 * r2)));
        let got = lens.focal_length().unwrap() as f64;
        assert!((got - f).abs() < 2e-4 * f, "{got} vs {f}");
    }

    /// Focused at 2 m, the rays from one film point through the whole exit pupil meet
    /// near one point of the plane 2 m from the film (to within the singlet's spherical
    /// aberration: 0.6 mm); focused at 0.6 m they spread there over its circle of
    /// confusion (some 4 mm × (2 / 0.6 − 1) across).
    #[test]
    fn rays_from_a_film_point_meet_on_the_plane_in_focus() {
        let rows = parse_lens_file(SINGLET).unwrap();
        let spread = |focus: f32| {
            let lens = LensSystem::new(&rows, 4.0, focus, 35.0, 30, 20).unwrap();
            let mut hits = Vec::new();
            for j in 0..16 {
                for i in 0..16 {
                    let u = Vec2::new((i as f32 + 0.5) / 16.0, (j as f32 + 0.5) / 16.0);
                    if let Some((o, d, w)) = lens.camera_ray(Vec2::new(0.6, 0.45), u) {
                        assert!(w > 0.0 && d.z > 0.0);
                        let t = (2.0 - o.z) / d.z;
                        hits.push((o + t * d).truncate());
                    }
                }
            }
            assert!(hits.len() > 20, "{} rays pass", hits.len());
            let mean = hits.iter().copied().sum::<Vec2>() / hits.len() as f32;
            hits.iter()
                .map(|h| (*h - mean).length())
                .fold(0.0f32, f32::max)
        };
        let (sharp, blurred) = (spread(2.0), spread(0.6));
        assert!(sharp < 1e-3, "spread on the plane in focus {sharp}");
        assert!(
            blurred > 3e-3 && blurred > 4.0 * sharp,
            "{blurred} vs {sharp}"
        );
    }

    /// The exit pupil's bounds hold every pupil point a ray passes through: a finer grid
    /// than theirs finds none outside.
    #[test]
    fn the_exit_pupil_bounds_hold_every_passing_ray() {
        let rows = parse_lens_file(SINGLET).unwrap();
        let lens = LensSystem::new(&rows, 6.0, 3.0, 35.0, 30, 20).unwrap();
        let half = lens.film_half.length();
        let s = 1.5 * lens.rear_radius();
        for interval in [0usize, 20, 45, 63] {
            let b = lens.pupils[interval];
            for k in 0..5 {
                let x = half * (interval as f32 + k as f32 / 4.0) / PUPIL_INTERVALS as f32;
                for j in 0..200 {
                    for i in 0..200 {
                        let p = Vec2::new(
                            -s + 2.0 * s * (i as f32 + 0.3) / 200.0,
                            -s + 2.0 * s * (j as f32 + 0.7) / 200.0,
                        );
                        let film = Vec3::new(x, 0.0, 0.0);
                        if lens
                            .trace_from_film(film, p.extend(lens.rear_z()) - film)
                            .is_some()
                        {
                            assert!(
                                p.x >= b[0] && p.x <= b[2] && p.y >= b[1] && p.y <= b[3],
                                "interval {interval}: {p} outside {b:?}"
                            );
                        }
                    }
                }
            }
        }
    }
}

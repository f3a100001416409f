//! pbrt-v4's media: `MakeNamedMedium` (the `homogeneous`, `uniformgrid`, `rgbgrid` and
//! `cloud` kinds; NanoVDB is refused for now) and the names
//! `MediumInterface` and the camera refer to.

use super::{Params, ParseError, Parser};
use crate::scene::{
    GridValues, Medium, MediumGrid, MediumInterface, SampledGrid, Temperature, MAX_MEDIA,
};
use glam::{Mat4, Vec3};
use std::sync::Arc;

impl Parser {
    /// `MakeNamedMedium name "string type" ...`.
    pub(super) fn named_medium(
        &mut self,
        name: String,
        params: &Params,
        file: u32,
        line: u32,
    ) -> Result<(), ParseError> {
        let d = "MakeNamedMedium";
        let ty = match params.find("type") {
            Some(p) if p.ty == "string" && !p.strs.is_empty() => p.strs[0].clone(),
            _ => {
                return Err(self.err_at(
                    file,
                    line,
                    d,
                    format!("medium \"{name}\" has no \"string type\""),
                ))
            }
        };
        if !["homogeneous", "uniformgrid", "rgbgrid", "cloud", "nanovdb"].contains(&ty.as_str()) {
            // (Its parameters are not checked: the whole medium is unsupported.)
            for p in &params.0 {
                p.used.set(true);
            }
            self.unsupported(
                file,
                line,
                format!(
                    "MakeNamedMedium \"{ty}\" (participating media: homogeneous, uniformgrid, rgbgrid, cloud and nanovdb only)"
                ),
            );
            self.named_media.insert(name, 0);
            return Ok(());
        }
        // A homogeneous medium's named preset: its measured σa and σs, in place of the
        // parameters (pbrt-v4 reads them only without a preset).
        let preset = match params.find("preset") {
            Some(p) if ty == "homogeneous" => {
                let want = p.strs.first().cloned().unwrap_or_default();
                match PRESETS.iter().find(|(n, _, _)| *n == want) {
                    Some(&(_, s, a)) => Some((Vec3::from(a), Vec3::from(s))),
                    None => {
                        let names: Vec<&str> = PRESETS.iter().map(|p| p.0).collect();
                        return Err(self.err_at(
                            p.file,
                            p.line,
                            d,
                            format!(
                                "medium \"{name}\": no preset named \"{want}\" (known: {})",
                                names.join(", ")
                            ),
                        ));
                    }
                }
            }
            Some(p) => {
                let (f, l) = (p.file, p.line);
                self.unsupported(
                    f,
                    l,
                    format!(
                        "MakeNamedMedium \"{ty}\": \"preset\" (homogeneous media only, as pbrt-v4)"
                    ),
                );
                None
            }
            None => None,
        };
        let spectrum =
            |this: &mut Self, what: &str, emitted: bool| -> Result<Option<Vec3>, ParseError> {
                match params.find(what).cloned() {
                    Some(p) => this.rgb(&p, d, emitted),
                    None => Ok(None),
                }
            };
        // (An rgbgrid's sigma_a, sigma_s and Le are its grids: 1 here, times scale and
        // Lescale below.)
        let rgb_grid = if ty == "rgbgrid" {
            Some(self.rgb_grid(&name, params, file, line)?)
        } else {
            None
        };
        let (sigma_a, sigma_s) = match preset {
            _ if rgb_grid.is_some() => (Vec3::ONE, Vec3::ONE),
            Some(preset) => {
                params.find("sigma_a");
                params.find("sigma_s");
                preset
            }
            None => (
                spectrum(self, "sigma_a", false)?.unwrap_or(Vec3::ONE),
                spectrum(self, "sigma_s", false)?.unwrap_or(Vec3::ONE),
            ),
        };
        // (pbrt-v4's cloud reads neither Le nor scale; its nanovdb no Le.)
        let cloud = ty == "cloud";
        let nano_vdb = ty == "nanovdb";
        let le = match &rgb_grid {
            Some((_, emits)) => Vec3::splat(if *emits { 1.0 } else { 0.0 }),
            None if cloud || nano_vdb => Vec3::ZERO,
            None => spectrum(self, "Le", true)?.unwrap_or(Vec3::ZERO),
        };
        let num = |what: &str, default: f64| {
            params
                .find(what)
                .and_then(|p| p.nums.first().copied())
                .unwrap_or(default) as f32
        };
        let scale = if cloud { 1.0 } else { num("scale", 1.0) };
        let grid = if ty == "uniformgrid" {
            Some(self.uniform_grid(&name, params, file, line)?)
        } else if cloud {
            Some(self.cloud(&name, params, file, line)?)
        } else if nano_vdb {
            Some(self.nano_vdb(&name, params, file, line)?)
        } else {
            rgb_grid.map(|(g, _)| g)
        };
        // (A temperature grid emits its blackbody: Le 1 times it, as pbrt-v4's.)
        let le = match grid.as_deref().map(|g| &g.values) {
            Some(
                GridValues::Density {
                    temperature: Some(_),
                    ..
                }
                | GridValues::NanoVdb {
                    temperature: Some(_),
                    ..
                },
            ) => Vec3::ONE,
            _ => le,
        };
        // (A uniformgrid's Lescale is its grid of scales.)
        let le_scale = if ty == "uniformgrid" || cloud {
            1.0
        } else if nano_vdb && params.find("Lescale").is_none() && params.find("LeScale").is_some() {
            // (pbrt-v4 read "LeScale" before it was renamed; the collection's explosion
            // still says so.)
            num("LeScale", 1.0)
        } else {
            num("Lescale", 1.0)
        };
        let g = num("g", 0.0);
        self.check_used(d, &format!("\"{ty}\""), params);
        let bad = |this: &Self, what: String| {
            this.err_at(file, line, d, format!("medium \"{name}\": {what}"))
        };
        for (what, v) in [("sigma_a", sigma_a), ("sigma_s", sigma_s)] {
            if !v.is_finite() || v.min_element() < 0.0 {
                return Err(bad(
                    self,
                    format!("{what} must be finite and not negative, got {v}"),
                ));
            }
        }
        if !scale.is_finite() || scale < 0.0 {
            return Err(bad(
                self,
                format!("scale must be finite and not negative, got {scale}"),
            ));
        }
        if !(g > -1.0 && g < 1.0) {
            return Err(bad(self, format!("g must lie in (-1, 1), got {g}")));
        }
        let emission = le * le_scale;
        if !emission.is_finite() || emission.min_element() < 0.0 {
            return Err(bad(
                self,
                format!("Le × Lescale must be finite and not negative, got {emission}"),
            ));
        }
        if self.scene.media.len() >= MAX_MEDIA {
            return Err(bad(self, format!("more than {MAX_MEDIA} media")));
        }
        self.scene.media.push(Medium {
            sigma_a: sigma_a * scale,
            sigma_s: sigma_s * scale,
            g,
            emission,
            grid,
        });
        self.named_media.insert(name, self.scene.media.len() as u32);
        Ok(())
    }

    /// A `uniformgrid` medium's grids: "density" (nx × ny × nz values, x fastest, none
    /// negative), "Lescale" (as many, or none: a single sample of 1, as pbrt-v4 makes it),
    /// over the box "p0" to "p1" of the medium's space (the CTM here).
    fn uniform_grid(
        &mut self,
        name: &str,
        params: &Params,
        file: u32,
        line: u32,
    ) -> Result<Arc<MediumGrid>, ParseError> {
        let (res, unit_from_world) = self.grid_frame(name, params, file, line)?;
        let Some(density) = self.grid_values(name, params, "density", res, 1)? else {
            return Err(self.err_at(
                file,
                line,
                "MakeNamedMedium",
                format!("medium \"{name}\": no \"density\" values (a uniformgrid needs them)"),
            ));
        };
        let le_scale = match self.grid_values(name, params, "Lescale", res, 1)? {
            Some(values) => SampledGrid { res, values },
            None => SampledGrid {
                res: [1, 1, 1],
                values: vec![1.0],
            },
        };
        let temperature = match self.grid_values(name, params, "temperature", res, 1)? {
            None => {
                self.temperature_map(name, params, file, line)?;
                None
            }
            Some(values) => {
                if params.find("Le").is_some() {
                    return Err(self.err_at(
                        file,
                        line,
                        "MakeNamedMedium",
                        format!(
                            "medium \"{name}\": both \"Le\" and \"temperature\" given (pbrt-v4 takes one)"
                        ),
                    ));
                }
                let (offset, scale) = self.temperature_map(name, params, file, line)?;
                Some(Temperature {
                    grid: SampledGrid { res, values },
                    offset,
                    scale,
                })
            }
        };
        Ok(Arc::new(MediumGrid::density(
            unit_from_world,
            SampledGrid {
                res,
                values: density,
            },
            le_scale,
            temperature,
        )))
    }

    /// An `rgbgrid` medium's grids, and whether it emits: "rgb sigma_a", "rgb sigma_s"
    /// (nx × ny × nz RGB values each, x fastest, none negative; at least one of the two;
    /// one not given is 1, as pbrt-v4's), "rgb Le" (as many; it needs sigma_a, as
    /// pbrt-v4), over the box "p0" to "p1" of the medium's space (the CTM here).
    fn rgb_grid(
        &mut self,
        name: &str,
        params: &Params,
        file: u32,
        line: u32,
    ) -> Result<(Arc<MediumGrid>, bool), ParseError> {
        let (res, unit_from_world) = self.grid_frame(name, params, file, line)?;
        let grid = |this: &Self, what: &str| -> Result<Option<SampledGrid<Vec3>>, ParseError> {
            Ok(this
                .grid_values(name, params, what, res, 3)?
                .map(|v| SampledGrid {
                    res,
                    values: v.chunks(3).map(Vec3::from_slice).collect(),
                }))
        };
        let sigma_a = grid(self, "sigma_a")?;
        let sigma_s = grid(self, "sigma_s")?;
        let le = grid(self, "Le")?;
        let bad = |this: &Self, what: &str| {
            this.err_at(
                file,
                line,
                "MakeNamedMedium",
                format!("medium \"{name}\": {what}"),
            )
        };
        if sigma_a.is_none() && sigma_s.is_none() {
            return Err(bad(
                self,
                "an rgbgrid needs \"rgb sigma_a\" or \"rgb sigma_s\" values (or both)",
            ));
        }
        if le.is_some() && sigma_a.is_none() {
            return Err(bad(
                self,
                "an rgbgrid with \"Le\" needs \"rgb sigma_a\" values (its emission is sigma_a Le)",
            ));
        }
        let emits = le.is_some();
        Ok((
            Arc::new(MediumGrid::rgb(unit_from_world, sigma_a, sigma_s, le)),
            emits,
        ))
    }

    /// A grid medium's sample counts "nx", "ny", "nz" (1 each by default) and the map from
    /// world space to the unit cube of its box "p0" to "p1" in the medium's space (the CTM).
    fn grid_frame(
        &self,
        name: &str,
        params: &Params,
        file: u32,
        line: u32,
    ) -> Result<([u32; 3], Mat4), ParseError> {
        let d = "MakeNamedMedium";
        let bad = |this: &Self, (f, l): (u32, u32), what: String| {
            this.err_at(f, l, d, format!("medium \"{name}\": {what}"))
        };
        let int = |this: &Self, what: &str| -> Result<u32, ParseError> {
            match params.find(what) {
                None => Ok(1),
                Some(p) => match p.nums.first() {
                    Some(&v) if v >= 1.0 && v.fract() == 0.0 && v <= 65536.0 => Ok(v as u32),
                    _ => Err(bad(
                        this,
                        (p.file, p.line),
                        format!(
                            "\"{what}\" must be a whole number from 1 to 65536, got {:?}",
                            p.nums
                        ),
                    )),
                },
            }
        };
        let res = [int(self, "nx")?, int(self, "ny")?, int(self, "nz")?];
        let (_, _, unit_from_world) = self.grid_box(name, params, file, line)?;
        Ok((res, unit_from_world))
    }

    /// A medium's box "p0" to "p1" (defaults: the unit cube) in the medium's space and the
    /// map from world space to the unit cube it is mapped to (through the CTM).
    fn grid_box(
        &self,
        name: &str,
        params: &Params,
        file: u32,
        line: u32,
    ) -> Result<(Vec3, Vec3, Mat4), ParseError> {
        let d = "MakeNamedMedium";
        let bad = |this: &Self, (f, l): (u32, u32), what: String| {
            this.err_at(f, l, d, format!("medium \"{name}\": {what}"))
        };
        let point = |this: &Self, what: &str, default: Vec3| -> Result<Vec3, ParseError> {
            match params.find(what) {
                None => Ok(default),
                Some(p) if p.nums.len() == 3 && p.nums.iter().all(|v| v.is_finite()) => Ok(
                    Vec3::new(p.nums[0] as f32, p.nums[1] as f32, p.nums[2] as f32),
                ),
                Some(p) => Err(bad(
                    this,
                    (p.file, p.line),
                    format!(
                        "\"{what}\" must be one point (3 finite numbers), got {:?}",
                        p.nums
                    ),
                )),
            }
        };
        let p0 = point(self, "p0", Vec3::ZERO)?;
        let p1 = point(self, "p1", Vec3::ONE)?;
        if !(p1 - p0).cmpgt(Vec3::ZERO).all() {
            return Err(bad(
                self,
                (file, line),
                format!(
                    "the bounds p0 {p0} to p1 {p1} are empty (p1 must exceed p0 on every axis)"
                ),
            ));
        }
        let world_from_unit = self.gs.ctm * Mat4::from_translation(p0) * Mat4::from_scale(p1 - p0);
        if world_from_unit.determinant().abs() < 1e-30 || !world_from_unit.is_finite() {
            return Err(bad(
                self,
                (file, line),
                "its transformation is singular".into(),
            ));
        }
        Ok((p0, p1, world_from_unit.inverse()))
    }

    /// pbrt-v4's temperature map, T = (grid − offset) × scale: "temperatureoffset" (where
    /// it is not given, the older "temperaturecutoff"; else 0) and "temperaturescale" (1),
    /// each finite. Reading them marks all three used.
    fn temperature_map(
        &self,
        name: &str,
        params: &Params,
        file: u32,
        line: u32,
    ) -> Result<(f32, f32), ParseError> {
        let num = |what: &str| params.find(what).and_then(|p| p.nums.first().copied());
        let (offset, cutoff, scale) = (
            num("temperatureoffset"),
            num("temperaturecutoff"),
            num("temperaturescale"),
        );
        let offset = offset.or(cutoff).unwrap_or(0.0) as f32;
        let scale = scale.unwrap_or(1.0) as f32;
        if !offset.is_finite() || !scale.is_finite() {
            return Err(self.err_at(
                file,
                line,
                "MakeNamedMedium",
                format!("medium \"{name}\": the temperature's offset and scale must be finite, got {offset} and {scale}"),
            ));
        }
        Ok((offset, scale))
    }

    /// A `nanovdb` medium's grids (pbrt-v4's): "filename" (a NanoVDB file, relative to
    /// the scene file), its Float grid "gridname" ("density") and, where the file has it,
    /// "temperaturename" ("temperature") with "temperatureoffset" (else "temperaturecutoff",
    /// else 0) and "temperaturescale" (1); the medium's bounds are the grids' world boxes
    /// in the medium's space (the CTM here), as pbrt-v4's.
    fn nano_vdb(
        &mut self,
        name: &str,
        params: &Params,
        file: u32,
        line: u32,
    ) -> Result<Arc<MediumGrid>, ParseError> {
        let d = "MakeNamedMedium";
        let Some(p) = params.find("filename").cloned() else {
            return Err(self.err_at(
                file,
                line,
                d,
                format!("medium \"{name}\": a nanovdb medium needs a \"string filename\""),
            ));
        };
        let path = self.resolve(p.file, p.strs.first().map_or("", |s| s.as_str()));
        let string = |what: &str, default: &str| {
            params
                .find(what)
                .and_then(|p| p.strs.first().cloned())
                .unwrap_or_else(|| default.to_string())
        };
        let (density_name, temperature_name) = (
            string("gridname", "density"),
            string("temperaturename", "temperature"),
        );
        let bad = |this: &Self, what: String| {
            this.err_at(
                p.file,
                p.line,
                d,
                format!("medium \"{name}\" (nanovdb): {what}"),
            )
        };
        let read = |this: &Self, grid: &str| {
            crate::nanovdb::read_float_grid(&path, grid).map_err(|e| bad(this, format!("{e:#}")))
        };
        let Some(density) = read(self, &density_name)? else {
            let names = crate::nanovdb::grid_names(&path).unwrap_or_default();
            return Err(bad(
                self,
                format!(
                    "{}: no grid named \"{density_name}\" (the file has: {})",
                    path.display(),
                    names.join(", ")
                ),
            ));
        };
        let temperature = read(self, &temperature_name)?;
        let (offset, scale) = self.temperature_map(name, params, file, line)?;
        // The bounds: the grids' world boxes (index min to max + 1 through their maps).
        let (mut lo, mut hi) = density.world_bbox();
        if let Some(t) = &temperature {
            let (a, b) = t.world_bbox();
            (lo, hi) = (lo.min(a), hi.max(b));
        }
        if !(hi - lo).cmpgt(glam::DVec3::ZERO).all() || !(lo.is_finite() && hi.is_finite()) {
            return Err(bad(
                self,
                format!(
                    "{}: grid \"{density_name}\" has an empty world box ({lo} to {hi}): no active voxels?",
                    path.display()
                ),
            ));
        }
        let sparse = |this: &Self, g: &crate::nanovdb::FloatGrid| {
            // index = M⁻¹ (medium point − v), the medium point lo + u (hi − lo).
            let m = g.map();
            let inv = glam::DMat3::from_cols_array(&m.inv_mat_d).transpose();
            let v = glam::DVec3::from_array(m.vec_d);
            let index_from_unit = glam::DMat4::from_mat3_translation(
                inv * glam::DMat3::from_diagonal(hi - lo),
                inv * (lo - v),
            );
            let bricks = g.bricks().map_err(|e| bad(this, format!("{e:#}")))?;
            Ok::<_, ParseError>(crate::scene::SparseGrid {
                index_from_unit: index_from_unit.as_mat4(),
                bricks,
            })
        };
        let density = sparse(self, &density)?;
        let temperature = match &temperature {
            Some(t) => Some((sparse(self, t)?, offset, scale)),
            None => None,
        };
        let world_from_unit = self.gs.ctm
            * Mat4::from_translation(lo.as_vec3())
            * Mat4::from_scale((hi - lo).as_vec3());
        if world_from_unit.determinant().abs() < 1e-30 || !world_from_unit.is_finite() {
            return Err(self.err_at(
                file,
                line,
                d,
                format!("medium \"{name}\": its transformation is singular"),
            ));
        }
        params.find("LeScale");
        Ok(Arc::new(MediumGrid::nano_vdb(
            world_from_unit.inverse(),
            density,
            temperature,
        )))
    }

    /// A `cloud` medium (pbrt-v4's procedural one): "density" (1), "wispiness" (1),
    /// "frequency" (5), each finite and not negative, over the box "p0" to "p1".
    fn cloud(
        &mut self,
        name: &str,
        params: &Params,
        file: u32,
        line: u32,
    ) -> Result<Arc<MediumGrid>, ParseError> {
        let (p0, p1, unit_from_world) = self.grid_box(name, params, file, line)?;
        let num = |what: &str, default: f64| -> Result<f32, ParseError> {
            let Some(p) = params.find(what) else {
                return Ok(default as f32);
            };
            match p.nums.first() {
                Some(&v) if p.nums.len() == 1 && (v as f32).is_finite() && v >= 0.0 => Ok(v as f32),
                _ => Err(self.err_at(
                    p.file,
                    p.line,
                    "MakeNamedMedium",
                    format!(
                        "medium \"{name}\": \"{what}\" must be one finite number, not negative; got {:?}",
                        p.nums
                    ),
                )),
            }
        };
        let values = crate::scene::GridValues::Cloud {
            density: num("density", 1.0)?,
            wispiness: num("wispiness", 1.0)?,
            frequency: num("frequency", 5.0)?,
            p0,
            extent: p1 - p0,
        };
        Ok(Arc::new(MediumGrid::new(unit_from_world, values)))
    }

    /// A grid's values `what`: nx × ny × nz samples of `channels` numbers each (an RGB
    /// grid's: "rgb" values), finite and not negative; `None` where not given.
    fn grid_values(
        &self,
        name: &str,
        params: &Params,
        what: &str,
        res: [u32; 3],
        channels: u64,
    ) -> Result<Option<Vec<f32>>, ParseError> {
        let Some(p) = params.find(what) else {
            return Ok(None);
        };
        let bad = |what: String| {
            self.err_at(
                p.file,
                p.line,
                "MakeNamedMedium",
                format!("medium \"{name}\": {what}"),
            )
        };
        if channels == 3 && p.ty != "rgb" {
            return Err(bad(format!(
                "\"{} {what}\": an rgbgrid's values are \"rgb\" (nx × ny × nz triples)",
                p.ty
            )));
        }
        let count = res.iter().map(|&r| r as u64).product::<u64>();
        if p.nums.len() as u64 != count * channels {
            let unit = if channels == 3 { " RGB triples" } else { "" };
            return Err(bad(format!(
                "\"{what}\" has {} values; nx × ny × nz = {} × {} × {} = {count}{unit} expected",
                p.nums.len(),
                res[0],
                res[1],
                res[2]
            )));
        }
        if let Some(v) = p.nums.iter().find(|v| !v.is_finite() || **v < 0.0) {
            return Err(bad(format!(
                "\"{what}\" must be finite and not negative, got {v}"
            )));
        }
        Ok(Some(p.nums.iter().map(|&v| v as f32).collect()))
    }

    /// The medium a name stands for: "" is vacuum; an unknown name is an error.
    /// (`named_media` holds index + 1, 0 for a refused medium, read as vacuum: the
    /// scene is refused anyway.)
    pub(super) fn medium_named(
        &self,
        name: &str,
        file: u32,
        line: u32,
        d: &str,
    ) -> Result<Option<u32>, ParseError> {
        if name.is_empty() {
            return Ok(None);
        }
        match self.named_media.get(name) {
            Some(&0) => Ok(None),
            Some(&i) => Ok(Some(i - 1)),
            None => Err(self.err_at(
                file,
                line,
                d,
                format!(
                    "no medium named \"{name}\" (MakeNamedMedium defines one before it is used)"
                ),
            )),
        }
    }

    /// The graphics state's medium interface where it is a transition (inside and outside
    /// differ): what a shape declared now bounds.
    pub(super) fn medium_transition(&self) -> Option<MediumInterface> {
        let (inside, outside) = self.gs.media;
        (inside != outside).then_some(MediumInterface { inside, outside })
    }
}

/// pbrt-v4's named scattering presets (`"string preset"` of a homogeneous medium): name,
/// σs (the reduced scattering coefficient σ′s the papers measured, used as σs) and σa, per
/// mm, as RGB. Published measurements: Jensen, Marschner, Levoy and Hanrahan, "A Practical
/// Model for Subsurface Light Transport" (SIGGRAPH 2001), the first twelve; Narasimhan,
/// Gupta, Donner, Ramamoorthi, Nayar and Jensen, "Acquiring Scattering Properties of
/// Participating Media by Dilution" (SIGGRAPH 2006), the rest.
#[rustfmt::skip]
pub(super) const PRESETS: [(&str, [f32; 3], [f32; 3]); 47] = [
    ("Apple", [2.29, 2.39, 1.97], [0.0030, 0.0034, 0.046]),
    ("Chicken1", [0.15, 0.21, 0.38], [0.015, 0.077, 0.19]),
    ("Chicken2", [0.19, 0.25, 0.32], [0.018, 0.088, 0.20]),
    ("Cream", [7.38, 5.47, 3.15], [0.0002, 0.0028, 0.0163]),
    ("Ketchup", [0.18, 0.07, 0.03], [0.061, 0.97, 1.45]),
    ("Marble", [2.19, 2.62, 3.00], [0.0021, 0.0041, 0.0071]),
    ("Potato", [0.68, 0.70, 0.55], [0.0024, 0.0090, 0.12]),
    ("Skimmilk", [0.70, 1.22, 1.90], [0.0014, 0.0025, 0.0142]),
    ("Skin1", [0.74, 0.88, 1.01], [0.032, 0.17, 0.48]),
    ("Skin2", [1.09, 1.59, 1.79], [0.013, 0.070, 0.145]),
    ("Spectralon", [11.6, 20.4, 14.9], [0.00, 0.00, 0.00]),
    ("Wholemilk", [2.55, 3.21, 3.77], [0.0011, 0.0024, 0.014]),
    ("Lowfat Milk", [0.89187, 1.5136, 2.532], [0.002875, 0.00575, 0.0115]),
    ("Reduced Milk", [2.4858, 3.1669, 4.5214], [0.0025556, 0.0051111, 0.012778]),
    ("Regular Milk", [4.5513, 5.8294, 7.136], [0.0015333, 0.0046, 0.019933]),
    ("Espresso", [0.72378, 0.84557, 1.0247], [4.7984, 6.5751, 8.8493]),
    ("Mint Mocha Coffee", [0.31602, 0.38538, 0.48131], [3.772, 5.8228, 7.82]),
    ("Lowfat Soy Milk", [0.30576, 0.34233, 0.61664], [0.0014375, 0.0071875, 0.035937]),
    ("Regular Soy Milk", [0.59223, 0.73866, 1.4693], [0.0019167, 0.0095833, 0.065167]),
    ("Lowfat Chocolate Milk", [0.64925, 0.83916, 1.1057], [0.0115, 0.0368, 0.1564]),
    ("Regular Chocolate Milk", [1.4585, 2.1289, 2.9527], [0.010063, 0.043125, 0.14375]),
    ("Coke", [8.9053e-05, 8.372e-05, 0.0], [0.10014, 0.16503, 0.2468]),
    ("Pepsi", [6.1697e-05, 4.2564e-05, 0.0], [0.091641, 0.14158, 0.20729]),
    ("Sprite", [6.0306e-06, 6.4139e-06, 6.5504e-06], [0.001886, 0.0018308, 0.0020025]),
    ("Gatorade", [0.0024574, 0.003007, 0.0037325], [0.024794, 0.019289, 0.008878]),
    ("Chardonnay", [1.7982e-05, 1.3758e-05, 1.2023e-05], [0.010782, 0.011855, 0.023997]),
    ("White Zinfandel", [1.7501e-05, 1.9069e-05, 1.288e-05], [0.012072, 0.016184, 0.019843]),
    ("Merlot", [2.1129e-05, 0.0, 0.0], [0.11632, 0.25191, 0.29434]),
    ("Budweiser Beer", [2.4356e-05, 2.4079e-05, 1.0564e-05], [0.011492, 0.024911, 0.057786]),
    ("Coors Light Beer", [5.0922e-05, 4.301e-05, 0.0], [0.006164, 0.013984, 0.034983]),
    ("Clorox", [0.0024035, 0.0031373, 0.003991], [0.0033542, 0.014892, 0.026297]),
    ("Apple Juice", [0.00013612, 0.00015836, 0.000227], [0.012957, 0.023741, 0.052184]),
    ("Cranberry Juice", [0.00010402, 0.00011646, 7.8139e-05], [0.039437, 0.094223, 0.12426]),
    ("Grape Juice", [5.382e-05, 0.0, 0.0], [0.10404, 0.23958, 0.29325]),
    ("Ruby Grapefruit Juice", [0.011002, 0.010927, 0.011036], [0.085867, 0.18314, 0.25262]),
    ("White Grapefruit Juice", [0.22826, 0.23998, 0.32748], [0.0138, 0.018831, 0.056781]),
    ("Shampoo", [0.0007176, 0.0008303, 0.0009016], [0.014107, 0.045693, 0.061717]),
    ("Strawberry Shampoo", [0.00015671, 0.00015947, 1.518e-05], [0.01449, 0.05796, 0.075823]),
    ("Head & Shoulders Shampoo", [0.023805, 0.028804, 0.034306], [0.084621, 0.15688, 0.20365]),
    ("Lemon Tea Powder", [0.040224, 0.045264, 0.051081], [2.4288, 4.5757, 7.2127]),
    ("Orange Powder", [0.00015617, 0.00017482, 0.0001762], [0.001449, 0.003441, 0.007863]),
    ("Pink Lemonade Powder", [0.00012103, 0.00013073, 0.00012528], [0.001165, 0.002366, 0.003195]),
    ("Cappuccino Powder", [1.8436, 2.5851, 2.1662], [35.844, 49.547, 61.084]),
    ("Salt Powder", [0.027333, 0.032451, 0.031979], [0.28415, 0.3257, 0.34148]),
    ("Sugar Powder", [0.00022272, 0.00025513, 0.000271], [0.012638, 0.031051, 0.050124]),
    ("Suisse Mocha Powder", [2.7979, 3.5452, 4.3365], [17.502, 27.004, 35.433]),
    ("Pacific Ocean Surface Water", [0.0001764, 0.00032095, 0.00019617], [0.031845, 0.031324, 0.030147]),
];

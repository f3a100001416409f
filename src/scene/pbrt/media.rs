//! pbrt-v4's media: `MakeNamedMedium` (the `homogeneous` and `uniformgrid` kinds; the
//! RGB grid, NanoVDB and the procedural cloud are refused for now) and the names
//! `MediumInterface` and the camera refer to.

use super::{Params, ParseError, Parser};
use crate::scene::{Medium, MediumGrid, MediumInterface, SampledGrid, MAX_MEDIA};
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
        if ty != "homogeneous" && ty != "uniformgrid" {
            // (Its parameters are not checked: the whole medium is unsupported.)
            for p in &params.0 {
                p.used.set(true);
            }
            self.unsupported(
                file,
                line,
                format!(
                    "MakeNamedMedium \"{ty}\" (participating media: homogeneous and uniformgrid only)"
                ),
            );
            self.named_media.insert(name, 0);
            return Ok(());
        }
        if let Some(p) = params.find("preset") {
            let (f, l) = (p.file, p.line);
            self.unsupported(
                f,
                l,
                "MakeNamedMedium: \"preset\" (the named scattering presets)",
            );
        }
        let spectrum =
            |this: &mut Self, what: &str, emitted: bool| -> Result<Option<Vec3>, ParseError> {
                match params.find(what).cloned() {
                    Some(p) => this.rgb(&p, d, emitted),
                    None => Ok(None),
                }
            };
        let sigma_a = spectrum(self, "sigma_a", false)?.unwrap_or(Vec3::ONE);
        let sigma_s = spectrum(self, "sigma_s", false)?.unwrap_or(Vec3::ONE);
        let le = spectrum(self, "Le", true)?.unwrap_or(Vec3::ZERO);
        let num = |what: &str, default: f64| {
            params
                .find(what)
                .and_then(|p| p.nums.first().copied())
                .unwrap_or(default) as f32
        };
        let scale = num("scale", 1.0);
        let grid = if ty == "uniformgrid" {
            Some(self.uniform_grid(&name, params, file, line)?)
        } else {
            None
        };
        // (A grid's Lescale is its grid of scales.)
        let le_scale = if grid.is_some() {
            1.0
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
        let count = res.iter().map(|&r| r as u64).product::<u64>();
        if let Some(p) = params.find("temperature") {
            let (f, l) = (p.file, p.line);
            self.unsupported(
                f,
                l,
                "MakeNamedMedium \"uniformgrid\": \"temperature\" (blackbody emission)",
            );
        }
        for what in ["temperaturecutoff", "temperatureoffset", "temperaturescale"] {
            params.find(what);
        }
        let floats = |this: &Self, what: &str| -> Result<Option<Vec<f32>>, ParseError> {
            let Some(p) = params.find(what) else {
                return Ok(None);
            };
            if p.nums.len() as u64 != count {
                return Err(bad(
                    this,
                    (p.file, p.line),
                    format!(
                        "\"{what}\" has {} values; nx × ny × nz = {} × {} × {} = {count} expected",
                        p.nums.len(),
                        res[0],
                        res[1],
                        res[2]
                    ),
                ));
            }
            if let Some(v) = p.nums.iter().find(|v| !v.is_finite() || **v < 0.0) {
                return Err(bad(
                    this,
                    (p.file, p.line),
                    format!("\"{what}\" must be finite and not negative, got {v}"),
                ));
            }
            Ok(Some(p.nums.iter().map(|&v| v as f32).collect()))
        };
        let Some(density) = floats(self, "density")? else {
            return Err(bad(
                self,
                (file, line),
                "no \"density\" values (a uniformgrid needs them)".into(),
            ));
        };
        let le_scale = match floats(self, "Lescale")? {
            Some(values) => SampledGrid { res, values },
            None => SampledGrid {
                res: [1, 1, 1],
                values: vec![1.0],
            },
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
        let density = SampledGrid {
            res,
            values: density,
        };
        let majorants = crate::media::density_majorants(&density);
        Ok(Arc::new(MediumGrid {
            unit_from_world: world_from_unit.inverse(),
            density,
            le_scale,
            majorants,
        }))
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

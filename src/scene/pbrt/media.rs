//! pbrt-v4's media: `MakeNamedMedium` (the `homogeneous` kind; the grids and the
//! procedural cloud are refused for now) and the names `MediumInterface` and the camera
//! refer to.

use super::{Params, ParseError, Parser};
use crate::scene::{Medium, MediumInterface, MAX_MEDIA};
use glam::Vec3;

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
        if ty != "homogeneous" {
            // (Its parameters are not checked: the whole medium is unsupported.)
            for p in &params.0 {
                p.used.set(true);
            }
            self.unsupported(
                file,
                line,
                format!("MakeNamedMedium \"{ty}\" (participating media: homogeneous only)"),
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
        let le_scale = num("Lescale", 1.0);
        let g = num("g", 0.0);
        self.check_used(d, "\"homogeneous\"", params);
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
        });
        self.named_media.insert(name, self.scene.media.len() as u32);
        Ok(())
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

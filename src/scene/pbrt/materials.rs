//! Materials: pbrt-v4's material types as lightpath's, named materials and mixes.

use super::*;

/// The material a shape uses.
#[derive(Clone, Debug)]
pub(super) enum MaterialRef {
    Material(Material),
    /// `interface`: no surface (a boundary between media); its shapes are not rendered.
    Interface,
    /// `mix`: two materials and the second's probability (a constant or a float texture).
    Mix(Box<[MaterialRef; 2]>, Value),
}

/// How deep mixes nest in a material (0: not a mix).
pub(super) fn mix_depth(m: &MaterialRef) -> u32 {
    match m {
        MaterialRef::Mix(refs, _) => 1 + mix_depth(&refs[0]).max(mix_depth(&refs[1])),
        _ => 0,
    }
}

pub(super) fn diffuse(kd: Vec3) -> Material {
    Material {
        bsdf: BsdfKind::Phong,
        diffuse: kd,
        specular: Vec3::ZERO,
        ..Material::default()
    }
}

pub(super) fn named_spectrum(name: &str) -> Option<Vec3> {
    let measured = |text: &str| {
        spectrum::Sampled::from_spd(text)
            .expect("a named spectrum's table")
            .bounded_rgb()
            .max(Vec3::ZERO)
    };
    Some(match name {
        "metal-Cu-eta" => crate::scene::COPPER_ETA,
        "metal-Cu-k" => crate::scene::COPPER_K,
        "metal-Au-eta" => Vec3::new(0.143_119, 0.374_957, 1.442_48),
        "metal-Au-k" => Vec3::new(3.983_16, 2.385_72, 1.603_22),
        "metal-Ag-eta" => Vec3::new(0.155_265, 0.116_723, 0.138_342),
        "metal-Ag-k" => Vec3::new(4.828_35, 3.122_25, 2.146_96),
        "metal-Al-eta" => Vec3::new(1.657_46, 0.880_369, 0.521_229),
        "metal-Al-k" => Vec3::new(9.223_87, 6.269_52, 4.837),
        // pbrt-v4's other named metals, from their measured tables (refractiveindex.info)
        // projected as a bounded `.spd` spectrum is (spectrum.rs), k kept non-negative.
        "metal-CuZn-eta" => measured(include_str!("../data/spectra/metal-CuZn-eta.spd")),
        "metal-CuZn-k" => measured(include_str!("../data/spectra/metal-CuZn-k.spd")),
        "metal-MgO-eta" => measured(include_str!("../data/spectra/metal-MgO-eta.spd")),
        "metal-MgO-k" => measured(include_str!("../data/spectra/metal-MgO-k.spd")),
        "metal-TiO2-eta" => measured(include_str!("../data/spectra/metal-TiO2-eta.spd")),
        "metal-TiO2-k" => measured(include_str!("../data/spectra/metal-TiO2-k.spd")),
        "glass-BK7" => Vec3::splat(1.5168),
        "glass-BAF10" => Vec3::splat(1.67),
        "glass-F11" => Vec3::splat(1.62),
        _ => return None,
    })
}

impl Parser {
    pub(super) fn material(
        &mut self,
        ty: &str,
        params: &Params,
        file: u32,
        line: u32,
    ) -> Result<MaterialRef, ParseError> {
        let d = "Material";
        params.find("type");
        let mut m = Material::default();
        // A microfacet roughness (`{prefix}roughness`, `uroughness`, `vroughness`): the
        // alphas, or a texture (remapped at lookup when `remaproughness`).
        let roughness_of = |this: &mut Self,
                            prefix: &str|
         -> Result<(f32, f32, Option<u32>, bool), ParseError> {
            let remap = params
                .find("remaproughness")
                .and_then(|p| p.bools.first().copied())
                .unwrap_or(true);
            let r = this.value(params, &format!("{prefix}roughness"), true, d)?;
            let u = this
                .value(params, &format!("{prefix}uroughness"), true, d)?
                .or(r);
            let v = this
                .value(params, &format!("{prefix}vroughness"), true, d)?
                .or(r);
            let remap_f = |x: f32| if remap { x.max(0.0).sqrt() } else { x };
            match (u, v) {
                (Some(Value::Texture(t)), _) | (_, Some(Value::Texture(t))) => {
                    Ok((0.0, 0.0, Some(t), remap))
                }
                (u, v) => {
                    let get = |x: Option<Value>| match x {
                        Some(Value::Const(c)) => c.x,
                        _ => 0.0,
                    };
                    let (au, av) = (remap_f(get(u)), remap_f(get(v)));
                    if au < 0.0 || av < 0.0 {
                        return Err(this.err_at(file, line, d, "roughness must not be negative"));
                    }
                    Ok((au, av, None, false))
                }
            }
        };
        let roughness = |this: &mut Self, m: &mut Material| -> Result<(), ParseError> {
            let (au, av, texture, remap) = roughness_of(this, "")?;
            m.roughness = au;
            m.roughness_v = av;
            m.roughness_texture = texture;
            m.remap_roughness_texture = remap;
            Ok(())
        };
        let eta_named = |this: &mut Self, name: &str| -> Result<f32, ParseError> {
            let eta = match this.value(params, name, true, d)? {
                Some(Value::Const(c)) => c.x,
                Some(Value::Texture(_)) => {
                    this.unsupported(file, line, "a textured index of refraction");
                    1.5
                }
                None => 1.5,
            };
            if !(eta > 0.0 && eta.is_finite()) {
                return Err(this.err_at(
                    file,
                    line,
                    d,
                    format!("eta must be positive and finite, got {eta}"),
                ));
            }
            Ok(eta)
        };
        let eta = |this: &mut Self| eta_named(this, "eta");
        // A coating's layer: pbrt-v4's `thickness`, `maxdepth`, `nsamples` (and `albedo`
        // and `g` of a scattering layer).
        let layer = |this: &mut Self, m: &mut Material, what: &str| -> Result<(), ParseError> {
            let num = |name: &str, default: f64| {
                params
                    .find(name)
                    .and_then(|p| p.nums.first().copied())
                    .unwrap_or(default)
            };
            match this.value(params, "thickness", true, d)? {
                Some(Value::Texture(t)) => m.thickness_texture = Some(t),
                _ => m.thickness = num("thickness", 0.01) as f32,
            }
            m.layer_max_depth = num("maxdepth", 10.0).clamp(1.0, 1000.0) as u32;
            m.layer_samples = num("nsamples", 1.0).clamp(1.0, 64.0) as u32;
            // The scattering layer: albedo and g clamped as pbrt-v4 clamps them.
            match this.value(params, "albedo", false, d)? {
                Some(Value::Const(c)) => m.layer_albedo = c.clamp(Vec3::ZERO, Vec3::ONE),
                Some(Value::Texture(_)) => {
                    this.unsupported(file, line, format!("{what}: a textured albedo"))
                }
                None => {}
            }
            match this.value(params, "g", true, d)? {
                Some(Value::Const(c)) => m.layer_g = c.x.clamp(-1.0, 1.0),
                Some(Value::Texture(_)) => {
                    this.unsupported(file, line, format!("{what}: a textured g"))
                }
                None => {}
            }
            if m.thickness < 0.0 {
                return Err(this.err_at(file, line, d, "thickness must not be negative"));
            }
            Ok(())
        };
        // A conductor's eta and k (`{prefix}eta`, `{prefix}k`), or pbrt-v4's
        // artist-friendly `reflectance` r (eta 1, k = 2 sqrt(r) / sqrt(1 - r)); a textured
        // reflectance where `textured` allows it (its texture becomes the diffuse one).
        let conductor = |this: &mut Self,
                         m: &mut Material,
                         prefix: &str,
                         textured: bool|
         -> Result<(), ParseError> {
            if let Some(r) = this.value(params, "reflectance", false, d)? {
                match r {
                    Value::Const(r) => {
                        if r.max_element() >= 1.0 || r.min_element() < 0.0 {
                            return Err(this.err_at(
                                file,
                                line,
                                d,
                                "a conductor's reflectance must lie in [0, 1)",
                            ));
                        }
                        m.eta = Vec3::ONE;
                        m.k = 2.0 * r.map(f32::sqrt) / (Vec3::ONE - r).map(f32::sqrt);
                    }
                    Value::Texture(t) if textured => m.diffuse_texture = Some(t),
                    Value::Texture(_) => {
                        this.unsupported(file, line, "conductor: a textured reflectance")
                    }
                }
                return Ok(());
            }
            for (name, slot) in [("eta", 0), ("k", 1)] {
                let name = format!("{prefix}{name}");
                match this.value(params, &name, false, d)? {
                    Some(Value::Const(c)) => {
                        if c.min_element() < 0.0 {
                            return Err(this.err_at(
                                file,
                                line,
                                d,
                                format!("{name} must not be negative"),
                            ));
                        }
                        if slot == 0 {
                            m.eta = c
                        } else {
                            m.k = c
                        }
                    }
                    Some(Value::Texture(_)) => {
                        this.unsupported(file, line, format!("a textured {name}"))
                    }
                    None => {}
                }
            }
            Ok(())
        };
        match ty {
            // pbrt-v4 makes no material of "" or "none": its shapes only bound media, as an
            // interface's.
            "interface" | "" | "none" => {
                self.check_used(d, &format!("\"{ty}\""), params);
                return Ok(MaterialRef::Interface);
            }
            "mix" => return self.mix_material(params, file, line),
            "diffuse" => {
                m = diffuse(Vec3::splat(0.5));
                match self.value(params, "reflectance", false, d)? {
                    // (Clamped to [0, 1] as pbrt-v4 clamps it; a texture's value where
                    // bsdf.glsl's material_bsdf reads it.)
                    Some(Value::Const(c)) => m.diffuse = c.clamp(Vec3::ZERO, Vec3::ONE),
                    Some(Value::Texture(t)) => m.diffuse_texture = Some(t),
                    None => {}
                }
            }
            "coateddiffuse" => {
                m.bsdf = BsdfKind::CoatedDiffuse;
                m.diffuse = Vec3::splat(0.5);
                match self.value(params, "reflectance", false, d)? {
                    // (Clamped to [0, 1] as pbrt-v4 clamps it; a texture's value where
                    // bsdf.glsl's material_bsdf reads it.)
                    Some(Value::Const(c)) => m.diffuse = c.clamp(Vec3::ZERO, Vec3::ONE),
                    Some(Value::Texture(t)) => m.diffuse_texture = Some(t),
                    None => {}
                }
                roughness(self, &mut m)?;
                m.ior = eta(self)?;
                layer(self, &mut m, "coateddiffuse")?;
            }
            "coatedconductor" => {
                // pbrt-v4's CoatedConductorMaterial: a dielectric coating (`interface.*`)
                // over a conductor (`conductor.*`, or `reflectance`), copper by default.
                m.bsdf = BsdfKind::CoatedConductor;
                let (au, av, texture, remap) = roughness_of(self, "interface.")?;
                m.roughness = au;
                m.roughness_v = av;
                m.roughness_texture = texture;
                let (bu, bv, base_texture, base_remap) = roughness_of(self, "conductor.")?;
                m.base_roughness = bu;
                m.base_roughness_v = bv;
                m.base_roughness_texture = base_texture;
                m.remap_roughness_texture = remap || base_remap;
                m.ior = eta_named(self, "interface.eta")?;
                conductor(self, &mut m, "conductor.", true)?;
                layer(self, &mut m, "coatedconductor")?;
            }
            "diffusetransmission" => {
                // pbrt-v4: R and T (0.25 each) times `scale`, each clamped to [0, 1].
                m.bsdf = BsdfKind::DiffuseTransmission;
                let scale = params
                    .find("scale")
                    .and_then(|p| p.nums.first().copied())
                    .unwrap_or(1.0) as f32;
                if !(scale >= 0.0 && scale.is_finite()) {
                    return Err(self.err_at(
                        file,
                        line,
                        d,
                        format!("scale must be non-negative and finite, got {scale}"),
                    ));
                }
                for name in ["reflectance", "transmittance"] {
                    let c = match self.value(params, name, false, d)? {
                        Some(Value::Const(c)) => c,
                        Some(Value::Texture(t)) => {
                            // (A textured value times the scale: a scaled texture, as
                            // the `scale` texture makes it.)
                            let t = match scale {
                                1.0 => t,
                                _ => match self.scale_value(
                                    Value::Texture(t),
                                    Value::Const(Vec3::splat(scale)),
                                    file,
                                    line,
                                )? {
                                    Value::Texture(t) => t,
                                    Value::Const(_) => unreachable!("a texture times a constant"),
                                },
                            };
                            if name == "reflectance" {
                                m.diffuse_texture = Some(t);
                            } else {
                                m.transmittance_texture = Some(t);
                            }
                            Vec3::splat(0.25)
                        }
                        None => Vec3::splat(0.25),
                    };
                    let c = (c * scale).clamp(Vec3::ZERO, Vec3::ONE);
                    if name == "reflectance" {
                        m.diffuse = c;
                    } else {
                        m.transmittance = c;
                    }
                }
            }
            "dielectric" | "thindielectric" => {
                m.bsdf = if ty == "dielectric" {
                    BsdfKind::Dielectric
                } else {
                    BsdfKind::ThinDielectric
                };
                m.ior = eta(self)?;
                if ty == "dielectric" {
                    roughness(self, &mut m)?;
                }
            }
            "conductor" => {
                m.bsdf = BsdfKind::Conductor;
                roughness(self, &mut m)?;
                conductor(self, &mut m, "", true)?;
            }
            "measured" => {
                // pbrt-v4's MeasuredMaterial: an RGL `.bsdf` file (relative to the file
                // that names it), read once however many materials name it.
                let Some(p) = params.find("filename").cloned() else {
                    return Err(self.err_at(file, line, d, "measured: no \"string filename\""));
                };
                let path = self.resolve(p.file, &p.strs[0]);
                let index = match self.measured_files.get(&path) {
                    Some(&i) => i,
                    None => {
                        let table = crate::measured::MeasuredBsdf::read(&path).map_err(|e| {
                            self.err_at(p.file, p.line, d, format!("measured: {e:#}"))
                        })?;
                        self.scene.measured.push(Arc::new(table));
                        let i = self.scene.measured.len() as u32 - 1;
                        self.measured_files.insert(path, i);
                        i
                    }
                };
                m.bsdf = BsdfKind::Measured;
                m.measured = Some(index);
            }
            "hair" => {
                // pbrt-v4's HairMaterial (src/hair.rs): the absorption from `sigma_a`, else
                // from the colour (`reflectance`, or `color`), else from melanin
                // concentrations, else brown hair (eumelanin 1.3); the roughnesses clamped
                // to [0.01, 1] as pbrt-v4 clamps them.
                m.bsdf = BsdfKind::Hair;
                let float = |this: &mut Self,
                             name: &str,
                             default: f32|
                 -> Result<Option<f32>, ParseError> {
                    Ok(match this.value(params, name, true, d)? {
                        Some(Value::Const(c)) => Some(c.x),
                        Some(Value::Texture(_)) => {
                            this.unsupported(file, line, format!("hair: a textured {name}"));
                            Some(default)
                        }
                        None => None,
                    })
                };
                let eta = float(self, "eta", 1.55)?.unwrap_or(1.55);
                if !(eta > 0.0 && eta.is_finite()) {
                    return Err(self.err_at(
                        file,
                        line,
                        d,
                        format!("hair: eta must be positive and finite, got {eta}"),
                    ));
                }
                let beta_m = float(self, "beta_m", 0.3)?.unwrap_or(0.3).clamp(0.01, 1.0);
                let beta_n = float(self, "beta_n", 0.3)?.unwrap_or(0.3).clamp(0.01, 1.0);
                let alpha = float(self, "alpha", 2.0)?.unwrap_or(2.0);
                let eumelanin = float(self, "eumelanin", 0.0)?;
                let pheomelanin = float(self, "pheomelanin", 0.0)?;
                let colour = |this: &mut Self, name: &str| -> Result<Option<Vec3>, ParseError> {
                    Ok(match this.value(params, name, false, d)? {
                        Some(Value::Const(c)) => Some(c),
                        Some(Value::Texture(_)) => {
                            this.unsupported(file, line, format!("hair: a textured {name}"));
                            Some(Vec3::splat(0.5))
                        }
                        None => None,
                    })
                };
                let sigma_a = colour(self, "sigma_a")?;
                let reflectance = match colour(self, "reflectance")? {
                    Some(c) => Some(c),
                    None => colour(self, "color")?,
                };
                m.k = match (sigma_a, reflectance) {
                    (Some(s), _) => s.max(Vec3::ZERO),
                    (None, Some(c)) => crate::hair::sigma_a_from_reflectance(c, beta_n),
                    (None, None) if eumelanin.is_some() || pheomelanin.is_some() => {
                        crate::hair::sigma_a_from_concentration(
                            eumelanin.unwrap_or(0.0).max(0.0),
                            pheomelanin.unwrap_or(0.0).max(0.0),
                        )
                    }
                    (None, None) => crate::hair::sigma_a_from_concentration(1.3, 0.0),
                };
                m.ior = eta;
                m.roughness = beta_m;
                m.roughness_v = beta_n;
                m.shininess = alpha;
            }
            other => {
                self.unsupported(file, line, format!("Material \"{other}\""));
                for p in &params.0 {
                    p.used.set(true);
                }
                return Ok(MaterialRef::Material(diffuse(Vec3::splat(0.5))));
            }
        }
        // (pbrt-v4's hair reads no displacement or normal map.)
        if m.bsdf != BsdfKind::Hair {
            m.shading_map = self.shading_map(params, d)?;
        }
        self.check_used(d, &format!("\"{ty}\""), params);
        Ok(MaterialRef::Material(m))
    }

    /// A material's `normalmap` (an image file, read as linear RGB, repeating) or else its
    /// `displacement` (a float texture), as pbrt-v4 prefers them.
    pub(super) fn shading_map(
        &mut self,
        params: &Params,
        d: &str,
    ) -> Result<Option<crate::scene::ShadingMap>, ParseError> {
        use crate::scene::ShadingMap;
        let displacement = self.value(params, "displacement", true, d)?;
        if let Some(p) = params.find("normalmap").cloned() {
            let Some(name) = p.strs.first().filter(|s| !s.is_empty()) else {
                return Ok(None);
            };
            let path = self.resolve(p.file, name);
            let image =
                self.image_texture(path, Encoding::Linear, (p.file, p.line, d), "normalmap: ");
            self.scene.textures.push(Texture::Image {
                image,
                scale: Vec3::ONE,
                mapping: crate::texture::UV_MAPPING,
                wrap: Wrap::Repeat,
                projection: Projection::Uv,
                filter: crate::texture::Filter::Bilinear,
                max_anisotropy: crate::texture::DEFAULT_MAX_ANISOTROPY,
            });
            return Ok(Some(ShadingMap::Normal(
                self.scene.textures.len() as u32 - 1,
            )));
        }
        Ok(match displacement {
            Some(Value::Texture(t)) => Some(ShadingMap::Bump(t)),
            Some(Value::Const(c)) => {
                if c.x != 0.0 {
                    self.warn(
                        "constant displacement",
                        "a constant \"displacement\" is ignored (it tilts no normal of flat \
                         geometry; on curved geometry lightpath leaves the normal as it is)"
                            .into(),
                    );
                }
                None
            }
            None => None,
        })
    }

    /// pbrt-v4's `mix`: `string materials` names two materials made before, `amount`
    /// (0.5) the probability of the second.
    pub(super) fn mix_material(
        &mut self,
        params: &Params,
        file: u32,
        line: u32,
    ) -> Result<MaterialRef, ParseError> {
        let d = "Material";
        let names = match params.find("materials") {
            Some(p) if p.ty == "string" && p.strs.len() == 2 => p.strs.clone(),
            _ => {
                return Err(self.err_at(
                    file,
                    line,
                    d,
                    "mix needs \"string materials\" with two material names",
                ))
            }
        };
        let mut refs = Vec::with_capacity(2);
        for name in &names {
            match self.named_material(name)? {
                Some(MaterialRef::Interface) => {
                    self.unsupported(file, line, "mix: an interface material");
                    refs.push(MaterialRef::Material(diffuse(Vec3::splat(0.5))));
                }
                Some(m) => {
                    if mix_depth(&m) >= MAX_MIX_DEPTH {
                        return Err(self.err_at(
                            file,
                            line,
                            d,
                            format!("mixes nest more than {MAX_MIX_DEPTH} deep"),
                        ));
                    }
                    refs.push(m)
                }
                None => {
                    return Err(self.err_at(file, line, d, format!("no material named \"{name}\"")))
                }
            }
        }
        let amount = self
            .value(params, "amount", true, d)?
            .unwrap_or(Value::Const(Vec3::splat(0.5)));
        if let Value::Const(c) = amount {
            if !c.x.is_finite() {
                return Err(self.err_at(file, line, d, "mix: amount must be finite"));
            }
        }
        self.check_used(d, "\"mix\"", params);
        let [a, b]: [MaterialRef; 2] = refs.try_into().expect("two materials");
        Ok(MaterialRef::Mix(Box::new([a, b]), amount))
    }

    /// The scene's index of a shape's material, with the emission of its area light and
    /// the media it bounds (a mix's materials carry both too, since the kernels resolve a
    /// mix to one of them).
    pub(super) fn intern_ref(
        &mut self,
        r: &MaterialRef,
        emission: Option<(Vec3, bool)>,
        media: Option<crate::scene::MediumInterface>,
    ) -> u32 {
        let mut m = match r {
            MaterialRef::Material(m) => *m,
            MaterialRef::Interface => Material {
                pass_through: true,
                ..Material::default()
            },
            MaterialRef::Mix(refs, amount) => {
                let materials = [
                    self.intern_ref(&refs[0], emission, media),
                    self.intern_ref(&refs[1], emission, media),
                ];
                let (amount, amount_texture) = match *amount {
                    Value::Const(c) => (c.x, None),
                    Value::Texture(t) => (0.5, Some(t)),
                };
                Material {
                    mix: Some(MaterialMix {
                        materials,
                        amount,
                        amount_texture,
                    }),
                    ..Material::default()
                }
            }
        };
        if let Some((e, two_sided)) = emission {
            m.emission = e;
            m.two_sided_emission = two_sided;
        }
        m.medium_interface = media;
        self.intern(m)
    }

    pub(super) fn intern(&mut self, m: Material) -> u32 {
        let materials = &mut self.scene.materials;
        *self
            .material_lookup
            .entry(MaterialKey::of(&m))
            .or_insert_with(|| {
                materials.push(m);
                (materials.len() - 1) as u32
            })
    }
}

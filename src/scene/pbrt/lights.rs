//! Light sources and area lights.

use super::*;

/// An area light as declared (applies to the shapes that follow it).
#[derive(Clone, Debug)]
pub(super) struct AreaLight {
    pub(super) radiance: Vec3,
    pub(super) two_sided: bool,
    /// pbrt-v4's `power` (W), which rescales the radiance by the shape's area.
    pub(super) power: Option<f32>,
}

/// The luminance of a linear sRGB colour.
fn luminance(c: Vec3) -> f32 {
    0.212_672_9 * c.x + 0.715_152_2 * c.y + 0.072_175 * c.z
}

/// The illuminance an equal-area environment map (radiance in linear sRGB) gives a
/// surface facing its +z: the sum over the pixels above the horizon of their luminance
/// times cos θ times their solid angle (4π over the pixel count).
pub(super) fn upper_hemisphere_illuminance(image: &crate::io::Image) -> f32 {
    let (w, h) = (image.width as usize, image.height as usize);
    let mut sum = 0.0f64;
    for y in 0..h {
        for x in 0..w {
            let uv = Vec2::new((x as f32 + 0.5) / w as f32, (y as f32 + 0.5) / h as f32);
            let z = crate::texture::equal_area_square_to_sphere(uv).z;
            if z > 0.0 {
                let p = image.pixels[y * w + x];
                sum += (luminance(Vec3::from(p)) * z) as f64;
            }
        }
    }
    (sum * 4.0 * std::f64::consts::PI / (w * h) as f64) as f32
}

/// Two infinite lights without portals as one: constants add; a constant adds to each
/// texel of a map (scaled by the map's radiance), which is exact for the bilinear lookup
/// and leaves the map's sampling proportional to what it emits. Two maps cannot be one
/// (Err: the first).
pub(super) fn add_environments(a: Environment, b: Environment) -> Result<Environment, Environment> {
    match (&a.map, &b.map) {
        (None, None) => Ok(Environment {
            radiance: a.radiance + b.radiance,
            map: None,
            portal: None,
        }),
        (Some(_), Some(_)) => Err(a),
        _ => {
            let (lit, constant) = if a.map.is_some() { (a, b) } else { (b, a) };
            let map = lit.map.expect("a map");
            let mut image = (*map.image).clone();
            for p in &mut image.pixels {
                *p = (Vec3::from_array(*p) * lit.radiance + constant.radiance).to_array();
            }
            Ok(Environment {
                radiance: Vec3::ONE,
                map: Some(EnvironmentMap {
                    image: Arc::new(image),
                    ..map
                }),
                portal: None,
            })
        }
    }
}

impl Parser {
    /// A light's colour: `name`'s RGB times `scale`, times the film's imaging ratio.
    pub(super) fn light_colour(
        &mut self,
        params: &Params,
        name: &str,
        default: Vec3,
        d: &str,
    ) -> Result<Vec3, ParseError> {
        let base = match params.find(name).cloned() {
            Some(p) => self.rgb(&p, d, true)?.unwrap_or(Vec3::ONE),
            None => default,
        };
        let scale = params
            .find("scale")
            .and_then(|p| p.nums.first().copied())
            .unwrap_or(1.0) as f32;
        Ok(base * scale)
    }

    pub(super) fn light(
        &mut self,
        ty: &str,
        params: &Params,
        file: u32,
        line: u32,
    ) -> Result<(), ParseError> {
        let d = "LightSource";
        let ctm = self.gs.ctm;
        let point = |params: &Params, name: &str, default: Vec3| {
            params.find(name).map_or(default, |p| {
                Vec3::new(p.nums[0] as f32, p.nums[1] as f32, p.nums[2] as f32)
            })
        };
        // (pbrt-v4's distant and infinite lights take "illuminance" instead.)
        let power = if matches!(ty, "point" | "spot" | "goniometric" | "projection") {
            params
                .find("power")
                .and_then(|p| p.nums.first().copied())
                .map(|x| x as f32)
        } else {
            None
        };
        match ty {
            "point" => {
                let mut i = self.light_colour(params, "I", Vec3::ONE, d)?;
                // (pbrt-v4 divides by the photometric value of the colour space's
                // illuminant only, so an RGB intensity keeps its values.)
                if let Some(phi) = power {
                    i *= phi / (4.0 * std::f32::consts::PI);
                }
                let position = ctm.transform_point3(point(params, "from", Vec3::ZERO));
                self.scene.delta_lights.push(DeltaLight::Point {
                    position,
                    intensity: i,
                });
            }
            "spot" => {
                let mut i = self.light_colour(params, "I", Vec3::ONE, d)?;
                let from = point(params, "from", Vec3::ZERO);
                let to = point(params, "to", Vec3::Z);
                let cone = params
                    .find("coneangle")
                    .and_then(|p| p.nums.first().copied())
                    .unwrap_or(30.0) as f32;
                let delta = params
                    .find("conedeltaangle")
                    .and_then(|p| p.nums.first().copied())
                    .unwrap_or(5.0) as f32;
                if !(cone > 0.0 && cone <= 180.0 && delta >= 0.0) {
                    return Err(self.err_at(
                        file,
                        line,
                        d,
                        "spot: coneangle must be in (0, 180] and conedeltaangle not negative",
                    ));
                }
                let cos_end = cone.to_radians().cos();
                let cos_start = (cone - delta).max(0.0).to_radians().cos();
                if let Some(phi) = power {
                    let k_e = 2.0
                        * std::f32::consts::PI
                        * ((1.0 - cos_start) + (cos_start - cos_end) / 2.0);
                    i *= phi / k_e;
                }
                let dir = ctm.transform_vector3(to - from);
                if dir.length_squared() == 0.0 {
                    return Err(self.err_at(file, line, d, "spot: from and to coincide"));
                }
                self.scene.delta_lights.push(DeltaLight::Spot {
                    position: ctm.transform_point3(from),
                    direction: dir.normalize(),
                    intensity: i,
                    cos_falloff_start: cos_start,
                    cos_falloff_end: cos_end,
                });
            }
            "distant" => {
                let mut l = self.light_colour(params, "L", Vec3::ONE, d)?;
                if let Some(e) = params
                    .find("illuminance")
                    .and_then(|p| p.nums.first().copied())
                {
                    l *= e as f32;
                }
                let from = point(params, "from", Vec3::ZERO);
                let to = point(params, "to", Vec3::Z);
                let dir = ctm.transform_vector3(from - to);
                if dir.length_squared() == 0.0 {
                    return Err(self.err_at(file, line, d, "distant: from and to coincide"));
                }
                self.scene.delta_lights.push(DeltaLight::Directional {
                    direction: dir.normalize(),
                    radiance: l,
                });
            }
            "infinite" => {
                let file_param = params.find("filename").cloned();
                let mut l = self.light_colour(params, "L", Vec3::ONE, d)?;
                let illuminance = params
                    .find("illuminance")
                    .and_then(|p| p.nums.first().copied())
                    .map(|e| e as f32);
                if file_param.is_none() {
                    if let Some(e) = illuminance {
                        // The upper hemisphere's illuminance from constant L is π L.
                        l *= e / std::f32::consts::PI;
                    }
                }
                let portal = match params.find("portal").cloned() {
                    None => None,
                    Some(p) => {
                        if p.nums.len() != 12 {
                            return Err(self.err_at(
                                p.file,
                                p.line,
                                d,
                                format!(
                                    "infinite: \"portal\" takes 4 points (12 numbers), got {}",
                                    p.nums.len()
                                ),
                            ));
                        }
                        let q: Vec<Vec3> = p
                            .nums
                            .chunks(3)
                            .map(|c| {
                                ctm.transform_point3(Vec3::new(
                                    c[0] as f32,
                                    c[1] as f32,
                                    c[2] as f32,
                                ))
                            })
                            .collect();
                        // A rectangle, as pbrt-v4 requires.
                        let (e1, e3) = (q[1] - q[0], q[3] - q[0]);
                        let scale = e1.length() * e3.length();
                        let square = e1.normalize_or_zero().dot(e3.normalize_or_zero()).abs()
                            < 1e-3
                            && (q[0] + e1 + e3 - q[2]).length() <= 1e-3 * scale.sqrt()
                            && scale > 0.0;
                        if !square {
                            return Err(self.err_at(p.file, p.line, d, "infinite: the \"portal\" is not a rectangle (p0 p1 p2 p3 in order)"));
                        }
                        Some([q[0], q[1], q[2], q[3]])
                    }
                };
                let map = match file_param {
                    None => None,
                    Some(p) => {
                        let path = self.resolve(p.file, &p.strs[0]);
                        let image = load_image(&path, Encoding::Linear)
                            .map_err(|e| self.err_at(p.file, p.line, d, e))?;
                        if image.width != image.height {
                            return Err(self.err_at(p.file, p.line, d, format!("{}: an equal-area environment map is square, this one is {}x{}", path.display(), image.width, image.height)));
                        }
                        let linear = Mat3::from_mat4(ctm);
                        let s = linear.col(0).length();
                        let rotation = linear * (1.0 / s);
                        let orthonormal = (rotation.transpose() * rotation - Mat3::IDENTITY)
                            .to_cols_array()
                            .iter()
                            .all(|x| x.abs() < 1e-4);
                        // A mirror is read as pbrt-v4 reads it: directions go through the
                        // light's (orthonormal) frame either way.
                        if !orthonormal {
                            return Err(self.err_at(
                                file,
                                line,
                                d,
                                "the transform turns the environment map by more than a rotation and a mirror",
                            ));
                        }
                        if let Some(e) = illuminance {
                            // As pbrt-v4: scaled so that a surface facing the map's +z
                            // (in the light's space) receives illuminance e.
                            let k = upper_hemisphere_illuminance(&image);
                            if !(k > 0.0) {
                                return Err(self.err_at(p.file, p.line, d, format!("{}: \"illuminance\" asks to scale a map that lights nothing above its horizon", path.display())));
                            }
                            l *= e / k;
                        }
                        Some(EnvironmentMap {
                            image: Arc::new(image),
                            mapping: EnvMapping::EqualArea,
                            to_world: rotation,
                        })
                    }
                };
                let light = Environment {
                    radiance: l,
                    map,
                    portal,
                };
                // A constant light without a portal adds into another such light (one
                // emitter the fewer to sample); any other is an emitter of its own.
                let envs = &mut self.scene.environments;
                let merge = light.portal.is_none().then(|| {
                    envs.iter().position(|e| {
                        e.portal.is_none() && (e.map.is_none() || light.map.is_none())
                    })
                });
                match merge.flatten() {
                    Some(i) => {
                        envs[i] = add_environments(envs[i].clone(), light)
                            .expect("one of the two is constant");
                    }
                    None => envs.push(light),
                }
            }
            "goniometric" | "projection" => self.profiled_light(ty, params, power, file, line)?,
            other => {
                self.unsupported(file, line, format!("LightSource \"{other}\""));
                for p in &params.0 {
                    p.used.set(true);
                }
            }
        }
        self.check_used(d, &format!("\"{ty}\""), params);
        Ok(())
    }

    /// pbrt-v4's goniometric and projection lights: point lights at the light space's
    /// origin whose intensity an image sets per direction (its nearest pixel).
    fn profiled_light(
        &mut self,
        ty: &str,
        params: &Params,
        power: Option<f32>,
        file: u32,
        line: u32,
    ) -> Result<(), ParseError> {
        let d = "LightSource";
        let ctm = self.gs.ctm;
        let linear = Mat3::from_mat4(ctm);
        if linear.determinant() == 0.0 {
            return Err(self.err_at(file, line, d, format!("{ty}: the transform is singular")));
        }
        let position = ctm.transform_point3(Vec3::ZERO);
        // (The numbers first: the image is read last.)
        let colour = if ty == "goniometric" {
            self.light_colour(params, "I", Vec3::ONE, d)?
        } else {
            Vec3::splat(
                params
                    .find("scale")
                    .and_then(|p| p.nums.first().copied())
                    .unwrap_or(1.0) as f32,
            )
        };
        let fov = if ty == "projection" {
            params
                .find("fov")
                .and_then(|p| p.nums.first().copied())
                .unwrap_or(90.0) as f32
        } else {
            0.0
        };
        let image = match params.find("filename").cloned() {
            Some(p) => {
                let path = self.resolve(p.file, &p.strs[0]);
                // (8-bit images decoded from sRGB, as pbrt-v4's Image::Read tags them.)
                let image = load_image(&path, Encoding::Srgb)
                    .map_err(|e| self.err_at(p.file, p.line, d, e))?;
                if image.pixels.iter().flatten().any(|x| !x.is_finite()) {
                    return Err(self.err_at(p.file, p.line, d, format!("{}: the image has infinite or not-a-number pixels and cannot be a light", path.display())));
                }
                if ty == "goniometric" && image.width != image.height {
                    return Err(self.err_at(p.file, p.line, d, format!("{}: a goniometric light's image is an equal-area square, this one is {}x{}", path.display(), image.width, image.height)));
                }
                Some(image)
            }
            None if ty == "projection" => {
                return Err(self.err_at(
                    file,
                    line,
                    d,
                    "projection: a \"string filename\" is required (the image it projects)",
                ))
            }
            None => {
                self.warn(
                    "goniometric without an image",
                    format!(
                        "{}:{line}: LightSource \"goniometric\" without a \"filename\": lit alike in every direction",
                        self.files[file as usize]
                    ),
                );
                None
            }
        };
        let profile = self.scene.light_profiles.len() as u32;
        let mut light = if ty == "goniometric" {
            // One channel, pbrt-v4's mean of R, G and B; its y and z axes swapped.
            let values = image.as_ref().map_or(vec![1.0], |im| {
                im.pixels
                    .iter()
                    .map(|p| ((p[0] + p[1] + p[2]) / 3.0).max(0.0))
                    .collect()
            });
            let n = image.as_ref().map_or(1, |im| im.width);
            self.scene.light_profiles.push(LightProfile {
                width: n,
                height: n,
                channels: 1,
                values,
            });
            let swap_yz = Mat3::from_cols(Vec3::X, Vec3::Z, Vec3::Y);
            DeltaLight::Goniometric {
                position,
                light_from_world: swap_yz * linear.inverse(),
                intensity: colour,
                profile,
            }
        } else {
            let image = image.expect("projection: an image");
            if !(fov > 0.0 && fov < 180.0) {
                return Err(self.err_at(file, line, d, "projection: fov must be in (0, 180)"));
            }
            self.scene.light_profiles.push(LightProfile {
                width: image.width,
                height: image.height,
                channels: 3,
                values: image.pixels.iter().flatten().map(|x| x.max(0.0)).collect(),
            });
            // pbrt-v4's screen space: the light space with y flipped, x and y over
            // tan(fov / 2).
            let k = 1.0 / (fov.to_radians() / 2.0).tan();
            let screen = Mat3::from_diagonal(Vec3::new(k, -k, 1.0));
            DeltaLight::Projection {
                position,
                screen_from_world: screen * linear.inverse(),
                scale: colour,
                profile,
            }
        };
        if let Some(phi) = power {
            // pbrt-v4: the flux of the image's luminance (a goniometric light's one
            // channel, a projection's RGB) over the sphere becomes `power`.
            let (_, k_e) = light
                .profile_pixel_integral(&self.scene.light_profiles, |c| {
                    luminance(if c.len() == 1 {
                        Vec3::splat(c[0])
                    } else {
                        Vec3::new(c[0], c[1], c[2])
                    })
                })
                .expect("a profiled light");
            if !(k_e > 0.0) {
                return Err(self.err_at(
                    file,
                    line,
                    d,
                    format!("{ty}: \"power\" asks to scale an image that emits nothing"),
                ));
            }
            match &mut light {
                DeltaLight::Goniometric { intensity: c, .. }
                | DeltaLight::Projection { scale: c, .. } => *c *= phi / k_e,
                _ => {}
            }
        }
        self.scene.delta_lights.push(light);
        Ok(())
    }

    pub(super) fn area_light(
        &mut self,
        ty: &str,
        params: &Params,
        file: u32,
        line: u32,
    ) -> Result<(), ParseError> {
        let d = "AreaLightSource";
        if ty != "diffuse" {
            self.unsupported(file, line, format!("AreaLightSource \"{ty}\""));
            for p in &params.0 {
                p.used.set(true);
            }
            return Ok(());
        }
        let radiance = self.light_colour(params, "L", Vec3::ONE, d)?;
        let two_sided = params
            .find("twosided")
            .and_then(|p| p.bools.first().copied())
            .unwrap_or(false);
        let power = params
            .find("power")
            .and_then(|p| p.nums.first().copied())
            .map(|x| x as f32);
        if let Some(p) = params.find("filename") {
            self.unsupported(p.file, p.line, "AreaLightSource: an image");
        }
        self.check_used(d, "\"diffuse\"", params);
        self.gs.area = Some(AreaLight {
            radiance,
            two_sided,
            power,
        });
        Ok(())
    }
}

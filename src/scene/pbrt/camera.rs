//! The camera, the film, the sampler's count and the integrator.

use super::*;

/// The part of the film that is rendered.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Crop {
    /// `cropwindow`: x0 x1 y0 y1 as fractions of the image ((0, 0) the top-left corner).
    Window([f32; 4]),
    /// `pixelbounds`: x0 x1 y0 y1 in pixels (the ends excluded).
    Pixels([i64; 4]),
}

impl Parser {
    pub(super) fn camera(
        &mut self,
        ty: &str,
        camera_from_world: Mat4,
        params: &Params,
        file: u32,
        line: u32,
    ) -> Result<(), ParseError> {
        let fov = params
            .find("fov")
            .and_then(|p| p.nums.first().copied())
            .unwrap_or(90.0) as f32;
        if !(fov > 0.0 && fov < 180.0) {
            return Err(self.err_at(
                file,
                line,
                "Camera",
                format!("fov must be between 0 and 180 degrees, got {fov}"),
            ));
        }
        // The shutter interval: lightpath renders the shutter-open instant (no motion blur);
        // its length is pbrt-v4's exposure time, which scales the image.
        let mut shutter = [0.0, 1.0];
        for (i, name) in ["shutteropen", "shutterclose"].into_iter().enumerate() {
            if let Some(p) = params.find(name) {
                let x = p.nums.first().copied().unwrap_or(f64::NAN);
                if !x.is_finite() {
                    return Err(self.err_at(
                        p.file,
                        p.line,
                        "Camera",
                        format!("{name} must be a finite number, got {x}"),
                    ));
                }
                shutter[i] = x;
                let at = format!("{}:{}", self.files[p.file as usize], p.line);
                self.warn(
                    name,
                    format!("{at}: Camera {name}: rendered at the shutter-open transform, without motion blur"),
                );
            }
        }
        if shutter[1] - shutter[0] <= 0.0 {
            return Err(self.err_at(
                file,
                line,
                "Camera",
                format!(
                    "shutterclose ({}) must be after shutteropen ({}): the shutter never opens",
                    shutter[1], shutter[0]
                ),
            ));
        }
        self.exposure = (shutter[1] - shutter[0]) as f32;
        let positive = |name: &str, default: f64, zero_ok: bool| -> Result<f32, ParseError> {
            let Some(p) = params.find(name) else {
                return Ok(default as f32);
            };
            let x = p.nums.first().copied().unwrap_or(f64::NAN);
            if !(x.is_finite() && (x > 0.0 || (zero_ok && x == 0.0))) {
                let want = if zero_ok {
                    "zero or positive"
                } else {
                    "positive"
                };
                return Err(self.err_at(
                    p.file,
                    p.line,
                    "Camera",
                    format!("{name} must be {want} and finite, got {x}"),
                ));
            }
            Ok(x as f32)
        };
        // pbrt-v4's realistic camera: a lens file's system (src/scene/lens.rs), built in
        // `lens_system` once the film is known. (The last Camera directive is the camera.)
        let mut realistic = None;
        if ty == "realistic" {
            let Some(p) = params
                .find("lensfile")
                .cloned()
                .filter(|p| !p.strs.is_empty())
            else {
                return Err(self.err_at(
                    file,
                    line,
                    "Camera",
                    "a realistic camera needs \"string lensfile\"",
                ));
            };
            let path = self.resolve(p.file, &p.strs[0]);
            let rows = std::fs::read_to_string(&path)
                .map_err(|e| e.to_string())
                .and_then(|text| crate::scene::lens::parse_lens_file(&text))
                .map_err(|e| {
                    self.err_at(p.file, p.line, "Camera", format!("{}: {e}", path.display()))
                })?;
            let aperture = positive("aperturediameter", 1.0, false)?;
            let focus = positive("focusdistance", 10.0, false)?;
            realistic = Some((rows, aperture, focus, file, line));
        }
        let lens_radius = positive("lensradius", 0.0, true)?;
        let focal_distance = positive("focaldistance", 1e6, false)?;
        self.frame_aspect = params
            .find("frameaspectratio")
            .map(|_| positive("frameaspectratio", 1.0, false))
            .transpose()?;
        self.screen_window = match params.find("screenwindow") {
            Some(p) => {
                let w: Vec<f32> = p.nums.iter().map(|&x| x as f32).collect();
                if w.len() != 4 || w.iter().any(|x| !x.is_finite()) || w[0] == w[1] || w[2] == w[3]
                {
                    return Err(self.err_at(
                        p.file,
                        p.line,
                        "Camera",
                        format!("screenwindow must be 4 finite numbers x0 x1 y0 y1 with x0 != x1 and y0 != y1, got {w:?}"),
                    ));
                }
                Some([w[0], w[1], w[2], w[3]])
            }
            None => None,
        };
        self.realistic = realistic;
        if ty == "realistic" {
            if let Some(p) = params.find("aperture") {
                let msg =
                    "Camera \"realistic\": a shaped \"aperture\" (the stop is a disk)".to_string();
                self.unsupported(p.file, p.line, msg);
            }
            self.check_used("Camera", "\"realistic\"", params);
        } else {
            self.check_used("Camera", "\"perspective\"", params);
        }
        let world_from_camera = camera_from_world.inverse();
        let eye = world_from_camera.transform_point3(Vec3::ZERO);
        let forward = world_from_camera.transform_vector3(Vec3::Z);
        let up = world_from_camera.transform_vector3(Vec3::Y);
        let right = world_from_camera.transform_vector3(Vec3::X);
        let finite = eye.is_finite() && forward.is_finite() && up.is_finite() && right.is_finite();
        if !finite || forward.length_squared() == 0.0 || up.length_squared() == 0.0 {
            return Err(self.err_at(file, line, "Camera", "the camera transform is singular"));
        }
        // pbrt's camera space: x to the image's right, y up, z ahead. Ours builds right
        // as forward × up, so a camera whose x is up × forward (pbrt's LookAt) is mirrored.
        let mirror = forward.cross(up).dot(right) < 0.0;
        self.scene.camera = Camera {
            eye,
            look_at: eye + forward.normalize(),
            up: up.normalize(),
            fovy_degrees: fov,
            mirror,
            window: None,
            lens_radius,
            focal_distance,
        };
        Ok(())
    }

    pub(super) fn film(
        &mut self,
        ty: &str,
        params: &Params,
        file: u32,
        line: u32,
    ) -> Result<(), ParseError> {
        if ty == "gbuffer" {
            // pbrt-v4's gbuffer film: the image, and beside it what the camera sees first
            // (src/integrators/gbuffer.rs), in camera space unless asked otherwise.
            let space = match params.find("coordinatesystem") {
                None => crate::scene::GBufferSpace::Camera,
                Some(p) => match p.strs.first().map(String::as_str) {
                    Some("camera") => crate::scene::GBufferSpace::Camera,
                    Some("world") => crate::scene::GBufferSpace::World,
                    other => {
                        return Err(self.err_at(
                            p.file,
                            p.line,
                            "Film",
                            format!(
                                "coordinatesystem {:?} (expected \"camera\" or \"world\")",
                                other.unwrap_or("")
                            ),
                        ))
                    }
                },
            };
            self.scene.settings.gbuffer = Some(space);
        } else if ty != "rgb" {
            self.warn("film", format!("Film \"{ty}\" rendered as \"rgb\""));
        }
        let int = |name: &str, default: u32| -> Result<u32, ParseError> {
            match params.find(name) {
                Some(p) => {
                    let x = p.nums.first().copied().unwrap_or(0.0);
                    if !(1.0..=65536.0).contains(&x) {
                        return Err(self.err_at(
                            p.file,
                            p.line,
                            "Film",
                            format!("{name} must be between 1 and 65536, got {x}"),
                        ));
                    }
                    Ok(x as u32)
                }
                None => Ok(default),
            }
        };
        self.film_size = (int("xresolution", 1280)?, int("yresolution", 720)?);
        if let Some(p) = params.find("filename") {
            self.scene.output = p.strs.first().cloned();
        }
        let iso = params
            .find("iso")
            .and_then(|p| p.nums.first().copied())
            .unwrap_or(100.0);
        // (pbrt-v4's exposure time is the camera's shutter interval, 1 by default.)
        if !(iso > 0.0) {
            return Err(self.err_at(file, line, "Film", "iso must be positive"));
        }
        // Film "scale" (read by the pbrt-v4 of the published scenes, which multiplied the
        // image by it): folded into the imaging ratio like ISO, the same for linear light
        // transport.
        let scale = match params.find("scale") {
            None => 1.0,
            Some(p) => {
                let x = p.nums.first().copied().unwrap_or(f64::NAN);
                if !(x.is_finite() && x >= 0.0) {
                    return Err(self.err_at(
                        p.file,
                        p.line,
                        "Film",
                        format!("scale must be a finite number >= 0, got {x}"),
                    ));
                }
                x
            }
        };
        self.film_ratio = (iso / 100.0 * scale) as f32;
        // pbrt-v4's sensor and white balance: a colour matrix on the finished image.
        let sensor = params.find("sensor");
        let balance = params.find("whitebalance");
        let name = sensor
            .and_then(|p| p.strs.first().cloned())
            .unwrap_or_else(|| "cie1931".into());
        let kelvin = balance.and_then(|p| p.nums.first().copied()).unwrap_or(0.0);
        match crate::scene::sensor::output_from_render(&name, kelvin) {
            Ok(m) => self.scene.settings.output_from_render = m.as_mat3(),
            Err(e) => {
                let (file, line) = match (e.starts_with("whitebalance"), sensor, balance) {
                    (true, _, Some(p)) | (false, Some(p), _) => (p.file, p.line),
                    _ => (file, line),
                };
                return Err(self.err_at(file, line, "Film", e));
            }
        }
        // pixelbounds wins over cropwindow, as in pbrt-v4.
        let crop = params.find("cropwindow");
        self.crop = match (params.find("pixelbounds"), crop) {
            (Some(p), crop) => {
                if crop.is_some() {
                    self.warn(
                        "crop",
                        "Film: both pixelbounds and cropwindow; using pixelbounds".into(),
                    );
                }
                let b: Vec<i64> = p.nums.iter().map(|&x| x as i64).collect();
                if b.len() != 4 || b[0] < 0 || b[2] < 0 || b[1] <= b[0] || b[3] <= b[2] {
                    return Err(self.err_at(p.file, p.line, "Film", format!(
                        "pixelbounds must be 4 integers x0 x1 y0 y1 with 0 <= x0 < x1 and 0 <= y0 < y1, got {:?}", p.nums)));
                }
                Some((Crop::Pixels([b[0], b[1], b[2], b[3]]), p.file, p.line))
            }
            (None, Some(p)) => {
                let c: Vec<f32> = p.nums.iter().map(|&x| x as f32).collect();
                if c.len() != 4 || !c.iter().all(|x| (0.0..=1.0).contains(x)) {
                    return Err(self.err_at(
                        p.file,
                        p.line,
                        "Film",
                        format!(
                            "cropwindow must be 4 numbers x0 x1 y0 y1 between 0 and 1, got {:?}",
                            p.nums
                        ),
                    ));
                }
                let w = [
                    c[0].min(c[1]),
                    c[0].max(c[1]),
                    c[2].min(c[3]),
                    c[2].max(c[3]),
                ];
                Some((Crop::Window(w), p.file, p.line))
            }
            (None, None) => None,
        };
        params.find("savefp16");
        if let Some(p) = params.find("diagonal") {
            let x = p.nums.first().copied().unwrap_or(f64::NAN);
            if !(x.is_finite() && x > 0.0) {
                return Err(self.err_at(
                    p.file,
                    p.line,
                    "Film",
                    format!("diagonal must be positive, got {x}"),
                ));
            }
            self.film_diagonal = x as f32;
        }
        if let Some(p) = params.find("maxcomponentvalue") {
            if p.nums.first().is_some_and(|x| x.is_finite()) {
                self.warn(
                    "maxcomponentvalue",
                    "Film: maxcomponentvalue (pbrt-v4's clamp of each sample's brightest channel) is not applied: lightpath's estimates stay unbiased".into(),
                );
            }
        }
        self.check_used("Film", &format!("\"{ty}\""), params);
        Ok(())
    }

    /// The camera's film for pbrt's fov, screen window, frame aspect ratio and crop: the
    /// fov spans the shorter side of the frame (ours is vertical), the screen window
    /// defaults to [-frame, frame] × [-1, 1] (or [-1, 1] × [-1/frame, 1/frame] for a
    /// portrait frame) and is scaled by tan(fov / 2), and a crop renders the pixels
    /// pbrt-v4 would (ceil(resolution × crop), or pixelbounds) as an image of their size
    /// whose film is that part of the whole. Without a screen window, frame or crop the
    /// film is left to the image's aspect, so that `--size` keeps pbrt's rule.
    /// A realistic camera's lens system, for the film's size and diagonal; its
    /// equivalent pinhole's field of view stands in for texture footprints.
    pub(super) fn lens_system(&mut self) -> Result<(), ParseError> {
        let Some((rows, aperture, focus, file, line)) = self.realistic.take() else {
            return Ok(());
        };
        if self.crop.is_some() || self.screen_window.is_some() {
            return Err(self.err_at(file, line, "Camera", "a realistic camera renders the whole film: no cropwindow, pixelbounds or screenwindow"));
        }
        let (w, h) = self.film_size;
        let lens =
            crate::scene::lens::LensSystem::new(&rows, aperture, focus, self.film_diagonal, w, h)
                .map_err(|e| self.err_at(file, line, "Camera", e))?;
        self.scene.camera.fovy_degrees = lens.equivalent_fovy_degrees();
        self.scene.camera.window = None;
        self.scene.camera.lens_radius = 0.0;
        self.scene.lens = Some(std::sync::Arc::new(lens));
        Ok(())
    }

    pub(super) fn film_window(&mut self) -> Result<(), ParseError> {
        let (w, h) = self.film_size;
        let camera = &mut self.scene.camera;
        let aspect = w as f32 / h as f32;
        let t = (camera.fovy_degrees.to_radians() * 0.5).tan();
        if self.screen_window.is_none() && self.frame_aspect.is_none() && self.crop.is_none() {
            if w < h {
                camera.fovy_degrees = (2.0 * (t / aspect).atan()).to_degrees();
            }
            return Ok(());
        }
        let frame = self.frame_aspect.unwrap_or(aspect);
        let sw = self.screen_window.unwrap_or(if frame > 1.0 {
            [-frame, frame, -1.0, 1.0]
        } else {
            [-1.0, 1.0, -1.0 / frame, 1.0 / frame]
        });
        let window = sw.map(|x| x * t);
        let Some((crop, file, line)) = self.crop else {
            camera.window = Some(window);
            return Ok(());
        };
        let (x0, x1, y0, y1) = match crop {
            Crop::Window(c) => {
                let at = |f: f32, n: u32| (n as f32 * f).ceil() as i64;
                (at(c[0], w), at(c[1], w), at(c[2], h), at(c[3], h))
            }
            Crop::Pixels(b) => (
                b[0].min(w as i64),
                b[1].min(w as i64),
                b[2].min(h as i64),
                b[3].min(h as i64),
            ),
        };
        if x1 <= x0 || y1 <= y0 {
            return Err(self.err_at(
                file,
                line,
                "Film",
                format!(
                    "the crop of the {w} x {h} film holds no pixel (x {x0}..{x1}, y {y0}..{y1})"
                ),
            ));
        }
        // Pixel rows run down from the window's top (y1).
        let fx = |x: i64| window[0] + (window[1] - window[0]) * x as f32 / w as f32;
        let fy = |y: i64| window[3] - (window[3] - window[2]) * y as f32 / h as f32;
        self.scene.camera.window = Some([fx(x0), fx(x1), fy(y1), fy(y0)]);
        self.scene.width = (x1 - x0) as u32;
        self.scene.height = (y1 - y0) as u32;
        Ok(())
    }

    pub(super) fn integrator(
        &mut self,
        ty: &str,
        params: &Params,
        file: u32,
        line: u32,
    ) -> Result<(), ParseError> {
        self.mlt_mutations = None;
        self.scene.settings.integrator = match ty {
            "path" | "volpath" => IntegratorKind::PathTracer,
            "bdpt" => IntegratorKind::Bdpt,
            "mlt" => IntegratorKind::Mmlt,
            // pbrt-v4's other integrators of the same light transport converge to the same
            // image: its photon mapper and light tracer are rendered with BDPT (which has
            // their light-tracing strategies), its simpler path tracers with the path
            // tracer.
            "sppm" | "lightpath" | "simplepath" | "randomwalk" | "simplevolpath" => {
                let kind = if matches!(ty, "sppm" | "lightpath") {
                    IntegratorKind::Bdpt
                } else {
                    IntegratorKind::PathTracer
                };
                let name = if kind == IntegratorKind::Bdpt {
                    "bdpt"
                } else {
                    "path"
                };
                self.warn(
                    &format!("Integrator {ty}"),
                    format!(
                        "Integrator \"{ty}\" rendered as \"{name}\" (the same image, other noise)"
                    ),
                );
                kind
            }
            other => {
                self.unsupported(file, line, format!("Integrator \"{other}\""));
                return Ok(());
            }
        };
        if let Some(p) = params.find("maxdepth") {
            let n = p.nums.first().copied().unwrap_or(-2.0);
            if n < 0.0 {
                return Err(self.err_at(
                    p.file,
                    p.line,
                    "Integrator",
                    format!("maxdepth must not be negative, got {n}"),
                ));
            }
            self.scene.settings.max_depth = n as i32;
        }
        // (Each of pbrt-v4's integrators reads its own switches.)
        let switches: &[&str] = match ty {
            // (rrthreshold: the published scenes' earlier pbrt-v4 read it, a Russian
            // roulette threshold.)
            "path" | "volpath" => &["regularize", "lightsampler", "rrthreshold"],
            "bdpt" => &[
                "regularize",
                "visualizestrategies",
                "visualizeweights",
                "rrthreshold",
            ],
            "mlt" => &["regularize"],
            "sppm" => &["photonsperiteration", "radius", "seed"],
            "simplepath" => &["samplelights", "samplebsdf"],
            _ => &[],
        };
        for &name in switches {
            if let Some(p) = params.find(name) {
                let on = p.bools.first().copied().unwrap_or(true);
                if name == "lightsampler" || on {
                    let msg = format!("Integrator \"{name}\" ignored (it changes sampling only)");
                    self.warn(name, msg);
                }
            }
        }
        let m = &mut self.scene.settings.mmlt;
        if ty == "mlt" {
            if let Some(p) = params.find("bootstrapsamples") {
                m.bootstrap = p.nums.first().map(|&x| x.max(1.0) as u32);
            }
            if let Some(p) = params.find("chains") {
                m.chains = p.nums.first().map(|&x| x.max(1.0) as u32);
            }
            if let Some(p) = params.find("sigma") {
                m.sigma = p.nums.first().copied().unwrap_or(0.01) as f32;
            }
            if let Some(p) = params.find("largestepprobability") {
                m.large_step = p.nums.first().copied().unwrap_or(0.3) as f32;
            }
            // pbrt's MLT renders mutationsperpixel (100) and ignores the sampler's
            // pixelsamples, whichever comes first in the file.
            self.mlt_mutations = Some(
                params
                    .find("mutationsperpixel")
                    .and_then(|p| p.nums.first())
                    .map_or(100, |&x| x.max(1.0) as u32),
            );
        }
        self.check_used("Integrator", &format!("\"{ty}\""), params);
        Ok(())
    }

    /// The sensor's imaging ratio folded into every emitter: pbrt-v4's exposure time ×
    /// ISO / 100 (cie1931 sensor), times the film's `scale`.
    pub(super) fn imaging_ratio(&self) -> f32 {
        self.film_ratio * self.exposure
    }
}

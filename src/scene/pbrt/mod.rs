//! pbrt-v4 scene files (docs/scene-format.md, "pbrt-v4 scenes").
//!
//! The file is tokenized whole (`Include`d and `Import`ed files in turn) and its
//! directives executed in order on a graphics state as pbrt-v4's parser does: the current
//! transform, the material, the area light and reverse orientation, pushed and popped by
//! `AttributeBegin`/`AttributeEnd`. Shapes become world-space triangles and spheres of
//! the one scene model; object instances are flattened (each instance a copy).
//!
//! What lightpath cannot render and would change what is seen (media, other shapes,
//! materials or lights, unused parameters such as alpha cut-outs) is collected and
//! reported at once, every use with its file and line; what only changes reconstruction
//! or sampling (`PixelFilter`, the sampler's type) is one warning each.
//!
//! The reader follows pbrt-v4's own seams: `params` (tokens, parameter lists and the
//! values they give), this module (the directive state machine, includes and the
//! scene's final assembly), and one module of `create` functions per kind of thing:
//! `camera` (camera, film, sampler and integrator), `materials`, `textures`, `lights`
//! and `shapes`.

mod camera;
mod curves;
mod lights;
mod materials;
mod media;
mod params;
mod shapes;
#[cfg(test)]
mod tests;
mod textures;

use camera::*;
use lights::*;
use materials::*;
use params::*;
use shapes::*;

use super::parse::MaterialKey;
use super::spectrum;
use super::{
    BsdfKind, Camera, DeltaLight, Environment, EnvironmentMap, IntegratorKind, LightProfile,
    Material, MaterialMix, NextEventEstimation, ParseError, SampleMode, Scene, Sphere, Texture,
    Triangle, MAX_MIX_DEPTH,
};
use crate::texture::{
    load_image, load_texture, Encoding, EnvMapping, Filter, Projection, TextureImage, Wrap,
};
use glam::{Mat3, Mat4, Vec2, Vec3, Vec4};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The most files `Include` and `Import` may read (a file including itself stops here).
const MAX_FILES: usize = 4096;

/// Triangles a scene may hold: as many 48-byte device triangles (abi.h GpuTriangle) as the
/// largest storage-buffer range a Vulkan device can state (a 32-bit byte count). The
/// device's own range, often smaller (lavapipe: 128 MiB), is checked before the BVH build.
pub const MAX_SCENE_TRIANGLES: usize = (u32::MAX / 48) as usize;
/// The deepest `AttributeBegin` nesting.
const MAX_ATTRIBUTE_NESTING: usize = 1 << 16;

#[derive(Clone, Debug)]
struct GraphicsState {
    ctm: Mat4,
    /// `ActiveTransform`: whether transform directives change the shutter-open transform,
    /// the one lightpath renders at (false after `ActiveTransform EndTime`: they change
    /// only the shutter-close one, which motion blur alone would use).
    start_active: bool,
    reverse: bool,
    material: MaterialRef,
    /// A `NamedMaterial` of a name no `MakeNamedMaterial` has given yet (and where): the
    /// shapes that follow wait for the end of the file, where pbrt-v4 looks the names up
    /// (the collection's contemporary bathroom names its materials before it includes
    /// them); still undefined there, an error (the watercolor names a material it has
    /// commented out, for no shape: no error).
    undefined_material: Option<(String, u32, u32)>,
    area: Option<AreaLight>,
    /// `Attribute` defaults: (target, parameter), the latest of a name first.
    attributes: Vec<(String, Param)>,
    /// `MediumInterface`: the media (indices into `Scene::media`, `None` vacuum) inside
    /// and outside the shapes that follow; the outside one is the camera's.
    media: (Option<u32>, Option<u32>),
}

/// A `MakeNamedMaterial`: pbrt-v4 makes its materials once the whole scene is read, so a
/// named material may name a texture defined after it (the collection's watercolor
/// does); lightpath makes it where it is first used, or at the end.
enum NamedMaterial {
    Made(MaterialRef),
    /// Its type and parameters, and where it was declared.
    Pending(String, Params, u32, u32),
}

struct Parser {
    scene: Scene,
    files: Vec<String>,
    tokens: Vec<Token>,
    pos: usize,
    /// The directory of each file read, the top file's first (`resolve`).
    dirs: Vec<PathBuf>,
    gs: GraphicsState,
    stack: Vec<(GraphicsState, bool)>,
    named_coords: HashMap<String, Mat4>,
    named_materials: HashMap<String, NamedMaterial>,
    /// `MakeNamedMedium`'s names: index into `Scene::media` + 1 (0: a refused medium).
    named_media: HashMap<String, u32>,
    textures: HashMap<String, Value>,
    float_textures: HashMap<String, Value>,
    material_lookup: HashMap<MaterialKey, u32>,
    /// Image textures' files by name: the image, or the placeholder of one not read yet.
    image_textures: HashMap<(PathBuf, Encoding), Arc<TextureImage>>,
    /// The image files named and not read yet, in the order named (`read_images`).
    pending_images: Vec<PendingImage>,
    /// Measured materials' files read so far: their index in `Scene::measured`.
    measured_files: HashMap<PathBuf, u32>,
    /// The objects defined (ObjectBegin .. ObjectEnd): their shapes and where each was
    /// defined ("file:line").
    objects: HashMap<String, (Vec<ShapeDecl>, String)>,
    /// The object being defined (ObjectBegin .. ObjectEnd).
    defining: Option<(String, Vec<ShapeDecl>, String)>,
    /// The objects made so far, by name: the index in `Scene::objects` (None: it keeps no
    /// triangles).
    object_ids: HashMap<String, Option<u32>>,
    /// The triangles of `Scene::objects`, all told.
    object_triangles: usize,
    /// Shapes whose named material was not defined when they were read, with the name,
    /// the `NamedMaterial`'s file and line and the shape's: made at the end of the file.
    deferred: Vec<(ShapeDecl, String, (u32, u32), (u32, u32))>,
    /// While a shape of an undefined named material is read: its `deferred` entry's name
    /// and places.
    deferring: Option<(String, (u32, u32), (u32, u32))>,
    /// Everything unsupported, as "file:line: what", reported together at the end.
    unsupported: Vec<String>,
    warned: std::collections::HashSet<String>,
    warnings: Vec<String>,
    camera_seen: bool,
    /// `Integrator "mlt"`'s mutations per pixel (they become the samples per pixel).
    mlt_mutations: Option<u32>,
    film_size: (u32, u32),
    /// The camera's `screenwindow` and `frameaspectratio`, applied with the film's size.
    screen_window: Option<[f32; 4]>,
    frame_aspect: Option<f32>,
    /// A realistic camera's lens file rows, stop diameter (mm) and focus distance, and
    /// where it was declared: the lens system is built once the film is known.
    realistic: Option<(Vec<[f32; 4]>, f32, f32, u32, u32)>,
    /// The film's diagonal (mm; pbrt-v4's `diagonal`, for a realistic camera).
    film_diagonal: f32,
    /// The film's `cropwindow` or `pixelbounds`, with the file and line that gave it.
    crop: Option<(Crop, u32, u32)>,
    /// The film's share of the imaging ratio: ISO / 100 times the film's `scale`.
    film_ratio: f32,
    /// pbrt-v4's exposure time: the camera's shutterclose − shutteropen (1 by default).
    exposure: f32,
    in_world: bool,
}

/// An image texture's file named and not read yet (`Parser::read_images`): where it was
/// named, and the placeholder the textures hold until it is read.
struct PendingImage {
    placeholder: Arc<TextureImage>,
    path: PathBuf,
    encoding: Encoding,
    file: u32,
    line: u32,
    command: String,
    what: &'static str,
}

/// Reads and parses a pbrt-v4 scene file.
///
/// # Errors
/// When a file cannot be read, does not parse, or uses what lightpath cannot render
/// (every such use listed in the message).
pub fn parse_pbrt_file(path: &Path) -> Result<Scene, ParseError> {
    let (name, text, dir) = super::parse::read_scene_file(path)?;
    let mut scene = parse_pbrt_text(&text, &name, dir)?;
    scene.source = Some(path.to_path_buf());
    Ok(scene)
}

/// Parses pbrt-v4 text; `name` stands for its file name, and files it names are read
/// relative to the working directory.
pub fn parse_pbrt_str(text: &str, name: &str) -> Result<Scene, ParseError> {
    parse_pbrt_text(text, name, PathBuf::new())
}

fn parse_pbrt_text(text: &str, name: &str, dir: PathBuf) -> Result<Scene, ParseError> {
    let tokens = tokenize(text, 0, name)?;
    let mut p = Parser {
        scene: Scene::default(),
        files: vec![name.to_owned()],
        tokens,
        pos: 0,
        dirs: vec![dir],
        gs: GraphicsState {
            ctm: Mat4::IDENTITY,
            start_active: true,
            reverse: false,
            material: MaterialRef::Material(diffuse(Vec3::splat(0.5))),
            undefined_material: None,
            area: None,
            attributes: Vec::new(),
            media: (None, None),
        },
        stack: Vec::new(),
        named_coords: HashMap::new(),
        named_materials: HashMap::new(),
        named_media: HashMap::new(),
        textures: HashMap::new(),
        float_textures: HashMap::new(),
        material_lookup: HashMap::new(),
        image_textures: HashMap::new(),
        pending_images: Vec::new(),
        measured_files: HashMap::new(),
        objects: HashMap::new(),
        defining: None,
        object_ids: HashMap::new(),
        object_triangles: 0,
        deferred: Vec::new(),
        deferring: None,
        unsupported: Vec::new(),
        warned: Default::default(),
        warnings: Vec::new(),
        camera_seen: false,
        mlt_mutations: None,
        film_size: (1280, 720),
        screen_window: None,
        frame_aspect: None,
        realistic: None,
        film_diagonal: 35.0,
        crop: None,
        film_ratio: 1.0,
        exposure: 1.0,
        in_world: false,
    };
    // pbrt-v4's defaults: a volumetric path tracer of depth 5, 16 samples per pixel.
    let s = &mut p.scene.settings;
    s.integrator = IntegratorKind::PathTracer;
    s.spp = 16;
    s.max_depth = 5;
    s.nee = NextEventEstimation::Mis;
    s.russian_roulette = true;
    s.importance_sampling = SampleMode::Brdf;
    // (pbrt-v4 writes 8-bit images sRGB-encoded: a PNG output gets gamma 2.2.)
    s.gamma = 2.2;
    p.run()?;
    p.finish()
}

impl Parser {
    /// An error before `adding` more triangles would take the scene past
    /// [`MAX_SCENE_TRIANGLES`] (each instance of an object copies its triangles).
    fn check_triangles(
        &self,
        adding: usize,
        file: u32,
        line: u32,
        command: &str,
    ) -> Result<(), ParseError> {
        let total = self.scene.triangles.len() + self.object_triangles + adding;
        if total <= MAX_SCENE_TRIANGLES {
            return Ok(());
        }
        Err(self.err_at(
            file,
            line,
            command,
            format!(
                "this makes the scene {total} triangles, more than the {MAX_SCENE_TRIANGLES} \
                 that one device buffer of 48-byte triangles can hold on any Vulkan device \
                 (4 GiB); an object's triangles count once, but its spheres and alpha-cut \
                 shapes once per instance"
            ),
        ))
    }

    /// An `ObjectInstance` of the defined object `name` under `ctm`. Its triangle meshes
    /// are the object's, made once at its first instance (in the space of the object's
    /// definition) and drawn through each instance's transform (`Scene::instances`); its
    /// spheres and alpha-cut meshes are copied into the world at each instance (an alpha
    /// test hashes world-space rays), and so is everything under a singular transform
    /// (which has no inverse to carry rays into the object).
    fn instance(
        &mut self,
        name: String,
        ctm: Mat4,
        file: u32,
        line: u32,
        d: &str,
    ) -> Result<(), ParseError> {
        let det = Mat3::from_mat4(ctm).determinant();
        let invertible = det != 0.0 && det.is_finite();
        let kept = |s: &ShapeDecl| {
            invertible && matches!(s.kind, ShapeKind::Mesh { .. }) && s.alpha.is_none()
        };
        let shapes = &self.objects[&name].0;
        let copied: Vec<ShapeDecl> = shapes.iter().filter(|s| !kept(s)).cloned().collect();
        let adding = copied.iter().map(|s| s.triangles()).sum();
        self.check_triangles(adding, file, line, d)?;
        for mut s in copied {
            s.ctm = ctm * s.ctm;
            self.emit(s)?;
        }
        if !invertible {
            return Ok(());
        }
        let object = match self.object_ids.get(&name) {
            Some(&o) => o,
            None => {
                let shapes: Vec<ShapeDecl> = self.objects[&name]
                    .0
                    .iter()
                    .filter(|s| kept(s))
                    .cloned()
                    .collect();
                let adding = shapes.iter().map(|s| s.triangles()).sum();
                self.check_triangles(adding, file, line, d)?;
                // The object's triangles: its shapes emitted as they were defined.
                let world = std::mem::take(&mut self.scene.triangles);
                let mut emitted = Ok(());
                for s in shapes {
                    emitted = self.emit(s);
                    if emitted.is_err() {
                        break;
                    }
                }
                let triangles = std::mem::replace(&mut self.scene.triangles, world);
                emitted?;
                self.object_triangles += triangles.len();
                let o = (!triangles.is_empty()).then(|| {
                    self.scene.objects.push(crate::scene::Object {
                        name: name.clone(),
                        triangles,
                    });
                    self.scene.objects.len() as u32 - 1
                });
                self.object_ids.insert(name, o);
                o
            }
        };
        if let Some(object) = object {
            self.scene.instances.push(crate::scene::Instance {
                object,
                object_to_world: ctm,
            });
        }
        Ok(())
    }

    /// The image file `path` as a texture's texels: the image where it was read before,
    /// else a placeholder that `read_images` replaces, with the others named, on every
    /// core. `what` begins the error's message where the file cannot be read.
    fn image_texture(
        &mut self,
        path: PathBuf,
        encoding: Encoding,
        (file, line, command): (u32, u32, &str),
        what: &'static str,
    ) -> Arc<TextureImage> {
        let key = (path, encoding);
        if let Some(image) = self.image_textures.get(&key) {
            return image.clone();
        }
        let placeholder = Arc::new(TextureImage::Float(crate::io::Image {
            width: 0,
            height: 0,
            pixels: Vec::new(),
        }));
        self.pending_images.push(PendingImage {
            placeholder: placeholder.clone(),
            path: key.0.clone(),
            encoding,
            file,
            line,
            command: command.to_owned(),
            what,
        });
        self.image_textures.insert(key, placeholder.clone());
        placeholder
    }

    /// Reads the image files named and not read yet, on every core, and puts each image in
    /// place of its placeholder (in every texture that holds it: a scaled copy of a
    /// texture too). The first file that cannot be read, in the order named, is the
    /// error, at the line that named it. At the end of the parse, and before a texture's
    /// value is needed (displacement, `invert`).
    fn read_images(&mut self) -> Result<(), ParseError> {
        if self.pending_images.is_empty() {
            return Ok(());
        }
        let mut pending = std::mem::take(&mut self.pending_images);
        let read = crate::accel::map_in_parallel(&mut pending, crate::accel::threads(), |p| {
            load_texture(&p.path, p.encoding)
        });
        let mut images = HashMap::new();
        for (p, r) in pending.iter().zip(read) {
            let image =
                Arc::new(r.map_err(|e| {
                    self.err_at(p.file, p.line, &p.command, format!("{}{e}", p.what))
                })?);
            self.image_textures
                .insert((p.path.clone(), p.encoding), image.clone());
            images.insert(Arc::as_ptr(&p.placeholder), image);
        }
        for t in &mut self.scene.textures {
            t.for_each_image_mut(&mut |image| {
                if let Some(read) = images.get(&Arc::as_ptr(image)) {
                    *image = read.clone();
                }
            });
        }
        Ok(())
    }

    fn err_at(
        &self,
        file: u32,
        line: u32,
        command: &str,
        message: impl Into<String>,
    ) -> ParseError {
        ParseError {
            file: self.files[file as usize].clone(),
            line: line as usize,
            command: command.to_owned(),
            message: message.into(),
        }
    }

    /// `params` with the `Attribute` defaults of `target` that it does not set itself.
    /// (Defaults a directive does not read are not reported: they apply to many kinds.)
    fn with_attributes(&self, target: &str, mut params: Params) -> Params {
        for (t, p) in &self.gs.attributes {
            if t == target && !params.0.iter().any(|q| q.name == p.name) {
                let p = p.clone();
                p.used.set(true);
                params.0.push(p);
            }
        }
        params
    }

    fn unsupported(&mut self, file: u32, line: u32, what: impl Into<String>) {
        let what = what.into();
        self.unsupported
            .push(format!("{}:{line}: {what}", self.files[file as usize]));
    }

    fn warn(&mut self, key: &str, message: String) {
        if self.warned.insert(key.to_owned()) {
            self.warnings.push(message);
        }
    }

    /// Reports every parameter the directive did not read as unsupported.
    fn check_used(&mut self, directive: &str, what: &str, params: &Params) {
        #[cfg(test)]
        ASKED.with(|a| {
            NAMES_READ.with(|r| {
                for name in a.borrow_mut().drain(..) {
                    r.borrow_mut().insert((
                        directive.to_owned(),
                        what.trim_matches('"').to_owned(),
                        name,
                    ));
                }
            })
        });
        for p in &params.0 {
            if !p.used.get() {
                let msg = format!(
                    "{directive} {what}: parameter \"{} {}\" is not supported",
                    p.ty, p.name
                );
                self.unsupported(p.file, p.line, msg);
            }
        }
    }

    fn run(&mut self) -> Result<(), ParseError> {
        while let Some(t) = self.next_token() {
            let (file, line) = (t.file, t.line);
            let Tok::Word(d) = t.tok else {
                return Err(self.err_at(
                    file,
                    line,
                    "",
                    format!("expected a directive, got {}", describe(&t.tok)),
                ));
            };
            self.directive(&d, file, line)?;
        }
        if !self.stack.is_empty() {
            let (f, l) = self.here();
            return Err(self.err_at(
                f,
                l,
                "AttributeBegin",
                format!(
                    "{} AttributeBegin without AttributeEnd at the end of the file",
                    self.stack.len()
                ),
            ));
        }
        if self.defining.is_some() {
            let (f, l) = self.here();
            return Err(self.err_at(
                f,
                l,
                "ObjectBegin",
                "ObjectBegin without ObjectEnd at the end of the file",
            ));
        }
        Ok(())
    }

    fn directive(&mut self, d: &str, file: u32, line: u32) -> Result<(), ParseError> {
        #[cfg(test)]
        ASKED.with(|a| a.borrow_mut().clear());
        let ctm = self.gs.ctm;
        let transform = matches!(
            d,
            "Identity"
                | "Translate"
                | "Scale"
                | "Rotate"
                | "LookAt"
                | "Transform"
                | "ConcatTransform"
                | "CoordSysTransform"
        );
        match d {
            "Identity" => self.gs.ctm = Mat4::IDENTITY,
            "Translate" => {
                let v = self.numbers(d, 3)?;
                self.gs.ctm = ctm * Mat4::from_translation(Vec3::new(v[0], v[1], v[2]));
            }
            "Scale" => {
                let v = self.numbers(d, 3)?;
                self.gs.ctm = ctm * Mat4::from_scale(Vec3::new(v[0], v[1], v[2]));
            }
            "Rotate" => {
                let v = self.numbers(d, 4)?;
                let axis = Vec3::new(v[1], v[2], v[3]);
                if axis.length_squared() == 0.0 {
                    return Err(self.err_at(file, line, d, "the rotation axis is zero"));
                }
                self.gs.ctm = ctm * Mat4::from_axis_angle(axis.normalize(), v[0].to_radians());
            }
            "LookAt" => {
                let v = self.numbers(d, 9)?;
                let eye = Vec3::new(v[0], v[1], v[2]);
                let look = Vec3::new(v[3], v[4], v[5]);
                let up = Vec3::new(v[6], v[7], v[8]);
                let dir = look - eye;
                if dir.length_squared() == 0.0
                    || up
                        .normalize_or_zero()
                        .cross(dir.normalize())
                        .length_squared()
                        == 0.0
                {
                    return Err(self.err_at(
                        file,
                        line,
                        d,
                        "the eye and the target coincide, or up is parallel to the view direction",
                    ));
                }
                // pbrt's LookAt: camera space x = up × dir, y = dir × x, z = dir.
                let dir = dir.normalize();
                let right = up.normalize().cross(dir).normalize();
                let new_up = dir.cross(right);
                let world_from_camera = Mat4::from_cols(
                    right.extend(0.0),
                    new_up.extend(0.0),
                    dir.extend(0.0),
                    eye.extend(1.0),
                );
                self.gs.ctm = ctm * world_from_camera.inverse();
            }
            "Transform" | "ConcatTransform" => {
                let v = self.numbers(d, 16)?;
                let m = Mat4::from_cols_array(&v.try_into().expect("16 numbers"));
                self.gs.ctm = if d == "Transform" { m } else { ctm * m };
            }
            "CoordinateSystem" => {
                let name = self.expect_string(d, "a name")?;
                self.named_coords.insert(name, ctm);
            }
            "CoordSysTransform" => {
                let name = self.expect_string(d, "a name")?;
                match self.named_coords.get(&name) {
                    Some(m) => self.gs.ctm = *m,
                    None => {
                        return Err(self.err_at(
                            file,
                            line,
                            d,
                            format!("no coordinate system named \"{name}\""),
                        ))
                    }
                }
            }
            "ReverseOrientation" => self.gs.reverse = !self.gs.reverse,
            "AttributeBegin" | "TransformBegin" => {
                if self.stack.len() >= MAX_ATTRIBUTE_NESTING {
                    return Err(self.err_at(file, line, d, "attributes nested too deeply"));
                }
                self.stack.push((self.gs.clone(), d == "TransformBegin"));
            }
            "AttributeEnd" | "TransformEnd" => match self.stack.pop() {
                Some((gs, transform_only)) => {
                    if transform_only != (d == "TransformEnd") {
                        return Err(self.err_at(
                            file,
                            line,
                            d,
                            "does not match the Begin it closes",
                        ));
                    }
                    if transform_only {
                        self.gs.ctm = gs.ctm;
                    } else {
                        self.gs = gs;
                    }
                }
                None => return Err(self.err_at(file, line, d, "without a matching Begin")),
            },
            "Attribute" => {
                let target = self.expect_string(d, "a target")?;
                let params = self.params(d)?;
                match target.as_str() {
                    "shape" | "light" | "material" | "texture" => {
                        for p in params.0.into_iter().rev() {
                            self.gs.attributes.insert(0, (target.clone(), p));
                        }
                    }
                    "medium" => {
                        if !params.0.is_empty() {
                            self.unsupported(file, line, "Attribute \"medium\" (participating media)");
                        }
                    }
                    other => {
                        return Err(self.err_at(
                            file,
                            line,
                            d,
                            format!(
                                "unknown target \"{other}\" (expected shape, light, material, medium or texture)"
                            ),
                        ))
                    }
                }
            }
            "Include" | "Import" => {
                let name = self.expect_string(d, "a file name")?;
                self.include(&name, file, line, d)?;
            }
            "Option" => {
                let params = self.params(d)?;
                for p in &params.0 {
                    let msg = format!("Option \"{}\" ignored", p.name);
                    self.warn(&format!("option {}", p.name), msg);
                }
            }
            "ColorSpace" => {
                let name = self.expect_string(d, "a colour space")?;
                if name != "srgb" {
                    self.unsupported(
                        file,
                        line,
                        format!("ColorSpace \"{name}\" (RGB values are read as linear sRGB)"),
                    );
                }
            }
            "Camera" => {
                let ty = self.expect_string(d, "a camera type")?;
                let params = self.params(d)?;
                if ty != "perspective" && ty != "realistic" {
                    self.unsupported(file, line, format!("Camera \"{ty}\""));
                }
                self.named_coords.insert("camera".into(), ctm.inverse());
                self.camera_seen = true;
                // pbrt-v4's camera is in the current outside medium.
                self.scene.camera_medium = self.gs.media.1;
                self.camera(&ty, ctm, &params, file, line)?;
            }
            "Film" => {
                let ty = self.expect_string(d, "a film type")?;
                let params = self.params(d)?;
                self.film(&ty, &params, file, line)?;
            }
            "Sampler" => {
                let ty = self.expect_string(d, "a sampler type")?;
                let params = self.params(d)?;
                if let Some(p) = params.find("pixelsamples") {
                    let n = p.nums.first().copied().unwrap_or(0.0);
                    if n < 1.0 {
                        return Err(self.err_at(
                            p.file,
                            p.line,
                            d,
                            format!("pixelsamples must be at least 1, got {n}"),
                        ));
                    }
                    self.scene.settings.spp = n as u32;
                }
                if ty != "independent" {
                    self.warn("sampler", format!("Sampler \"{ty}\": lightpath samples independently (only the sampling pattern differs)"));
                }
                for p in &params.0 {
                    p.used.set(true);
                }
            }
            "PixelFilter" => {
                let ty = self.expect_string(d, "a filter type")?;
                self.params(d)?;
                self.warn("filter", format!("PixelFilter \"{ty}\" ignored: lightpath averages over each pixel's square (a box filter)"));
            }
            "Integrator" => {
                let ty = self.expect_string(d, "an integrator type")?;
                let params = self.params(d)?;
                self.integrator(&ty, &params, file, line)?;
            }
            "Accelerator" => {
                self.expect_string(d, "an accelerator type")?;
                self.params(d)?;
            }
            "WorldBegin" => {
                self.in_world = true;
                self.gs.ctm = Mat4::IDENTITY;
                self.named_coords.insert("world".into(), Mat4::IDENTITY);
            }
            "WorldEnd" => {}
            "MakeNamedMedium" => {
                let name = self.expect_string(d, "a name")?;
                let params = self.params(d)?;
                self.named_medium(name, &params, file, line)?;
            }
            "MediumInterface" => {
                let inside = self.expect_string(d, "a medium name")?;
                let mut outside = inside.clone();
                if let Some(Token {
                    tok: Tok::Str(s), ..
                }) = self.peek().cloned()
                {
                    self.pos += 1;
                    outside = s;
                }
                self.gs.media = (
                    self.medium_named(&inside, file, line, d)?,
                    self.medium_named(&outside, file, line, d)?,
                );
            }
            "Material" => {
                let ty = self.expect_string(d, "a material type")?;
                let params = self.params(d)?;
                let params = self.with_attributes("material", params);
                self.gs.material = self.material(&ty, &params, file, line)?;
                self.gs.undefined_material = None;
            }
            "MakeNamedMaterial" => {
                let name = self.expect_string(d, "a name")?;
                let params = self.params(d)?;
                let params = self.with_attributes("material", params);
                let ty = match params.find("type") {
                    Some(p) if p.ty == "string" && p.strs.len() == 1 => p.strs[0].clone(),
                    _ => {
                        return Err(self.err_at(
                            file,
                            line,
                            d,
                            format!("material \"{name}\": no \"string type\""),
                        ))
                    }
                };
                self.named_materials
                    .insert(name, NamedMaterial::Pending(ty, params, file, line));
            }
            "NamedMaterial" => {
                let name = self.expect_string(d, "a name")?;
                match self.named_material(&name)? {
                    Some(m) => {
                        self.gs.material = m;
                        self.gs.undefined_material = None;
                    }
                    None => self.gs.undefined_material = Some((name, file, line)),
                }
            }
            "Texture" => {
                let name = self.expect_string(d, "a name")?;
                let ty = self.expect_string(d, "a texture type (\"spectrum\" or \"float\")")?;
                let class = self.expect_string(d, "a texture class")?;
                let params = self.params(d)?;
                let params = self.with_attributes("texture", params);
                self.texture(&name, &ty, &class, &params, file, line)?;
            }
            "LightSource" => {
                let ty = self.expect_string(d, "a light type")?;
                let params = self.params(d)?;
                let params = self.with_attributes("light", params);
                self.light(&ty, &params, file, line)?;
                // pbrt-v4's lights are in the outside medium current where they are made.
                self.scene.place_new_delta_lights(self.gs.media.1);
            }
            "AreaLightSource" => {
                let ty = self.expect_string(d, "an area light type")?;
                let params = self.params(d)?;
                let params = self.with_attributes("light", params);
                self.area_light(&ty, &params, file, line)?;
            }
            "Shape" => {
                let ty = self.expect_string(d, "a shape type")?;
                let params = self.params(d)?;
                let params = self.with_attributes("shape", params);
                if let Some((name, f, l)) = self.gs.undefined_material.clone() {
                    // Inside an object's definition the shape is kept now: no waiting.
                    if self.defining.is_some() {
                        return Err(self.undefined_material_error(&name, (f, l), (file, line)));
                    }
                    self.deferring = Some((name, (f, l), (file, line)));
                }
                let read = self.shape(&ty, &params, file, line);
                self.deferring = None;
                read?;
            }
            "ObjectBegin" => {
                let name = self.expect_string(d, "a name")?;
                if self.defining.is_some() {
                    return Err(self.err_at(
                        file,
                        line,
                        d,
                        "ObjectBegin inside another object's definition",
                    ));
                }
                // As pbrt-v4: an object's name is defined once.
                if let Some((_, at)) = self.objects.get(&name) {
                    return Err(self.err_at(
                        file,
                        line,
                        d,
                        format!("object \"{name}\" is already defined (at {at})"),
                    ));
                }
                let at = format!("{}:{line}", self.files[file as usize]);
                self.stack.push((self.gs.clone(), false));
                self.defining = Some((name, Vec::new(), at));
            }
            "ObjectEnd" => {
                let Some((name, shapes, at)) = self.defining.take() else {
                    return Err(self.err_at(file, line, d, "ObjectEnd without ObjectBegin"));
                };
                self.objects.insert(name, (shapes, at));
                match self.stack.pop() {
                    Some((gs, _)) => self.gs = gs,
                    None => {
                        return Err(self.err_at(file, line, d, "without a matching ObjectBegin"))
                    }
                }
            }
            "ObjectInstance" => {
                let name = self.expect_string(d, "a name")?;
                // No instance inside an object's definition (as pbrt-v4: no nested
                // instances), least of all of itself.
                if let Some((defining, _, at)) = &self.defining {
                    let message = if *defining == name {
                        format!(
                            "object \"{name}\" instances itself (its definition begins at {at})"
                        )
                    } else {
                        format!(
                            "an instance inside the definition of object \"{defining}\" (begun at {at}): objects do not nest, as in pbrt-v4"
                        )
                    };
                    return Err(self.err_at(file, line, d, message));
                }
                if !self.objects.contains_key(&name) {
                    return Err(self.err_at(
                        file,
                        line,
                        d,
                        format!("no object named \"{name}\" is defined before this"),
                    ));
                }
                self.instance(name, ctm, file, line, d)?;
            }
            "TransformTimes" | "ActiveTransform" => {
                if d == "TransformTimes" {
                    self.numbers(d, 2)?;
                } else {
                    match self.next_token() {
                        Some(Token {
                            tok: Tok::Word(w), ..
                        }) if w == "All" || w == "StartTime" || w == "EndTime" => {
                            self.gs.start_active = w != "EndTime";
                        }
                        _ => {
                            return Err(self.err_at(
                                file,
                                line,
                                d,
                                "expected All, StartTime or EndTime",
                            ))
                        }
                    }
                }
            }
            other => {
                return Err(self.err_at(file, line, other, format!("unknown directive '{other}'")));
            }
        }
        // Motion blur is not rendered: a transform of the shutter-close time alone leaves
        // the shutter-open transform, the one rendered, as it was.
        if transform && !self.gs.start_active {
            self.gs.ctm = ctm;
            self.warn(
                "motion",
                format!(
                    "{}:{line}: an animated transform (ActiveTransform EndTime): rendered at the shutter-open transform, without motion blur",
                    self.files[file as usize]
                ),
            );
        }
        Ok(())
    }

    /// A file named in file `file`: as pbrt-v4 resolves it, a relative path is relative
    /// to the top file's directory (its search directory), whichever file names it;
    /// where nothing is there but something is beside the naming file, that (what
    /// lightpath read before it followed pbrt-v4 here, 2026-12-06).
    fn resolve(&self, file: u32, name: &str) -> PathBuf {
        let pbrt = self.dirs[0].join(name);
        if file == 0 || pbrt.exists() {
            return pbrt;
        }
        let beside = self.dirs[file as usize].join(name);
        if beside.exists() {
            beside
        } else {
            pbrt
        }
    }

    /// `Include` and `Import` (which lightpath reads alike): the file's tokens in place of
    /// the directive. A name ending in `.gz` is a gzip-compressed file, as pbrt-v4 reads it.
    fn include(&mut self, name: &str, file: u32, line: u32, d: &str) -> Result<(), ParseError> {
        if self.dirs.len() >= MAX_FILES {
            return Err(self.err_at(
                file,
                line,
                d,
                format!("more than {MAX_FILES} files included (does a file include itself?)"),
            ));
        }
        let path = self.resolve(file, name);
        let text = read_scene_text(&path).map_err(|e| {
            self.err_at(
                file,
                line,
                d,
                format!("cannot read {}: {e}", path.display()),
            )
        })?;
        let index = self.files.len() as u32;
        let shown = path.display().to_string();
        self.files.push(shown.clone());
        self.dirs
            .push(path.parent().map(Path::to_path_buf).unwrap_or_default());
        let tokens = tokenize(&text, index, &shown)?;
        // Splice the file's tokens in where the directive stood.
        let rest = self.tokens.split_off(self.pos);
        self.tokens.extend(tokens);
        self.tokens.extend(rest);
        Ok(())
    }

    /// The material named `name`, made now if it is not yet (its errors at its
    /// MakeNamedMaterial); None if there is none (or it is being made: a mix of itself).
    fn named_material(&mut self, name: &str) -> Result<Option<MaterialRef>, ParseError> {
        let m = match self.named_materials.remove(name) {
            None => return Ok(None),
            Some(NamedMaterial::Made(m)) => m,
            Some(NamedMaterial::Pending(ty, params, file, line)) => {
                // (Tests: the names the directive being read asked for so far are its
                // own, not this material's.)
                #[cfg(test)]
                let asked = ASKED.with(|a| std::mem::take(&mut *a.borrow_mut()));
                let m = self.material(&ty, &params, file, line);
                #[cfg(test)]
                ASKED.with(|a| *a.borrow_mut() = asked);
                m?
            }
        };
        self.named_materials
            .insert(name.to_owned(), NamedMaterial::Made(m.clone()));
        Ok(Some(m))
    }

    /// No material of `name`, named at `named` (file, line) for the shape at `shape`.
    fn undefined_material_error(
        &self,
        name: &str,
        named: (u32, u32),
        shape: (u32, u32),
    ) -> ParseError {
        let at = format!("{}:{}", self.files[shape.0 as usize], shape.1);
        self.err_at(
            named.0,
            named.1,
            "NamedMaterial",
            format!("no material named \"{name}\" (the shape at {at} uses it)"),
        )
    }

    fn finish(mut self) -> Result<Scene, ParseError> {
        self.read_images()?;
        for t in &mut self.scene.textures {
            t.for_each_image_mut(&mut |image| {
                debug_assert_ne!(
                    crate::texture::Texels::size(&**image),
                    (0, 0),
                    "an image not read"
                )
            });
        }
        // The shapes that waited for their named material, in the order they were read.
        for (mut decl, name, named, shape) in std::mem::take(&mut self.deferred) {
            let Some(material) = self.named_material(&name)? else {
                return Err(self.undefined_material_error(&name, named, shape));
            };
            decl.material = material;
            self.check_triangles(decl.triangles(), shape.0, shape.1, "Shape")?;
            self.emit(decl)?;
        }
        // (Named materials no shape used are made too, for their errors.)
        let mut pending: Vec<(u32, u32, String)> = self
            .named_materials
            .iter()
            .filter_map(|(n, m)| match m {
                NamedMaterial::Pending(_, _, file, line) => Some((*file, *line, n.clone())),
                NamedMaterial::Made(_) => None,
            })
            .collect();
        pending.sort();
        for (_, _, name) in pending {
            self.named_material(&name)?;
        }
        if !self.unsupported.is_empty() {
            let first = &self.unsupported[0];
            let (file, line) = first
                .split_once(": ")
                .and_then(|(loc, _)| loc.rsplit_once(':'))
                .map(|(f, l)| (f.to_owned(), l.parse().unwrap_or(0)))
                .unwrap_or_default();
            return Err(ParseError {
                file,
                line,
                command: "unsupported".into(),
                message: format!(
                    "lightpath cannot render {} feature use(s) of this scene:\n  {}",
                    self.unsupported.len(),
                    self.unsupported.join("\n  ")
                ),
            });
        }
        for w in &self.warnings {
            eprintln!("warning: {w}");
        }
        if let Some(n) = self.mlt_mutations {
            self.scene.settings.spp = n;
        }
        let (w, h) = self.film_size;
        self.scene.width = w;
        self.scene.height = h;
        if !self.camera_seen {
            // pbrt's default camera: at the origin looking down +z, fov 90.
            self.scene.camera = Camera {
                eye: Vec3::ZERO,
                look_at: Vec3::Z,
                up: Vec3::Y,
                fovy_degrees: 90.0,
                ..Camera::default()
            };
        }
        self.film_window()?;
        self.lens_system()?;
        let ratio = self.imaging_ratio();
        for l in &mut self.scene.delta_lights {
            match l {
                DeltaLight::Point { intensity, .. }
                | DeltaLight::Spot { intensity, .. }
                | DeltaLight::Goniometric { intensity, .. }
                | DeltaLight::Projection {
                    scale: intensity, ..
                } => *intensity *= ratio,
                DeltaLight::Directional { radiance, .. } => *radiance *= ratio,
            }
        }
        for e in &mut self.scene.environments {
            e.radiance *= ratio;
        }
        for m in &mut self.scene.media {
            m.emission *= ratio;
        }
        self.build_pyramids();
        Ok(self.scene)
    }

    /// pbrt-v4's MIP maps: every `imagemap` texture's image becomes its pyramid
    /// ([`crate::mipmap::pyramid`]; one per image and wrap mode, made on every core, each
    /// image moved into its pyramid's base where nothing else holds it). A material's
    /// `normalmap` is read at full resolution, as pbrt-v4 reads it.
    fn build_pyramids(&mut self) {
        use crate::scene::ShadingMap;
        use crate::texture::Wrap;
        let normal_maps: std::collections::HashSet<u32> = self
            .scene
            .materials
            .iter()
            .filter_map(|m| match m.shading_map {
                Some(ShadingMap::Normal(t)) => Some(t),
                _ => None,
            })
            .collect();
        let mipmapped = |i: usize| !normal_maps.contains(&(i as u32));
        // Each image texture's key (image, wrap) in the order met, the images taken out of
        // the textures (an empty image in their place) so that their Arcs are held once.
        let empty = Arc::new(TextureImage::Float(crate::io::Image {
            width: 0,
            height: 0,
            pixels: Vec::new(),
        }));
        let mut order: Vec<usize> = Vec::new();
        let mut index: HashMap<(*const TextureImage, Wrap), usize> = HashMap::new();
        let mut images: Vec<(Option<Arc<TextureImage>>, Wrap)> = Vec::new();
        for (i, t) in self.scene.textures.iter_mut().enumerate() {
            if mipmapped(i) {
                t.for_each_image_texture_mut(&mut |image, wrap| {
                    let taken = std::mem::replace(image, empty.clone());
                    let k = *index.entry((Arc::as_ptr(&taken), wrap)).or_insert_with(|| {
                        images.push((Some(taken.clone()), wrap));
                        images.len() - 1
                    });
                    order.push(k);
                });
            }
        }
        if images.is_empty() {
            return;
        }
        drop(index);
        self.image_textures.clear();
        let built =
            crate::accel::map_in_parallel(&mut images, crate::accel::threads(), |(image, wrap)| {
                let image = image.take().expect("each image once");
                Arc::new(crate::mipmap::pyramid(Arc::unwrap_or_clone(image), *wrap))
            });
        let mut next = order.into_iter();
        for (i, t) in self.scene.textures.iter_mut().enumerate() {
            if mipmapped(i) {
                t.for_each_image_texture_mut(&mut |image, _| {
                    *image = built[next.next().expect("a key per image texture")].clone();
                });
            }
        }
    }
}

/// A scene file's text; gzip-compressed when its name ends in `.gz`.
fn read_scene_text(path: &Path) -> std::io::Result<String> {
    let raw = std::fs::read(path)?;
    let bytes = if path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("gz"))
    {
        let mut out = Vec::new();
        std::io::Read::read_to_end(&mut flate2::read::GzDecoder::new(&raw[..]), &mut out)?;
        out
    } else {
        raw
    };
    String::from_utf8(bytes)
        .map_err(|e| std::io::Error::new(std::io::ErrorKind::InvalidData, e.utf8_error()))
}

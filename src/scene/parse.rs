//! The `.test` scene parser (see docs/scene-format.md).
//!
//! The file is read whole and parsed in one pass, line by line, without per-line
//! allocations. Vertices are stored as written; a `tri` transforms them by the
//! transform current at the `tri`, so the scene holds world-space triangles only.
//! Material state is sticky; identical materials share one index.

use super::{
    BsdfKind, Camera, DeltaLight, Environment, EnvironmentMap, IntegratorKind, Material,
    MediumInterface, NextEventEstimation, QuadLight, SampleMode, Scene, Sphere, Texture, Triangle,
    UV_MAPPING,
};
use crate::texture::{load_image, load_texture, Encoding, EnvMapping};
use glam::{Mat3, Mat4, Vec2, Vec3};
use std::collections::HashMap;
use std::fmt;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Why a scene could not be parsed.
///
/// Displays as `FILE:LINE: 'COMMAND': MESSAGE`, e.g.
/// `scenes/foo.test:12: 'tri': vertex index 7 out of range (3 vertices declared)`,
/// or as `FILE: MESSAGE` when the file itself could not be read (then `line` is 0
/// and `command` is empty).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub struct ParseError {
    /// The file name (the path for [`parse_file`], the given name for [`parse_str`]).
    pub file: String,
    /// The 1-based line number; 0 when the error concerns the whole file.
    pub line: usize,
    /// The command keyword as written in the file; empty when `line` is 0.
    pub command: String,
    /// What was wrong or expected.
    pub message: String,
}

impl fmt::Display for ParseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.line == 0 {
            write!(f, "{}: {}", self.file, self.message)
        } else {
            write!(
                f,
                "{}:{}: '{}': {}",
                self.file, self.line, self.command, self.message
            )
        }
    }
}

/// Reads and parses a scene file. The scene's `source` is set to `path`.
///
/// # Errors
/// When the file cannot be read (`line` 0) or does not parse (see [`parse_str`]).
pub fn parse_file(path: &Path) -> Result<Scene, ParseError> {
    let (name, text, base) = read_scene_file(path)?;
    let mut scene = parse_text(&text, &name, base)?;
    scene.source = Some(path.to_path_buf());
    Ok(scene)
}

/// A scene file's name (for messages), its text and its directory (which the files it
/// names are relative to), or the error that it cannot be read (line 0).
pub(super) fn read_scene_file(path: &Path) -> Result<(String, String, PathBuf), ParseError> {
    let name = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|err| ParseError {
        file: name.clone(),
        line: 0,
        command: String::new(),
        message: format!("cannot read: {err}"),
    })?;
    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    Ok((name, text, dir))
}

/// Parses a scene from its text; `name` stands for the file name in error messages.
///
/// # Errors
/// At the first line with an unknown command, a wrong number of arguments, an
/// unparsable or out-of-range value, a vertex index out of range or a
/// `popTransform` with nothing pushed.
/// `obj` paths are relative to the working directory.
pub fn parse_str(text: &str, name: &str) -> Result<Scene, ParseError> {
    parse_text(text, name, PathBuf::new())
}

/// Parses a scene whose `obj` files are relative to `base`.
fn parse_text(text: &str, name: &str, base: PathBuf) -> Result<Scene, ParseError> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let mut parser = Parser {
        base,
        ..Parser::default()
    };
    for (index, line) in text.lines().enumerate() {
        let content = match line.find('#') {
            Some(comment) => &line[..comment],
            None => line,
        };
        let mut tokens = content.split_whitespace();
        let Some(keyword) = tokens.next() else {
            continue;
        };
        let mut command = Command {
            file: name,
            line: index + 1,
            name: keyword,
            args: [""; MAX_ARGS],
            count: 0,
        };
        for token in tokens {
            if command.count < MAX_ARGS {
                command.args[command.count] = token;
            }
            command.count += 1;
        }
        parser.execute(&command)?;
        // Lights are in the outside medium of the current `mediuminterface`.
        let medium = parser.material.medium_interface.and_then(|m| m.outside);
        parser.scene.place_new_delta_lights(medium);
    }
    Ok(parser.scene)
}

/// The first line of an OBJ file that lightpath cannot use, with what is wrong: vertex
/// positions need three finite numbers, faces at least three vertex references within
/// the file's vertices (1-based, or negative: relative to the vertices before the face),
/// and texture and normal references likewise.
fn obj_problem(text: &str) -> Option<(usize, String)> {
    let count = |key: &str| {
        text.lines()
            .filter(|l| l.split_whitespace().next() == Some(key))
            .count() as i64
    };
    let (total_v, total_vt, total_vn) = (count("v"), count("vt"), count("vn"));
    let (mut v, mut vt, mut vn) = (0i64, 0i64, 0i64);
    let floats = |args: &[&str], n: usize, what: &str| -> Result<(), String> {
        if args.len() < n {
            return Err(format!("{what} needs {n} numbers, got {}", args.len()));
        }
        for a in &args[..n] {
            match a.parse::<f32>() {
                Ok(x) if x.is_finite() => {}
                _ => return Err(format!("{what}: expected a finite number, got '{a}'")),
            }
        }
        Ok(())
    };
    let index = |token: &str, so_far: i64, total: i64, what: &str| -> Result<(), String> {
        let i: i64 = token
            .parse()
            .map_err(|_| format!("expected a {what} index, got '{token}'"))?;
        let ok = (i > 0 && i <= total) || (i < 0 && -i <= so_far);
        if !ok {
            return Err(format!(
                "{what} index {i} is out of range ({total} {what}s in the file, {so_far} before this face)"
            ));
        }
        Ok(())
    };
    for (n, line) in text.lines().enumerate() {
        let content = line.split('#').next().unwrap_or("");
        let words: Vec<&str> = content.split_whitespace().collect();
        let Some((&key, args)) = words.split_first() else {
            continue;
        };
        let result = match key {
            "v" => {
                v += 1;
                floats(args, 3, "a vertex position")
            }
            "vt" => {
                vt += 1;
                floats(args, 1, "a texture coordinate")
            }
            "vn" => {
                vn += 1;
                floats(args, 3, "a normal")
            }
            "f" => {
                if args.len() < 3 {
                    Err(format!(
                        "a face needs at least 3 vertices, got {}",
                        args.len()
                    ))
                } else {
                    args.iter().try_for_each(|r| {
                        let mut parts = r.split('/');
                        index(parts.next().unwrap_or(""), v, total_v, "vertex")?;
                        if let Some(t) = parts.next().filter(|t| !t.is_empty()) {
                            index(t, vt, total_vt, "texture coordinate")?;
                        }
                        if let Some(nn) = parts.next().filter(|t| !t.is_empty()) {
                            index(nn, vn, total_vn, "normal")?;
                        }
                        if parts.next().is_some() {
                            return Err(format!("malformed vertex reference '{r}'"));
                        }
                        Ok(())
                    })
                }
            }
            _ => Ok(()),
        };
        if let Err(what) = result {
            return Some((n + 1, what));
        }
    }
    None
}

/// Every command with its arguments, as shown in arity errors. The argument count
/// is the number of words after the keyword. `vertex` and `tri` come first because
/// they make up nearly all lines of large meshes.
const COMMANDS: &[(&str, &str)] = &[
    ("vertex", "x y z"),
    ("tri", "i j k"),
    ("size", "W H"),
    ("output", "FILE"),
    ("camera", "fx fy fz ax ay az ux uy uz fovy"),
    ("spp", "N"),
    ("gamma", "G"),
    ("maxverts", "N"),
    ("sphere", "cx cy cz r"),
    ("translate", "x y z"),
    ("rotate", "ax ay az deg"),
    ("scale", "sx sy sz"),
    ("pushTransform", ""),
    ("popTransform", ""),
    ("diffuse", "r g b"),
    ("specular", "r g b"),
    ("shininess", "s"),
    ("roughness", "a [av]"),
    ("baseroughness", "a [av]"),
    (
        "brdf",
        "phong|ggx|dielectric|thindielectric|conductor|coateddiffuse|diffusetransmission|coatedconductor",
    ),
    ("transmittance", "r g b"),
    ("thickness", "T"),
    ("layerdepth", "N"),
    ("layersamples", "N"),
    ("layeralbedo", "r g b"),
    ("layerg", "g"),
    ("ior", "ETA"),
    ("eta", "r g b"),
    ("k", "r g b"),
    ("emission", "r g b"),
    ("ambient", "r g b"),
    ("quadLight", "ax ay az bx by bz cx cy cz r g b"),
    ("point", "x y z r g b"),
    ("directional", "x y z r g b"),
    ("spot", "fx fy fz tx ty tz r g b coneangle conedelta"),
    ("envlight", "r g b"),
    ("attenuation", "c l q"),
    ("integrator", "NAME"),
    ("maxdepth", "N"),
    ("nexteventestimation", "off|on|mis"),
    ("russianroulette", "on|off"),
    ("importancesampling", "hemisphere|cosine|brdf"),
    ("lightsamples", "N"),
    ("lightstratify", "on|off"),
    ("mmltbootstrap", "N"),
    ("mmltchains", "N"),
    ("mmltsigma", "s"),
    ("mmltlargestep", "p"),
    ("obj", "FILE"),
    ("texture", "FILE|none [srgb|linear]"),
    ("roughnesstexture", "FILE|none [srgb|linear]"),
    ("bumpmap", "FILE|none [srgb|linear]"),
    ("normalmap", "FILE|none"),
    ("checkerboard", "r g b r g b su sv"),
    ("reflectance", "r g b"),
    ("envmap", "FILE SCALE"),
    ("envmapsquare", "FILE SCALE"),
    ("medium", "NAME sar sag sab ssr ssg ssb g [ler] [leg] [leb]"),
    ("mediuminterface", "INSIDE OUTSIDE"),
    ("cameramedium", "NAME"),
    ("passthrough", "on|off"),
];

/// The most arguments any command takes (`quadLight`).
const MAX_ARGS: usize = 12;

/// Integrators in the order the error message lists them.
const INTEGRATORS: [IntegratorKind; 6] = [
    IntegratorKind::PathTracer,
    IntegratorKind::Bdpt,
    IntegratorKind::Mmlt,
    IntegratorKind::Direct,
    IntegratorKind::AnalyticDirect,
    IntegratorKind::RayTracer,
];

/// `maxverts` reserves at most this many vertices up front (it is only a hint).
const MAX_VERTEX_RESERVE: usize = 1 << 22;

/// The largest image side a scene may ask for (a film of 65536² would already exceed
/// every device's storage-buffer range; the renderer refuses what does not fit).
const MAX_IMAGE_SIDE: u32 = 1 << 16;

/// The deepest pushTransform nesting a scene may have.
const MAX_TRANSFORM_NESTING: usize = 1 << 16;

/// One non-empty line: its keyword and up to [`MAX_ARGS`] arguments.
struct Command<'a> {
    file: &'a str,
    line: usize,
    name: &'a str,
    args: [&'a str; MAX_ARGS],
    /// The number of arguments on the line (may exceed `MAX_ARGS`).
    count: usize,
}

impl Command<'_> {
    fn error(&self, message: impl Into<String>) -> ParseError {
        ParseError {
            file: self.file.to_owned(),
            line: self.line,
            command: self.name.to_owned(),
            message: message.into(),
        }
    }

    /// Checks that the keyword is known and has its number of arguments.
    fn check_arity(&self) -> Result<(), ParseError> {
        let Some(&(keyword, usage)) = COMMANDS.iter().find(|(k, _)| *k == self.name) else {
            return Err(self.unknown());
        };
        // Words in brackets are optional.
        let total = usage.split_whitespace().count();
        let required = usage
            .split_whitespace()
            .filter(|w| !w.starts_with('['))
            .count();
        if (required..=total).contains(&self.count) {
            return Ok(());
        }
        let expected = match (required, total) {
            (0, 0) => "no arguments".to_owned(),
            (1, 1) => "1 argument".to_owned(),
            (r, t) if r == t => format!("{r} arguments"),
            (r, t) => format!("{r} to {t} arguments"),
        };
        let usage = if usage.is_empty() {
            keyword.to_owned()
        } else {
            format!("{keyword} {usage}")
        };
        Err(self.error(format!("expected {expected} ({usage}), got {}", self.count)))
    }

    fn unknown(&self) -> ParseError {
        let near = COMMANDS
            .iter()
            .find(|(k, _)| k.eq_ignore_ascii_case(self.name));
        match near {
            Some((k, _)) => self.error(format!(
                "unknown command (keywords are case-sensitive: did you mean '{k}'?)"
            )),
            None => self.error("unknown command"),
        }
    }

    /// "argument N: " when the command takes several arguments, else nothing.
    fn label(&self, index: usize) -> String {
        if self.count > 1 {
            format!("argument {}: ", index + 1)
        } else {
            String::new()
        }
    }

    fn float(&self, index: usize) -> Result<f32, ParseError> {
        let token = self.args[index];
        match token.parse::<f32>() {
            Ok(value) if value.is_finite() => Ok(value),
            Ok(_) => Err(self.error(format!(
                "{}expected a finite number, got '{token}'",
                self.label(index)
            ))),
            Err(_) => Err(self.error(format!(
                "{}expected a number, got '{token}'",
                self.label(index)
            ))),
        }
    }

    fn floats<const N: usize>(&self) -> Result<[f32; N], ParseError> {
        let mut values = [0.0; N];
        for (index, value) in values.iter_mut().enumerate() {
            *value = self.float(index)?;
        }
        Ok(values)
    }

    fn vec3(&self, first: usize) -> Result<Vec3, ParseError> {
        Ok(Vec3::new(
            self.float(first)?,
            self.float(first + 1)?,
            self.float(first + 2)?,
        ))
    }

    /// A colour (or intensity): three non-negative numbers.
    fn color(&self, first: usize, what: &str) -> Result<Vec3, ParseError> {
        let color = self.vec3(first)?;
        if color.min_element() < 0.0 {
            return Err(self.error(format!(
                "{what} must not be negative, got ({}, {}, {})",
                color.x, color.y, color.z
            )));
        }
        Ok(color)
    }

    fn non_negative(&self, index: usize, what: &str) -> Result<f32, ParseError> {
        let value = self.float(index)?;
        if value < 0.0 {
            return Err(self.error(format!("{what} must not be negative, got {value}")));
        }
        Ok(value)
    }

    /// An exact integer: written as one (`5`, `+5`) or as a float with an integral
    /// value (`5.0`, `1e3`); `5.5` is rejected.
    fn int(&self, index: usize, min: i64, max: i64) -> Result<i64, ParseError> {
        let token = self.args[index];
        let value = token.parse::<i64>().ok().or_else(|| {
            // Beyond 2^53 not every integer is representable as an f64.
            const MAX_EXACT: f64 = 9_007_199_254_740_992.0;
            let value = token.parse::<f64>().ok()?;
            (value.fract() == 0.0 && value.abs() <= MAX_EXACT).then_some(value as i64)
        });
        let Some(value) = value else {
            return Err(self.error(format!(
                "{}expected an integer, got '{token}'",
                self.label(index)
            )));
        };
        if value < min {
            return Err(self.error(format!(
                "{}expected an integer >= {min}, got {value}",
                self.label(index)
            )));
        }
        if value > max {
            return Err(self.error(format!(
                "{}expected an integer <= {max}, got {value}",
                self.label(index)
            )));
        }
        Ok(value)
    }

    /// A `u32` in `min..=u32::MAX`.
    fn uint(&self, index: usize, min: u32) -> Result<u32, ParseError> {
        let value = self.int(index, i64::from(min), i64::from(u32::MAX))?;
        u32::try_from(value).map_err(|_| self.error("integer out of range"))
    }

    /// The single argument, one of the given words.
    fn choice<T: Copy>(&self, options: &[(&str, T)]) -> Result<T, ParseError> {
        let word = self.args[0];
        if let Some(&(_, value)) = options.iter().find(|(name, _)| *name == word) {
            return Ok(value);
        }
        let names: Vec<String> = options
            .iter()
            .map(|(name, _)| format!("'{name}'"))
            .collect();
        Err(self.error(format!("expected {}, got '{word}'", names.join(" or "))))
    }
}

/// A material's identity for deduplication: the bytes of its whole device record
/// (`Material::record`), with -0.0 read as 0.0, so no field can be forgotten.
#[derive(Clone, PartialEq, Eq, Hash)]
pub(super) struct MaterialKey(Vec<u32>);

impl MaterialKey {
    pub(super) fn of(m: &Material) -> Self {
        let record = m.record();
        let words: &[u32] = bytemuck::cast_slice(bytemuck::bytes_of(&record));
        MaterialKey(
            words
                .iter()
                .map(|&w| if w == 0x8000_0000 { 0 } else { w })
                .collect(),
        )
    }
}

/// The parser's state between lines.
struct Parser {
    scene: Scene,
    /// Vertices as written (untransformed).
    vertices: Vec<Vec3>,
    transform: Mat4,
    saved_transforms: Vec<Mat4>,
    /// The sticky material state.
    material: Material,
    /// `material`'s index in `scene.materials`, once a shape has used it.
    material_index: Option<u32>,
    material_lookup: HashMap<MaterialKey, u32>,
    /// The directory `obj` paths are relative to.
    base: PathBuf,
    /// Image textures already read: (path, encoding) to their texture index.
    image_textures: HashMap<(PathBuf, Encoding), u32>,
    /// `medium` names: their index in `scene.media`.
    media: HashMap<String, u32>,
}

impl Default for Parser {
    fn default() -> Self {
        Parser {
            scene: Scene::default(),
            vertices: Vec::new(),
            transform: Mat4::IDENTITY,
            saved_transforms: Vec::new(),
            material: Material::default(),
            material_index: None,
            material_lookup: HashMap::new(),
            base: PathBuf::new(),
            image_textures: HashMap::new(),
            media: HashMap::new(),
        }
    }
}

impl Parser {
    /// The index of `material`, adding it to the scene unless an identical one exists.
    fn intern(&mut self, material: Material) -> u32 {
        let materials = &mut self.scene.materials;
        *self
            .material_lookup
            .entry(MaterialKey::of(&material))
            .or_insert_with(|| {
                materials.push(material);
                u32::try_from(materials.len() - 1).expect("more than 2^32 materials")
            })
    }

    /// The index of the current sticky material.
    fn current_material(&mut self) -> u32 {
        if let Some(index) = self.material_index {
            return index;
        }
        let index = self.intern(self.material);
        self.material_index = Some(index);
        index
    }

    /// Applies a change to the sticky material state.
    /// `medium NAME  σa (3)  σs (3)  g  [Le (3)]`: a homogeneous medium.
    fn medium(&mut self, cmd: &Command) -> Result<(), ParseError> {
        if cmd.count != 8 && cmd.count != 11 {
            return Err(cmd.error(format!(
                "expected 8 or 11 arguments (medium NAME sar sag sab ssr ssg ssb g [ler leg leb]), got {}",
                cmd.count
            )));
        }
        let name = cmd.args[0];
        if name == "vacuum" {
            return Err(cmd.error("'vacuum' names no medium (it is the space outside media)"));
        }
        if self.media.contains_key(name) {
            return Err(cmd.error(format!("medium '{name}' is defined twice")));
        }
        let sigma_a = cmd.color(1, "sigma_a")?;
        let sigma_s = cmd.color(4, "sigma_s")?;
        let g = cmd.float(7)?;
        if !(g > -1.0 && g < 1.0) {
            return Err(cmd.error(format!("g must lie in (-1, 1), got {g}")));
        }
        let emission = if cmd.count == 11 {
            cmd.color(8, "the emission")?
        } else {
            Vec3::ZERO
        };
        if self.scene.media.len() >= super::MAX_MEDIA {
            return Err(cmd.error(format!("more than {} media", super::MAX_MEDIA)));
        }
        self.media
            .insert(name.to_owned(), self.scene.media.len() as u32);
        self.scene.media.push(super::Medium {
            sigma_a,
            sigma_s,
            g,
            emission,
            grid: None,
        });
        Ok(())
    }

    /// Argument `index` as a medium: a name `medium` defined, or `vacuum`.
    fn medium_named(&self, cmd: &Command, index: usize) -> Result<Option<u32>, ParseError> {
        let name = cmd.args[index];
        if name == "vacuum" {
            return Ok(None);
        }
        match self.media.get(name) {
            Some(&i) => Ok(Some(i)),
            None => Err(cmd.error(format!(
                "no medium named '{name}' (define it with `medium` first, or say 'vacuum')"
            ))),
        }
    }

    fn set_material(&mut self, change: impl FnOnce(&mut Material)) {
        change(&mut self.material);
        self.material_index = None;
    }

    fn execute(&mut self, cmd: &Command) -> Result<(), ParseError> {
        cmd.check_arity()?;
        let settings = &mut self.scene.settings;
        match cmd.name {
            "vertex" => self.vertices.push(cmd.vec3(0)?),
            "tri" => self.tri(cmd)?,
            "obj" => self.obj(cmd)?,
            "size" => {
                self.scene.width = cmd.uint(0, 1)?;
                self.scene.height = cmd.uint(1, 1)?;
                if self.scene.width > MAX_IMAGE_SIDE || self.scene.height > MAX_IMAGE_SIDE {
                    return Err(cmd.error(format!(
                        "width and height must be at most {MAX_IMAGE_SIDE}, got {}x{}",
                        self.scene.width, self.scene.height
                    )));
                }
            }
            "output" => self.scene.output = Some(cmd.args[0].to_owned()),
            "camera" => self.scene.camera = camera(cmd)?,
            "spp" => settings.spp = cmd.uint(0, 1)?,
            "gamma" => {
                let gamma = cmd.float(0)?;
                if gamma <= 0.0 {
                    return Err(cmd.error(format!("gamma must be positive, got {gamma}")));
                }
                settings.gamma = gamma;
            }
            "maxverts" => {
                let hint = cmd.int(0, 0, i64::MAX)?;
                let hint = usize::try_from(hint)
                    .unwrap_or(usize::MAX)
                    .min(MAX_VERTEX_RESERVE);
                self.vertices
                    .reserve(hint.saturating_sub(self.vertices.len()));
            }
            "sphere" => self.sphere(cmd)?,
            "translate" => self.transform *= Mat4::from_translation(cmd.vec3(0)?),
            "rotate" => {
                let axis = cmd.vec3(0)?;
                let degrees = cmd.float(3)?;
                let Some(axis) = axis.try_normalize() else {
                    return Err(cmd.error("the rotation axis must not be zero"));
                };
                self.transform *= Mat4::from_axis_angle(axis, degrees.to_radians());
            }
            "scale" => self.transform *= Mat4::from_scale(cmd.vec3(0)?),
            "pushTransform" => {
                if self.saved_transforms.len() >= MAX_TRANSFORM_NESTING {
                    return Err(cmd.error(format!(
                        "pushTransform nested deeper than {MAX_TRANSFORM_NESTING}"
                    )));
                }
                self.saved_transforms.push(self.transform)
            }
            "popTransform" => {
                let Some(saved) = self.saved_transforms.pop() else {
                    return Err(cmd.error("no matching pushTransform (nothing to pop)"));
                };
                self.transform = saved;
            }
            "diffuse" => {
                let kd = cmd.color(0, "the diffuse colour")?;
                self.set_material(|m| m.diffuse = kd);
            }
            "specular" => {
                let ks = cmd.color(0, "the specular colour")?;
                self.set_material(|m| m.specular = ks);
            }
            "shininess" => {
                let s = cmd.non_negative(0, "the shininess")?;
                self.set_material(|m| m.shininess = s);
            }
            "roughness" => {
                let a = cmd.non_negative(0, "the roughness")?;
                let av = if cmd.count > 1 {
                    cmd.non_negative(1, "the roughness")?
                } else {
                    a
                };
                self.set_material(|m| {
                    m.roughness = a;
                    m.roughness_v = av;
                });
            }
            "brdf" => {
                let brdf = cmd.choice(&[
                    ("phong", BsdfKind::Phong),
                    ("ggx", BsdfKind::Ggx),
                    ("dielectric", BsdfKind::Dielectric),
                    ("thindielectric", BsdfKind::ThinDielectric),
                    ("conductor", BsdfKind::Conductor),
                    ("coateddiffuse", BsdfKind::CoatedDiffuse),
                    ("diffusetransmission", BsdfKind::DiffuseTransmission),
                    ("coatedconductor", BsdfKind::CoatedConductor),
                ])?;
                self.set_material(|m| m.bsdf = brdf);
            }
            "transmittance" => {
                let t = cmd.color(0, "the transmittance")?;
                self.set_material(|m| m.transmittance = t);
            }
            "baseroughness" => {
                let a = cmd.non_negative(0, "the roughness")?;
                let av = if cmd.count > 1 {
                    cmd.non_negative(1, "the roughness")?
                } else {
                    a
                };
                self.set_material(|m| {
                    m.base_roughness = a;
                    m.base_roughness_v = av;
                });
            }
            "thickness" => {
                let t = cmd.non_negative(0, "the thickness")?;
                self.set_material(|m| m.thickness = t);
            }
            "layerdepth" => {
                let n = cmd.uint(0, 1)?;
                if n > 1000 {
                    return Err(cmd.error(format!("expected at most 1000, got {n}")));
                }
                self.set_material(|m| m.layer_max_depth = n);
            }
            "layersamples" => {
                let n = cmd.uint(0, 1)?;
                if n > 64 {
                    return Err(cmd.error(format!("expected at most 64, got {n}")));
                }
                self.set_material(|m| m.layer_samples = n);
            }
            "layeralbedo" => {
                let a = cmd.color(0, "the layer's albedo")?;
                if a.max_element() > 1.0 {
                    return Err(cmd.error(format!(
                        "the layer's albedo must not exceed 1, got ({}, {}, {})",
                        a.x, a.y, a.z
                    )));
                }
                self.set_material(|m| m.layer_albedo = a);
            }
            "layerg" => {
                let g = cmd.float(0)?;
                if !(-1.0..=1.0).contains(&g) {
                    return Err(cmd.error(format!("g must lie in [-1, 1], got {g}")));
                }
                self.set_material(|m| m.layer_g = g);
            }
            "ior" => {
                let eta = cmd.float(0)?;
                if eta <= 0.0 {
                    return Err(cmd.error(format!(
                        "the index of refraction must be positive, got {eta}"
                    )));
                }
                self.set_material(|m| m.ior = eta);
            }
            "eta" => {
                let eta = cmd.color(0, "eta")?;
                self.set_material(|m| m.eta = eta);
            }
            "k" => {
                let k = cmd.color(0, "k")?;
                self.set_material(|m| m.k = k);
            }
            "emission" => {
                let le = cmd.color(0, "the emission")?;
                self.set_material(|m| {
                    m.emission = le;
                    m.two_sided_emission = true;
                });
            }
            // Only for the Whitted ray tracer, which lightpath parses but does not render.
            "ambient" | "attenuation" => {
                cmd.floats::<3>()?;
            }
            "quadLight" => self.quad_light(cmd)?,
            "point" => {
                let position = cmd.vec3(0)?;
                let intensity = cmd.color(3, "the intensity")?;
                self.scene.delta_lights.push(DeltaLight::Point {
                    position,
                    intensity,
                });
            }
            "directional" => {
                let direction = cmd.vec3(0)?;
                let radiance = cmd.color(3, "the radiance")?;
                let Some(direction) = direction.try_normalize() else {
                    return Err(cmd.error("the direction must not be zero"));
                };
                self.scene.delta_lights.push(DeltaLight::Directional {
                    direction,
                    radiance,
                });
            }
            "spot" => {
                let position = cmd.vec3(0)?;
                let target = cmd.vec3(3)?;
                let intensity = cmd.color(6, "the intensity")?;
                let cone = cmd.float(9)?;
                let delta = cmd.float(10)?;
                let Some(direction) = (target - position).try_normalize() else {
                    return Err(cmd.error("the spot light's position and target must differ"));
                };
                if !(cone > 0.0 && cone < 180.0) {
                    return Err(cmd.error(format!(
                        "the cone angle must be between 0 and 180 degrees, got {cone}"
                    )));
                }
                if !(0.0..=cone).contains(&delta) {
                    return Err(cmd.error(format!(
                        "the cone delta must be between 0 and the cone angle ({cone}), got {delta}"
                    )));
                }
                self.scene.delta_lights.push(DeltaLight::Spot {
                    position,
                    direction,
                    intensity,
                    cos_falloff_start: (cone - delta).to_radians().cos(),
                    cos_falloff_end: cone.to_radians().cos(),
                });
            }
            "envlight" => {
                let radiance = cmd.color(0, "the environment radiance")?;
                self.scene.environments = vec![Environment {
                    radiance,
                    map: None,
                    portal: None,
                }];
            }
            "envmap" => self.envmap(cmd, EnvMapping::LatLong)?,
            "envmapsquare" => self.envmap(cmd, EnvMapping::EqualArea)?,
            "medium" => self.medium(cmd)?,
            "mediuminterface" => {
                let inside = self.medium_named(cmd, 0)?;
                let outside = self.medium_named(cmd, 1)?;
                // (The same medium on both sides places the shapes and lights that follow in
                // it: an area light's subpaths start there.)
                self.set_material(|m| {
                    m.medium_interface = (inside.is_some() || outside.is_some())
                        .then_some(MediumInterface { inside, outside })
                });
            }
            "cameramedium" => self.scene.camera_medium = self.medium_named(cmd, 0)?,
            "passthrough" => {
                let on = cmd.choice(&[("on", true), ("off", false)])?;
                if on && self.media.is_empty() {
                    return Err(cmd.error(
                        "no medium defined yet (pass-through shapes are boundaries of media)",
                    ));
                }
                self.set_material(|m| m.pass_through = on);
            }
            "texture" => {
                let texture = self.image_texture_argument(cmd)?;
                self.set_material(|m| m.diffuse_texture = texture);
            }
            "roughnesstexture" => {
                let texture = self.image_texture_argument(cmd)?;
                self.set_material(|m| m.roughness_texture = texture);
            }
            "bumpmap" => {
                let texture = self.image_texture_argument(cmd)?;
                self.set_material(|m| m.shading_map = texture.map(super::ShadingMap::Bump));
            }
            "normalmap" => {
                let texture = if cmd.args[0] == "none" {
                    None
                } else {
                    let path = self.base.join(cmd.args[0]);
                    Some(self.image_texture(path, Encoding::Linear, cmd)?)
                };
                self.set_material(|m| m.shading_map = texture.map(super::ShadingMap::Normal));
            }
            "checkerboard" => {
                let even = cmd.color(0, "the first colour")?;
                let odd = cmd.color(3, "the second colour")?;
                let su = cmd.float(6)?;
                let sv = cmd.float(7)?;
                self.scene.textures.push(Texture::Checkerboard {
                    even,
                    odd,
                    mapping: [su, sv, 0.0, 0.0],
                    projection: crate::texture::Projection::Uv,
                });
                let index = (self.scene.textures.len() - 1) as u32;
                self.set_material(|m| m.diffuse_texture = Some(index));
            }
            "reflectance" => {
                // pbrt-v4's conductor from a reflectance r: eta = 1 and k = 2 sqrt(r) /
                // sqrt(1 - r), whose normal-incidence Fresnel reflectance is r.
                let r = cmd.color(0, "the reflectance")?;
                if r.max_element() >= 1.0 {
                    return Err(cmd.error(format!(
                        "the reflectance must be below 1 in every channel, got ({}, {}, {})",
                        r.x, r.y, r.z
                    )));
                }
                let k = Vec3::new(
                    2.0 * r.x.sqrt() / (1.0 - r.x).sqrt(),
                    2.0 * r.y.sqrt() / (1.0 - r.y).sqrt(),
                    2.0 * r.z.sqrt() / (1.0 - r.z).sqrt(),
                );
                self.set_material(|m| {
                    m.eta = Vec3::ONE;
                    m.k = k;
                });
            }
            "integrator" => {
                let name = cmd.args[0];
                let Some(kind) = IntegratorKind::from_name(name) else {
                    let names: Vec<&str> = INTEGRATORS.iter().map(|k| k.name()).collect();
                    return Err(cmd.error(format!(
                        "unknown integrator '{name}' (expected one of: {})",
                        names.join(", ")
                    )));
                };
                settings.integrator = kind;
            }
            "maxdepth" => {
                let depth = cmd.int(0, -1, i64::from(i32::MAX))?;
                settings.max_depth =
                    i32::try_from(depth).map_err(|_| cmd.error("integer out of range"))?;
            }
            "nexteventestimation" => {
                settings.nee = cmd.choice(&[
                    ("off", NextEventEstimation::Off),
                    ("on", NextEventEstimation::On),
                    ("mis", NextEventEstimation::Mis),
                ])?;
            }
            "russianroulette" => {
                settings.russian_roulette = cmd.choice(&[("on", true), ("off", false)])?;
            }
            "importancesampling" => {
                settings.importance_sampling = cmd.choice(&[
                    ("hemisphere", SampleMode::Hemisphere),
                    ("cosine", SampleMode::Cosine),
                    ("brdf", SampleMode::Brdf),
                ])?;
            }
            "lightsamples" => settings.light_samples = cmd.uint(0, 1)?,
            "lightstratify" => {
                settings.light_stratify = cmd.choice(&[("on", true), ("off", false)])?;
            }
            "mmltbootstrap" => settings.mmlt.bootstrap = Some(cmd.uint(0, 1)?),
            "mmltchains" => settings.mmlt.chains = Some(cmd.uint(0, 1)?),
            "mmltsigma" => {
                let sigma = cmd.float(0)?;
                if !(sigma > 0.0 && sigma <= 1.0) {
                    return Err(cmd.error(format!("mmltsigma must be in (0, 1], got {sigma}")));
                }
                settings.mmlt.sigma = sigma;
            }
            "mmltlargestep" => {
                let p = cmd.float(0)?;
                if !(0.0..=1.0).contains(&p) {
                    return Err(cmd.error(format!("mmltlargestep must be in [0, 1], got {p}")));
                }
                settings.mmlt.large_step = p;
            }
            _ => return Err(cmd.unknown()),
        }
        Ok(())
    }

    fn tri(&mut self, cmd: &Command) -> Result<(), ParseError> {
        let declared = self.vertices.len();
        let mut v = [Vec3::ZERO; 3];
        for (k, corner) in v.iter_mut().enumerate() {
            let index = cmd.int(k, i64::MIN, i64::MAX)?;
            let Some(&vertex) = usize::try_from(index)
                .ok()
                .and_then(|i| self.vertices.get(i))
            else {
                let noun = if declared == 1 { "vertex" } else { "vertices" };
                return Err(cmd.error(format!(
                    "vertex index {index} out of range ({declared} {noun} declared)"
                )));
            };
            *corner = self.transform.transform_point3(vertex);
        }
        let material = self.current_material();
        self.scene.triangles.push(Triangle::new(v, material));
        Ok(())
    }

    /// `obj FILE`: a Wavefront OBJ's faces (triangulated) as triangles under the current
    /// transform with the current material; the path is relative to the scene file.
    fn obj(&mut self, cmd: &Command) -> Result<(), ParseError> {
        let path = self.base.join(cmd.args[0]);
        let text = std::fs::read_to_string(&path)
            .map_err(|e| cmd.error(format!("cannot read OBJ file {}: {e}", path.display())))?;
        // tobj says what is wrong but not where: check the lines first.
        if let Some((line, what)) = obj_problem(&text) {
            return Err(cmd.error(format!("OBJ file {}, line {line}: {what}", path.display())));
        }
        let options = tobj::LoadOptions {
            triangulate: true,
            single_index: false,
            ignore_points: true,
            ignore_lines: true,
        };
        let (models, _materials) = tobj::load_obj_buf(&mut text.as_bytes(), &options, |_| {
            Err(tobj::LoadError::OpenFileFailed)
        })
        .map_err(|e| cmd.error(format!("OBJ file {}: {e}", path.display())))?;
        let material = self.current_material();
        let before = self.scene.triangles.len();
        // Normals transform by the inverse transpose.
        let normal_matrix = Mat3::from_mat4(self.transform).inverse().transpose();
        let missing = || {
            cmd.error(format!(
                "OBJ file {}: a face refers to a missing vertex",
                path.display()
            ))
        };
        for model in &models {
            let mesh = &model.mesh;
            // Texture coordinates and normals are used when every corner of the model has
            // them (tobj's per-corner index lists are then as long as its positions').
            let corners = mesh.indices.len();
            let has_uv = mesh.texcoord_indices.len() == corners && !mesh.texcoords.is_empty();
            let has_n = mesh.normal_indices.len() == corners && !mesh.normals.is_empty();
            for (f, face) in mesh.indices.chunks_exact(3).enumerate() {
                let mut v = [Vec3::ZERO; 3];
                let mut uv = [Vec2::ZERO; 3];
                let mut n = [Vec3::ZERO; 3];
                for (corner, &i) in face.iter().enumerate() {
                    let i = i as usize;
                    let xyz = mesh.positions.get(3 * i..3 * i + 3).ok_or_else(missing)?;
                    v[corner] = self
                        .transform
                        .transform_point3(Vec3::new(xyz[0], xyz[1], xyz[2]));
                    let k = 3 * f + corner;
                    if has_uv {
                        let j = mesh.texcoord_indices[k] as usize;
                        let t = mesh.texcoords.get(2 * j..2 * j + 2).ok_or_else(missing)?;
                        uv[corner] = Vec2::new(t[0], t[1]);
                    }
                    if has_n {
                        let j = mesh.normal_indices[k] as usize;
                        let m = mesh.normals.get(3 * j..3 * j + 3).ok_or_else(missing)?;
                        n[corner] = (normal_matrix * Vec3::new(m[0], m[1], m[2]))
                            .try_normalize()
                            .unwrap_or(Vec3::ZERO);
                    }
                }
                let mut t = Triangle::new(v, material);
                t.uv = has_uv.then_some(uv);
                // A zero normal (a "vn 0 0 0") leaves the face flat.
                t.normals = (has_n && n.iter().all(|x| *x != Vec3::ZERO)).then_some(n);
                self.scene.triangles.push(t.facing_its_normals());
            }
        }
        if self.scene.triangles.len() == before {
            return Err(cmd.error(format!("OBJ file {} has no faces", path.display())));
        }
        Ok(())
    }

    /// `texture FILE|none [srgb|linear]` and `roughnesstexture`: the texture index of
    /// the image (read once per file and encoding), or None.
    fn image_texture_argument(&mut self, cmd: &Command) -> Result<Option<u32>, ParseError> {
        if cmd.args[0] == "none" {
            if cmd.count > 1 {
                return Err(cmd.error("'none' takes no encoding"));
            }
            return Ok(None);
        }
        let encoding = match (cmd.count > 1).then_some(cmd.args[1]) {
            None | Some("srgb") => Encoding::Srgb,
            Some("linear") => Encoding::Linear,
            Some(other) => {
                return Err(cmd.error(format!(
                    "argument 2: expected 'srgb' or 'linear', got '{other}'"
                )))
            }
        };
        let path = self.base.join(cmd.args[0]);
        self.image_texture(path, encoding, cmd).map(Some)
    }

    /// The texture index of the image at `path` (read once per file and encoding).
    fn image_texture(
        &mut self,
        path: PathBuf,
        encoding: Encoding,
        cmd: &Command,
    ) -> Result<u32, ParseError> {
        if let Some(&index) = self.image_textures.get(&(path.clone(), encoding)) {
            return Ok(index);
        }
        let image = load_texture(&path, encoding).map_err(|e| cmd.error(e))?;
        self.scene.textures.push(Texture::Image {
            image: Arc::new(image),
            scale: Vec3::ONE,
            mapping: UV_MAPPING,
            wrap: crate::texture::Wrap::Repeat,
            projection: crate::texture::Projection::Uv,
            filter: crate::texture::Filter::Bilinear,
            max_anisotropy: crate::texture::DEFAULT_MAX_ANISOTROPY,
        });
        let index = (self.scene.textures.len() - 1) as u32;
        self.image_textures.insert((path, encoding), index);
        Ok(index)
    }

    /// `envmap FILE SCALE` (latitude-longitude, 2:1) and `envmapsquare FILE SCALE`
    /// (pbrt's equal-area square): the environment light, turned by the rotation of the
    /// current transform.
    fn envmap(&mut self, cmd: &Command, mapping: EnvMapping) -> Result<(), ParseError> {
        let scale = cmd.float(1)?;
        if scale < 0.0 {
            return Err(cmd.error(format!("the scale must not be negative, got {scale}")));
        }
        let path = self.base.join(cmd.args[0]);
        let image = load_image(&path, Encoding::Srgb).map_err(|e| cmd.error(e))?;
        let (w, h) = (image.width, image.height);
        match mapping {
            EnvMapping::LatLong if w != 2 * h => {
                return Err(cmd.error(format!(
                    "{}: a latitude-longitude map is twice as wide as high, this one is {w}x{h}{}",
                    path.display(),
                    if w == h {
                        " (an equal-area square map is read by 'envmapsquare')"
                    } else {
                        ""
                    }
                )))
            }
            EnvMapping::EqualArea if w != h => {
                return Err(cmd.error(format!(
                    "{}: an equal-area map is square, this one is {w}x{h}",
                    path.display()
                )))
            }
            _ => {}
        }
        let linear = Mat3::from_mat4(self.transform);
        let scale_of = linear.col(0).length();
        let rotation = linear * (1.0 / scale_of);
        let orthonormal = (rotation.transpose() * rotation - Mat3::IDENTITY)
            .to_cols_array()
            .iter()
            .all(|x| x.abs() < 1e-4);
        // (A mirror is a rotation's orthonormal twin: lookups and sampling go through the
        // frame's axes alike, and solid angle is kept.)
        if !orthonormal {
            return Err(cmd.error(
                "the current transform turns the environment map by more than a rotation \
                 and a mirror (a shear or a non-uniform scale)",
            ));
        }
        self.scene.environments = vec![Environment {
            radiance: Vec3::splat(scale),
            map: Some(EnvironmentMap {
                image: Arc::new(image),
                mapping,
                to_world: rotation,
            }),
            portal: None,
        }];
        Ok(())
    }

    fn sphere(&mut self, cmd: &Command) -> Result<(), ParseError> {
        let centre = cmd.vec3(0)?;
        let radius = cmd.float(3)?;
        if radius <= 0.0 {
            return Err(cmd.error(format!("the radius must be positive, got {radius}")));
        }
        let object_to_world =
            self.transform * Mat4::from_translation(centre) * Mat4::from_scale(Vec3::splat(radius));
        let det = object_to_world.determinant();
        if det == 0.0 || !det.is_finite() {
            return Err(cmd.error(
                "the current transform is singular (a zero scale?): the sphere would be flat",
            ));
        }
        let material = self.current_material();
        self.scene.spheres.push(Sphere {
            object_to_world,
            material,
            inward: false,
            hidden: false,
        });
        Ok(())
    }

    fn quad_light(&mut self, cmd: &Command) -> Result<(), ParseError> {
        let a = cmd.vec3(0)?;
        let ab = cmd.vec3(3)?;
        let ac = cmd.vec3(6)?;
        let radiance = cmd.color(9, "the radiance")?;
        let normal = ac.cross(ab);
        if normal.length_squared() == 0.0 || !normal.is_finite() {
            return Err(cmd.error(
                "the quad is degenerate: its edges are zero or parallel, so it has no normal",
            ));
        }
        self.scene.quad_lights.push(QuadLight {
            a,
            ab,
            ac,
            radiance,
        });
        // Black, one-sided emitter, whatever the sticky material is.
        let material = self.intern(Material {
            bsdf: BsdfKind::Phong,
            diffuse: Vec3::ZERO,
            specular: Vec3::ZERO,
            shininess: 1.0,
            roughness: 0.0,
            emission: radiance,
            two_sided_emission: false,
            medium_interface: self.material.medium_interface,
            ..Material::default()
        });
        // Both triangles' geometric normals cross(v1 - v0, v2 - v0) point along
        // cross(ac, ab), the emitting side.
        let (b, c, d) = (a + ab, a + ac, a + ab + ac);
        self.scene
            .triangles
            .push(Triangle::new([a, c, b], material));
        self.scene
            .triangles
            .push(Triangle::new([c, d, b], material));
        Ok(())
    }
}

fn camera(cmd: &Command) -> Result<Camera, ParseError> {
    let eye = cmd.vec3(0)?;
    let look_at = cmd.vec3(3)?;
    let up = cmd.vec3(6)?;
    let fovy_degrees = cmd.float(9)?;
    if !(fovy_degrees > 0.0 && fovy_degrees < 180.0) {
        return Err(cmd.error(format!(
            "the field of view must be between 0 and 180 degrees (exclusive), got {fovy_degrees}"
        )));
    }
    if eye == look_at {
        return Err(cmd.error("the eye and the look-at point must differ"));
    }
    if (look_at - eye).cross(up).length_squared() == 0.0 {
        return Err(
            cmd.error("the up vector must be non-zero and not parallel to the viewing direction")
        );
    }
    Ok(Camera {
        eye,
        look_at,
        up,
        fovy_degrees,
        ..Camera::default()
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    const FILE: &str = "scenes/bad.test";

    /// Three vertices, so that `tri 0 1 2` is valid.
    const TRI_VERTICES: &str = "vertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\n";

    #[track_caller]
    fn parse(text: &str) -> Scene {
        parse_str(text, "ok.test").unwrap_or_else(|e| panic!("unexpected error: {e}"))
    }

    #[track_caller]
    fn parse_err(text: &str) -> ParseError {
        match parse_str(text, FILE) {
            Ok(_) => panic!("expected an error for:\n{text}"),
            Err(e) => e,
        }
    }

    /// Checks the error's file, line, command, that its message contains `needle`,
    /// and the Display format.
    #[track_caller]
    fn check_err(text: &str, line: usize, command: &str, needle: &str) -> ParseError {
        let e = parse_err(text);
        assert_eq!(e.file, FILE, "{e}");
        assert_eq!(e.line, line, "{e}");
        assert_eq!(e.command, command, "{e}");
        assert!(
            e.message.contains(needle),
            "message {:?} lacks {needle:?}",
            e.message
        );
        assert_eq!(
            e.to_string(),
            format!("{FILE}:{line}: '{command}': {}", e.message)
        );
        e
    }

    #[track_caller]
    fn close(a: Vec3, b: Vec3) {
        assert!(a.abs_diff_eq(b, 1e-5), "{a} != {b}");
    }

    /// Where the current transform after `prefix` puts the point `p` (via a `tri`).
    #[track_caller]
    fn transformed(prefix: &str, p: Vec3) -> Vec3 {
        let scene = parse(&format!(
            "{prefix}\nvertex {} {} {}\nvertex 0 0 0\nvertex 0 0 0\ntri 0 1 2\n",
            p.x, p.y, p.z
        ));
        scene.triangles[0].v[0]
    }

    fn normal(t: &crate::scene::TriangleCorners) -> Vec3 {
        (t.v[1] - t.v[0]).cross(t.v[2] - t.v[0])
    }

    // ---- commands and their effects ----

    #[test]
    fn empty_input_gives_defaults() {
        for text in ["", "\n\n", "  # only a comment\n\t\n#\n"] {
            let s = parse(text);
            let d = Scene::default();
            assert_eq!((s.width, s.height), (d.width, d.height));
            assert_eq!(s.output, None);
            assert_eq!(s.camera, d.camera);
            assert_eq!(s.settings, d.settings);
            assert_eq!(s.source, None);
            assert!(s.materials.is_empty() && s.triangles.is_empty() && s.spheres.is_empty());
            assert!(s.quad_lights.is_empty() && s.delta_lights.is_empty());
        }
    }

    #[test]
    fn image_and_camera_commands() {
        let s = parse(
            "size 320 240\noutput out/image.png\ncamera 0 1 3  0 1 0  0 1 0  45\nspp 16\ngamma 2.2\n",
        );
        assert_eq!((s.width, s.height), (320, 240));
        assert_eq!(s.output.as_deref(), Some("out/image.png"));
        assert_eq!(
            s.camera,
            Camera {
                eye: Vec3::new(0.0, 1.0, 3.0),
                look_at: Vec3::new(0.0, 1.0, 0.0),
                up: Vec3::Y,
                fovy_degrees: 45.0,
                ..Camera::default()
            }
        );
        assert_eq!(s.settings.spp, 16);
        assert_eq!(s.settings.gamma, 2.2);
    }

    #[test]
    fn later_commands_override_earlier_ones() {
        let s = parse("spp 4\nsize 1 2\nspp 8\nsize 3 4\noutput a.png\noutput b.png\n");
        assert_eq!(s.settings.spp, 8);
        assert_eq!((s.width, s.height), (3, 4));
        assert_eq!(s.output.as_deref(), Some("b.png"));
    }

    #[test]
    fn integrator_settings() {
        let s = parse(
            "integrator bdpt\nmaxdepth -1\nnexteventestimation mis\nrussianroulette on\n\
             importancesampling cosine\nlightsamples 9\nlightstratify on\n",
        );
        let t = s.settings;
        assert_eq!(t.integrator, IntegratorKind::Bdpt);
        assert_eq!(t.max_depth, -1);
        assert_eq!(t.nee, NextEventEstimation::Mis);
        assert!(t.russian_roulette);
        assert_eq!(t.importance_sampling, SampleMode::Cosine);
        assert_eq!(t.light_samples, 9);
        assert!(t.light_stratify);

        for kind in INTEGRATORS {
            let s = parse(&format!("integrator {}", kind.name()));
            assert_eq!(s.settings.integrator, kind);
        }
        for (word, nee) in [
            ("off", NextEventEstimation::Off),
            ("on", NextEventEstimation::On),
            ("mis", NextEventEstimation::Mis),
        ] {
            let s = parse(&format!("nexteventestimation {word}"));
            assert_eq!(s.settings.nee, nee);
        }
        for (word, is) in [
            ("hemisphere", SampleMode::Hemisphere),
            ("cosine", SampleMode::Cosine),
            ("brdf", SampleMode::Brdf),
        ] {
            let s = parse(&format!("importancesampling {word}"));
            assert_eq!(s.settings.importance_sampling, is);
        }
        for (word, on) in [("on", true), ("off", false)] {
            let s = parse(&format!("russianroulette on\nrussianroulette {word}"));
            assert_eq!(s.settings.russian_roulette, on);
            let s = parse(&format!("lightstratify on\nlightstratify {word}"));
            assert_eq!(s.settings.light_stratify, on);
        }
        for depth in [-1, 0, 1, 5, 100] {
            let s = parse(&format!("maxdepth {depth}"));
            assert_eq!(s.settings.max_depth, depth);
        }
    }

    #[test]
    fn vertices_and_triangles() {
        let s = parse(&format!("{TRI_VERTICES}tri 0 1 2\ntri 2 1 0\ntri 1 1 1\n"));
        assert_eq!(s.triangles.len(), 3);
        let (a, b, c) = (Vec3::ZERO, Vec3::X, Vec3::Y);
        assert_eq!(s.triangles[0].v, [a, b, c]);
        assert_eq!(s.triangles[1].v, [c, b, a]);
        assert_eq!(s.triangles[2].v, [b, b, b]);
        assert!(s.spheres.is_empty() && s.quad_lights.is_empty());
    }

    #[test]
    fn tri_uses_the_transform_current_at_the_tri() {
        let s = parse(
            "vertex 1 0 0\nvertex 0 1 0\nvertex 0 0 1\n\
             tri 0 1 2\n\
             pushTransform\ntranslate 10 0 0\ntri 0 1 2\npopTransform\n\
             tri 0 1 2\n\
             pushTransform\ntranslate 5 5 5\nvertex 1 1 1\npopTransform\n\
             tri 0 1 3\n",
        );
        let [t0, t1, t2, t3] = s.triangles[..] else {
            panic!("expected 4 triangles, got {}", s.triangles.len());
        };
        assert_eq!(t0.v, [Vec3::X, Vec3::Y, Vec3::Z]);
        let shift = Vec3::new(10.0, 0.0, 0.0);
        assert_eq!(t1.v, [Vec3::X + shift, Vec3::Y + shift, Vec3::Z + shift]);
        assert_eq!(t2.v, t0.v);
        // A vertex declared under a transform is stored as written.
        assert_eq!(t3.v, [Vec3::X, Vec3::Y, Vec3::ONE]);
    }

    #[test]
    fn transforms_right_multiply() {
        let p = Vec3::X;
        // M = T·S: scale first, then translate.
        close(
            transformed("translate 1 0 0\nscale 2 2 2", p),
            Vec3::new(3.0, 0.0, 0.0),
        );
        // M = S·T: translate first, then scale.
        close(
            transformed("scale 2 2 2\ntranslate 1 0 0", p),
            Vec3::new(4.0, 0.0, 0.0),
        );
        // M = R·T and T·R.
        close(
            transformed("rotate 0 0 1 90\ntranslate 1 0 0", Vec3::ZERO),
            Vec3::Y,
        );
        close(
            transformed("translate 1 0 0\nrotate 0 0 1 90", Vec3::ZERO),
            Vec3::X,
        );
        close(
            transformed("scale 1 2 3", Vec3::ONE),
            Vec3::new(1.0, 2.0, 3.0),
        );
        close(
            transformed("translate 1 2 3\ntranslate -1 0 1", Vec3::ZERO),
            Vec3::new(0.0, 2.0, 4.0),
        );
    }

    #[test]
    fn rotate_uses_degrees_and_a_normalised_axis() {
        close(transformed("rotate 0 0 1 90", Vec3::X), Vec3::Y);
        close(transformed("rotate 0 0 5 90", Vec3::X), Vec3::Y);
        close(transformed("rotate 0 0 -1 90", Vec3::X), -Vec3::Y);
        close(transformed("rotate 0 1 0 180", Vec3::X), -Vec3::X);
        close(transformed("rotate 1 0 0 90", Vec3::Y), Vec3::Z);
        // 120 degrees about (1,1,1) cycles the axes.
        close(transformed("rotate 1 1 1 120", Vec3::X), Vec3::Y);
        close(transformed("rotate 2 2 2 120", Vec3::Y), Vec3::Z);
    }

    #[test]
    fn push_and_pop_restore_the_transform() {
        let s = parse(
            "vertex 0 0 0\n\
             translate 1 0 0\n\
             pushTransform\ntranslate 0 1 0\n\
             pushTransform\ntranslate 0 0 1\nscale 5 5 5\n\
             tri 0 0 0\n\
             popTransform\ntri 0 0 0\n\
             popTransform\ntri 0 0 0\n\
             pushTransform\npopTransform\ntri 0 0 0\n",
        );
        let corners: Vec<Vec3> = s.triangles.iter().map(|t| t.v[0]).collect();
        assert_eq!(
            corners,
            [
                Vec3::new(1.0, 1.0, 1.0),
                Vec3::new(1.0, 1.0, 0.0),
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(1.0, 0.0, 0.0),
            ]
        );
    }

    #[test]
    fn unbalanced_push_at_the_end_is_accepted() {
        let s = parse("pushTransform\npushTransform\nsize 2 2\n");
        assert_eq!(s.width, 2);
    }

    #[test]
    fn sphere_folds_centre_and_radius_into_its_transform() {
        let s = parse("sphere 1 2 3 0.5\n");
        let m = s.spheres[0].object_to_world;
        assert!(m.abs_diff_eq(
            Mat4::from_translation(Vec3::new(1.0, 2.0, 3.0)) * Mat4::from_scale(Vec3::splat(0.5)),
            1e-6
        ));
        close(m.transform_point3(Vec3::ZERO), Vec3::new(1.0, 2.0, 3.0));
        close(m.transform_point3(Vec3::X), Vec3::new(1.5, 2.0, 3.0));
        assert_eq!(s.spheres[0].material, 0);
        assert_eq!(s.materials, [Material::default()]);

        // Under a transform: M · translate(c) · scale(r).
        let s = parse("translate 1 0 0\nrotate 0 0 1 90\nsphere 0 2 0 0.5\n");
        let m = s.spheres[0].object_to_world;
        close(m.transform_point3(Vec3::ZERO), Vec3::new(-1.0, 0.0, 0.0));
        close(m.transform_point3(Vec3::X), Vec3::new(-1.0, 0.5, 0.0));
    }

    #[test]
    fn non_uniform_scale_makes_an_ellipsoid() {
        let s = parse("scale 1 2 3\nsphere 0 0 0 1\n");
        let m = s.spheres[0].object_to_world;
        assert!(m.abs_diff_eq(Mat4::from_scale(Vec3::new(1.0, 2.0, 3.0)), 1e-6));
        close(m.transform_point3(Vec3::X), Vec3::new(1.0, 0.0, 0.0));
        close(m.transform_point3(Vec3::Y), Vec3::new(0.0, 2.0, 0.0));
        close(m.transform_point3(Vec3::Z), Vec3::new(0.0, 0.0, 3.0));
    }

    #[test]
    fn shapes_get_the_default_material_without_material_commands() {
        let s = parse(&format!("{TRI_VERTICES}tri 0 1 2\nsphere 0 0 0 1\n"));
        assert_eq!(s.materials, [Material::default()]);
        assert_eq!(s.triangles[0].material, 0);
        assert_eq!(s.spheres[0].material, 0);
    }

    #[test]
    fn material_commands_set_every_field() {
        let s = parse(&format!(
            "{TRI_VERTICES}brdf ggx\ndiffuse 0.1 0.2 0.3\nspecular 0.4 0.5 0.6\n\
             shininess 30\nroughness 0.25\nemission 1 2 3\ntri 0 1 2\n\
             brdf phong\nsphere 0 0 0 1\n"
        ));
        let expected = Material {
            bsdf: BsdfKind::Ggx,
            diffuse: Vec3::new(0.1, 0.2, 0.3),
            specular: Vec3::new(0.4, 0.5, 0.6),
            shininess: 30.0,
            roughness: 0.25,
            roughness_v: 0.25,
            emission: Vec3::new(1.0, 2.0, 3.0),
            two_sided_emission: true,
            ..Material::default()
        };
        assert_eq!(s.materials.len(), 2);
        assert_eq!(s.materials[s.triangles[0].material as usize], expected);
        assert_eq!(
            s.materials[s.spheres[0].material as usize],
            Material {
                bsdf: BsdfKind::Phong,
                ..expected
            }
        );
        assert!(s.materials[0].is_emissive());
    }

    #[test]
    fn materials_are_sticky_and_deduplicated() {
        let s = parse(&format!(
            "{TRI_VERTICES}diffuse 0.5 0.5 0.5\ntri 0 1 2\ntri 0 1 2\n\
             diffuse 0.1 0.2 0.3\ntri 0 1 2\nsphere 0 0 0 1\n\
             diffuse 0.5 0.5 0.5\ntri 0 1 2\n\
             shininess 1\ntri 0 1 2\n"
        ));
        let indices: Vec<u32> = s.triangles.iter().map(|t| t.material).collect();
        assert_eq!(indices, [0, 0, 1, 0, 0]);
        assert_eq!(s.spheres[0].material, 1);
        assert_eq!(s.materials.len(), 2);
        assert_eq!(s.materials[0].diffuse, Vec3::splat(0.5));
        assert_eq!(s.materials[1].diffuse, Vec3::new(0.1, 0.2, 0.3));
    }

    #[test]
    fn only_used_materials_are_stored() {
        let s = parse(&format!(
            "{TRI_VERTICES}diffuse 1 0 0\ndiffuse 0 1 0\ntri 0 1 2\ndiffuse 0 0 1\n"
        ));
        assert_eq!(s.materials.len(), 1);
        assert_eq!(s.materials[0].diffuse, Vec3::Y);
    }

    #[test]
    fn negative_zero_does_not_make_a_new_material() {
        let s = parse(&format!(
            "{TRI_VERTICES}diffuse -0 0 0\ntri 0 1 2\ndiffuse 0 0 0\ntri 0 1 2\n"
        ));
        assert_eq!(s.materials.len(), 1);
    }

    #[test]
    fn a_large_mesh_shares_one_material() {
        let mut text = String::from("diffuse 0.3 0.6 0.1\n");
        for i in 0..1000 {
            text.push_str(&format!("vertex {i} 0 0\n"));
        }
        for i in 0..998 {
            text.push_str(&format!("tri {i} {} {}\n", i + 1, i + 2));
        }
        let s = parse(&text);
        assert_eq!(s.triangles.len(), 998);
        assert_eq!(s.materials.len(), 1);
        assert!(s.triangles.iter().all(|t| t.material == 0));
    }

    #[test]
    fn quad_light_adds_a_light_and_two_front_facing_triangles() {
        // Sticky material state and the transform must not affect the light.
        let s = parse(
            "diffuse 0.5 0.5 0.5\nemission 1 1 1\ntranslate 100 0 0\nscale 2 2 2\n\
             quadLight 1 2 3  0 0 2  3 0 0  4 5 6\n",
        );
        let (a, ab, ac) = (
            Vec3::new(1.0, 2.0, 3.0),
            Vec3::new(0.0, 0.0, 2.0),
            Vec3::new(3.0, 0.0, 0.0),
        );
        let radiance = Vec3::new(4.0, 5.0, 6.0);
        assert_eq!(
            s.quad_lights,
            [QuadLight {
                a,
                ab,
                ac,
                radiance
            }]
        );
        assert_eq!(s.triangles.len(), 2);
        let t = &s.triangles;
        assert_eq!(t[0].v, [a, a + ac, a + ab]);
        assert_eq!(t[1].v, [a + ac, a + ab + ac, a + ab]);
        assert_eq!(t[0].material, t[1].material);
        assert_eq!(
            s.materials[t[0].material as usize],
            Material {
                bsdf: BsdfKind::Phong,
                diffuse: Vec3::ZERO,
                specular: Vec3::ZERO,
                shininess: 1.0,
                roughness: 0.0,
                emission: radiance,
                two_sided_emission: false,
                ..Material::default()
            }
        );
        // Only the light's material exists: the sticky one was never used.
        assert_eq!(s.materials.len(), 1);
    }

    #[test]
    fn quad_light_triangles_face_the_emitting_side() {
        for (ab, ac) in [
            (Vec3::new(0.0, 0.0, 2.0), Vec3::new(3.0, 0.0, 0.0)),
            (Vec3::new(3.0, 0.0, 0.0), Vec3::new(0.0, 0.0, 2.0)),
            (Vec3::new(1.0, 2.0, 0.5), Vec3::new(-0.3, 0.1, 2.0)),
        ] {
            let s = parse(&format!(
                "quadLight 0.5 -1 2  {} {} {}  {} {} {}  1 1 1\n",
                ab.x, ab.y, ab.z, ac.x, ac.y, ac.z
            ));
            let front = ac.cross(ab);
            let mut area = 0.0;
            for t in s.triangles.iter() {
                let n = normal(t);
                close(n.normalize(), front.normalize());
                area += 0.5 * n.length();
            }
            assert!(
                (area - front.length()).abs() < 1e-4,
                "{area} vs {}",
                front.length()
            );
            // Together they cover the parallelogram: a and a+ab+ac are opposite corners.
            let a = s.quad_lights[0].a;
            assert!(s.triangles[0].v.contains(&a));
            assert!(s.triangles[1].v.contains(&(a + ab + ac)));
        }
    }

    #[test]
    fn the_course_cornell_light_faces_down() {
        let s = parse("quadLight -0.25 1.999 -0.25  0 0 0.5  0.5 0 0  30 26 21\n");
        for t in s.triangles.iter() {
            close(normal(t).normalize(), -Vec3::Y);
        }
    }

    #[test]
    fn quad_lights_with_equal_radiance_share_a_material() {
        let s = parse(&format!(
            "quadLight 0 0 0  1 0 0  0 1 0  5 5 5\nquadLight 0 2 0  1 0 0  0 1 0  5 5 5\n\
             quadLight 0 4 0  1 0 0  0 1 0  1 1 1\n{TRI_VERTICES}emission 5 5 5\ntri 0 1 2\n"
        ));
        let indices: Vec<u32> = s.triangles.iter().map(|t| t.material).collect();
        // The sticky emission is two-sided, so it is not the lights' material.
        assert_eq!(indices, [0, 0, 0, 0, 1, 1, 2]);
        assert!(s.materials[2].two_sided_emission);
        assert!(!s.materials[0].two_sided_emission);
    }

    #[test]
    fn point_and_directional_lights_are_in_world_space() {
        let s =
            parse("translate 5 5 5\nscale 2 2 2\npoint 1 2 3  4 5 6\ndirectional 0 0 -2  1 1 1\n");
        assert_eq!(
            s.delta_lights,
            [
                DeltaLight::Point {
                    position: Vec3::new(1.0, 2.0, 3.0),
                    intensity: Vec3::new(4.0, 5.0, 6.0),
                },
                DeltaLight::Directional {
                    direction: -Vec3::Z,
                    radiance: Vec3::ONE,
                },
            ]
        );
        let s = parse("directional 1 1 0  1 1 1\n");
        let DeltaLight::Directional { direction, .. } = s.delta_lights[0] else {
            panic!("not directional");
        };
        close(direction, Vec3::new(1.0, 1.0, 0.0).normalize());
    }

    #[test]
    fn ignored_commands_are_accepted() {
        let s = parse(&format!(
            "maxverts 100\nmaxverts 0\nambient 0.1 0.2 0.3\nattenuation 1 0.5 0\n\
             {TRI_VERTICES}tri 0 1 2\n"
        ));
        assert_eq!(s.materials, [Material::default()]);
        assert_eq!(s.triangles.len(), 1);
        // A huge hint is only a hint.
        parse("maxverts 99999999999\n");
    }

    #[test]
    fn comments_blank_lines_and_whitespace() {
        let s = parse(
            "# full-line comment\n\
             size 10 20 # trailing comment\n\
             \x20  # indented comment\n\
             \n\
             \t spp\t7  \t\n\
             vertex 1 2 3#no space before the hash\n\
             output a.png#comment\n\
             #size 1 1\n\
             gamma 2 ## double\n",
        );
        assert_eq!((s.width, s.height), (10, 20));
        assert_eq!(s.settings.spp, 7);
        assert_eq!(s.output.as_deref(), Some("a.png"));
        assert_eq!(s.settings.gamma, 2.0);
    }

    #[test]
    fn crlf_line_endings_and_bom() {
        let s = parse("\u{feff}size 3 4\r\nspp 2\r\n\r\n# c\r\n");
        assert_eq!((s.width, s.height), (3, 4));
        assert_eq!(s.settings.spp, 2);
        check_err("size 1 1\r\n\r\nspp x\r\n", 3, "spp", "'x'");
    }

    #[test]
    fn numeric_formats() {
        let s = parse("vertex +1 -0.25 1e3\nvertex 1E-2 .5 5.\nvertex -0 +0.0 2.5e+1\ntri 0 1 2\n");
        assert_eq!(
            s.triangles[0].v,
            [
                Vec3::new(1.0, -0.25, 1000.0),
                Vec3::new(0.01, 0.5, 5.0),
                Vec3::new(0.0, 0.0, 25.0),
            ]
        );
        // Integers may be written as floats with integral values.
        assert_eq!(parse("spp 5.0").settings.spp, 5);
        assert_eq!(parse("spp 1e2").settings.spp, 100);
        assert_eq!(parse("spp +3").settings.spp, 3);
        assert_eq!(parse("maxdepth -1.0").settings.max_depth, -1);
        assert_eq!(parse("size 640.0 4.8e2").height, 480);
        let s = parse(&format!("{TRI_VERTICES}tri 0.0 +1 2e0\n"));
        assert_eq!(s.triangles[0].v, [Vec3::ZERO, Vec3::X, Vec3::Y]);
    }

    // ---- errors ----

    /// One valid line per command; it is line 5 after [`PREAMBLE`].
    const EXAMPLES: &[&str] = &[
        "vertex 1 2 3",
        "tri 0 1 2",
        "size 640 480",
        "output image.png",
        "camera 0 0 1  0 0 0  0 1 0  45",
        "spp 4",
        "gamma 2.2",
        "maxverts 8",
        "sphere 0 0 0 1",
        "translate 1 2 3",
        "rotate 0 1 0 90",
        "scale 1 2 3",
        "pushTransform",
        "popTransform",
        "diffuse 0.5 0.5 0.5",
        "specular 0.5 0.5 0.5",
        "shininess 20",
        "roughness 0.3",
        "baseroughness 0.1 0.2",
        "layeralbedo 0.5 0.6 0.7",
        "layerg -0.3",
        "brdf ggx",
        "emission 1 1 1",
        "ambient 0.1 0.1 0.1",
        "quadLight 0 1 0  1 0 0  0 0 1  5 5 5",
        "point 0 1 0  1 1 1",
        "directional 0 1 0  1 1 1",
        "spot 0 2 0  0 0 0  5 5 5  30 5",
        "envlight 0.5 0.6 0.7",
        "attenuation 1 0 0",
        "integrator bdpt",
        "maxdepth 3",
        "nexteventestimation mis",
        "russianroulette on",
        "importancesampling cosine",
        "lightsamples 4",
        "lightstratify on",
        "mmltbootstrap 1000",
        "mmltchains 64",
        "mmltsigma 0.02",
        "mmltlargestep 0.5",
        "ior 1.33",
        "eta 0.2 0.9 1.1",
        "k 3.9 2.4 2.1",
        "obj tests/data/tetrahedron.obj",
        "texture tests/data/checker.png srgb",
        "roughnesstexture tests/data/checker.png linear",
        "bumpmap tests/data/checker.png linear",
        "normalmap tests/data/checker.png",
        "checkerboard 1 1 1  0 0 0  4 4",
        "reflectance 0.9 0.6 0.3",
        "thickness 0.02",
        "transmittance 0.4 0.5 0.6",
        "layerdepth 12",
        "layersamples 2",
        "envmap tests/data/sky.pfm 2",
        "envmapsquare tests/data/sky-square.pfm 2",
        "medium fog  0.1 0.2 0.3  1 1 1  0.5",
        "mediuminterface vacuum vacuum",
        "cameramedium vacuum",
        "passthrough off",
    ];
    const PREAMBLE: &str = "vertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\npushTransform\n";

    /// The media commands: a medium's coefficients, the sticky interface and
    /// pass-through of the shapes that follow, the camera's medium; their errors.
    #[test]
    fn media_commands() {
        let s = parse(
            "medium fog  0.1 0.2 0.3  1 2 3  0.5\nmedium glow 1 1 1  0 0 0  0  2 1 0\n\
             cameramedium fog\nmediuminterface glow fog\npassthrough on\nsphere 0 0 0 1\n\
             passthrough off\nmediuminterface fog fog\nsphere 0 0 0 2\n",
        );
        assert_eq!(s.media.len(), 2);
        assert_eq!(s.media[0].sigma_s, Vec3::new(1.0, 2.0, 3.0));
        assert_eq!(s.media[0].g, 0.5);
        assert_eq!(s.media[1].emission, Vec3::new(2.0, 1.0, 0.0));
        assert_eq!(s.camera_medium, Some(0));
        let a = &s.materials[s.spheres[0].material as usize];
        assert!(a.pass_through);
        assert_eq!(
            a.medium_interface,
            Some(MediumInterface {
                inside: Some(1),
                outside: Some(0)
            })
        );
        // (The same medium on both sides: the shape is in it, a boundary of nothing.)
        let b = &s.materials[s.spheres[1].material as usize];
        assert!(!b.pass_through);
        assert_eq!(
            b.medium_interface,
            Some(MediumInterface {
                inside: Some(0),
                outside: Some(0)
            })
        );
        // Lights are in the outside medium of the current interface.
        let l = parse(
            "medium fog 0.1 0.2 0.3 1 2 3 0.5
point 0 0 0 1 1 1
mediuminterface vacuum fog
             point 0 1 0 1 1 1
spot 0 0 0 0 0 1 1 1 1 30 5
quadLight 0 0 0 1 0 0 0 1 0 1 1 1
             mediuminterface fog fog
directional 0 0 1 1 1 1
mediuminterface vacuum vacuum
             point 0 0 1 1 1 1
",
        );
        assert_eq!(
            l.delta_light_media,
            vec![None, Some(0), Some(0), Some(0), None]
        );
        let quad = &l.materials[l.triangles[0].material as usize];
        assert_eq!(quad.medium_interface.and_then(|m| m.outside), Some(0));
        check_err(
            "medium fog 1 1 1 1 1 1 0 1\n",
            1,
            "medium",
            "expected 8 or 11 arguments",
        );
        check_err("medium fog 1 1 1 1 1 1 1\n", 1, "medium", "g must lie");
        check_err(
            "medium fog 1 -1 1 1 1 1 0\n",
            1,
            "medium",
            "sigma_a must not be negative",
        );
        check_err(
            "medium f 1 1 1 1 1 1 0\nmedium f 1 1 1 1 1 1 0\n",
            2,
            "medium",
            "twice",
        );
        check_err(
            "\nmediuminterface smoke vacuum\n",
            2,
            "mediuminterface",
            "no medium named 'smoke'",
        );
        check_err("cameramedium fog\n", 1, "cameramedium", "no medium named");
        check_err("passthrough on\n", 1, "passthrough", "no medium defined");
    }

    #[test]
    fn examples_cover_every_command() {
        let mut from_examples: Vec<&str> = EXAMPLES
            .iter()
            .map(|e| e.split_whitespace().next().unwrap_or_default())
            .collect();
        let mut known: Vec<&str> = COMMANDS.iter().map(|(k, _)| *k).collect();
        from_examples.sort_unstable();
        known.sort_unstable();
        assert_eq!(from_examples, known);
    }

    #[test]
    fn every_example_parses() {
        for example in EXAMPLES {
            parse(&format!("{PREAMBLE}{example}\n"));
        }
    }

    #[test]
    fn wrong_argument_counts() {
        for example in EXAMPLES {
            let keyword = example.split_whitespace().next().unwrap_or_default();
            let usage = COMMANDS.iter().find(|(k, _)| *k == keyword).unwrap().1;
            // Words in brackets are optional.
            let total = usage.split_whitespace().count();
            let required = usage
                .split_whitespace()
                .filter(|w| !w.starts_with('['))
                .count();
            let mut wrong = vec![
                format!("{keyword}{}", " 1".repeat(total + 1)),
                format!("{example} {example}"),
            ];
            if required > 0 {
                wrong.push(format!("{keyword}{}", " 1".repeat(required - 1)));
                wrong.push(keyword.to_owned());
            }
            let expected = match (required, total) {
                (0, 0) => "expected no arguments".to_owned(),
                (1, 1) => "expected 1 argument ".to_owned(),
                (r, t) if r == t => format!("expected {r} arguments"),
                (r, t) => format!("expected {r} to {t} arguments"),
            };
            for line in wrong {
                let e = check_err(&format!("{PREAMBLE}{line}\n"), 5, keyword, &expected);
                let got = line.split_whitespace().count() - 1;
                assert!(e.message.ends_with(&format!("), got {got}")), "{e}");
                assert!(e.message.contains(&format!("({keyword}")), "{e}");
            }
        }
    }

    #[test]
    fn argument_count_messages() {
        check_err(
            "vertex 1 2",
            1,
            "vertex",
            "expected 3 arguments (vertex x y z), got 2",
        );
        check_err(
            "pushTransform now",
            1,
            "pushTransform",
            "expected no arguments (pushTransform), got 1",
        );
        check_err("spp", 1, "spp", "expected 1 argument (spp N), got 0");
        check_err(
            "quadLight 1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16 17 18 19 20",
            1,
            "quadLight",
            "expected 12 arguments (quadLight ax ay az bx by bz cx cy cz r g b), got 20",
        );
        check_err("output a b.png", 1, "output", "got 2");
    }

    #[test]
    fn unknown_commands() {
        check_err(
            "size 1 1\n\nfrobnicate 1 2\n",
            3,
            "frobnicate",
            "unknown command",
        );
        let e = check_err("pushtransform\n", 1, "pushtransform", "unknown command");
        assert!(e.message.contains("did you mean 'pushTransform'"), "{e}");
        let e = check_err("Vertex 1 2 3\n", 1, "Vertex", "did you mean 'vertex'");
        assert!(e.message.contains("case-sensitive"), "{e}");
        let e = check_err("tris 0 1 2\n", 1, "tris", "unknown command");
        assert!(!e.message.contains("did you mean"), "{e}");
    }

    #[test]
    fn unparsable_numbers_in_every_numeric_argument() {
        for example in EXAMPLES {
            let tokens: Vec<&str> = example.split_whitespace().collect();
            let n = tokens.len() - 1;
            for k in 1..=n {
                if tokens[k].parse::<f64>().is_err() {
                    continue; // a word argument
                }
                let mut bad = tokens.clone();
                bad[k] = "x1";
                let e = check_err(
                    &format!("{PREAMBLE}{}\n", bad.join(" ")),
                    5,
                    tokens[0],
                    "got 'x1'",
                );
                if n > 1 {
                    assert!(e.message.starts_with(&format!("argument {k}: ")), "{e}");
                } else {
                    assert!(!e.message.contains("argument"), "{e}");
                }
                assert!(
                    e.message.contains("expected a number")
                        || e.message.contains("expected an integer"),
                    "{e}"
                );
            }
        }
    }

    #[test]
    fn non_finite_numbers() {
        for token in ["nan", "NaN", "inf", "-infinity", "1e39"] {
            check_err(
                &format!("vertex 1 {token} 3"),
                1,
                "vertex",
                &format!("argument 2: expected a finite number, got '{token}'"),
            );
        }
        check_err(
            "gamma inf",
            1,
            "gamma",
            "expected a finite number, got 'inf'",
        );
        check_err("spp nan", 1, "spp", "expected an integer, got 'nan'");
    }

    #[test]
    fn numbers_must_be_whole_tokens() {
        check_err(
            "vertex 1 2 3x",
            1,
            "vertex",
            "argument 3: expected a number, got '3x'",
        );
        check_err("vertex 1,2 3 4", 1, "vertex", "got '1,2'");
        check_err("vertex 0x10 3 4", 1, "vertex", "got '0x10'");
    }

    #[test]
    fn integers_must_be_exact() {
        check_err("spp 5.5", 1, "spp", "expected an integer, got '5.5'");
        check_err("spp abc", 1, "spp", "expected an integer, got 'abc'");
        check_err(
            "size 10 2.5",
            1,
            "size",
            "argument 2: expected an integer, got '2.5'",
        );
        check_err(
            "size 0.1 2",
            1,
            "size",
            "argument 1: expected an integer, got '0.1'",
        );
        check_err(
            "maxdepth 2.5",
            1,
            "maxdepth",
            "expected an integer, got '2.5'",
        );
        check_err(
            "lightsamples 1.5",
            1,
            "lightsamples",
            "expected an integer, got '1.5'",
        );
        check_err(
            "maxverts 0.5",
            1,
            "maxverts",
            "expected an integer, got '0.5'",
        );
        check_err(
            &format!("{TRI_VERTICES}tri 0 1 1.5"),
            4,
            "tri",
            "argument 3: expected an integer, got '1.5'",
        );
    }

    #[test]
    fn integers_out_of_range() {
        check_err(
            "size 0 10",
            1,
            "size",
            "argument 1: expected an integer >= 1, got 0",
        );
        check_err(
            "size 10 -3",
            1,
            "size",
            "argument 2: expected an integer >= 1, got -3",
        );
        check_err(
            "size 4294967296 1",
            1,
            "size",
            "expected an integer <= 4294967295",
        );
        check_err("spp 0", 1, "spp", "expected an integer >= 1, got 0");
        check_err("spp -4", 1, "spp", "expected an integer >= 1, got -4");
        check_err(
            "spp 4294967296",
            1,
            "spp",
            "expected an integer <= 4294967295",
        );
        check_err(
            "maxdepth -2",
            1,
            "maxdepth",
            "expected an integer >= -1, got -2",
        );
        check_err(
            "maxdepth 2147483648",
            1,
            "maxdepth",
            "expected an integer <= 2147483647",
        );
        check_err(
            "lightsamples 0",
            1,
            "lightsamples",
            "expected an integer >= 1, got 0",
        );
        check_err(
            "maxverts -1",
            1,
            "maxverts",
            "expected an integer >= 0, got -1",
        );
    }

    #[test]
    fn vertex_index_out_of_range() {
        let e = check_err(
            &format!("{TRI_VERTICES}tri 0 1 3\n"),
            4,
            "tri",
            "vertex index 3 out of range (3 vertices declared)",
        );
        assert_eq!(
            e.to_string(),
            "scenes/bad.test:4: 'tri': vertex index 3 out of range (3 vertices declared)"
        );
        check_err(
            &format!("{TRI_VERTICES}tri 7 1 2\n"),
            4,
            "tri",
            "vertex index 7 out of range (3 vertices declared)",
        );
        check_err(
            &format!("{TRI_VERTICES}tri -1 1 2\n"),
            4,
            "tri",
            "vertex index -1 out of range",
        );
        check_err("tri 0 0 0\n", 1, "tri", "(0 vertices declared)");
        check_err(
            "vertex 0 0 0\ntri 0 0 1\n",
            2,
            "tri",
            "vertex index 1 out of range (1 vertex declared)",
        );
        // Only vertices declared before the tri count.
        check_err(
            "vertex 0 0 0\nvertex 0 0 0\ntri 0 1 2\nvertex 0 0 0\n",
            3,
            "tri",
            "index 2",
        );
    }

    #[test]
    fn rotate_about_a_zero_axis() {
        check_err(
            "rotate 0 0 0 45",
            1,
            "rotate",
            "the rotation axis must not be zero",
        );
        check_err(
            "translate 1 1 1\nrotate 0 -0 0 0",
            2,
            "rotate",
            "axis must not be zero",
        );
    }

    #[test]
    fn pop_without_push() {
        check_err(
            "popTransform\n",
            1,
            "popTransform",
            "no matching pushTransform",
        );
        check_err(
            "pushTransform\npopTransform\n# comment\npopTransform\n",
            4,
            "popTransform",
            "nothing to pop",
        );
    }

    #[test]
    fn glass_and_metal_materials() {
        let s = parse(
            "vertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\n\
             brdf dielectric\nior 1.33\nroughness 0.2\ntri 0 1 2\n\
             brdf conductor\neta 0.2 0.9 1.1\nk 3.9 2.4 2.1\nroughness 0.1 0.3\nsphere 0 0 0 1\n\
             brdf thindielectric\nsphere 0 0 3 1\n\
             brdf dielectric\nroughness 0\nsphere 0 0 6 1\n",
        );
        assert_eq!(s.materials.len(), 4);
        let glass = s.materials[s.triangles[0].material as usize];
        assert_eq!(glass.bsdf, BsdfKind::Dielectric);
        assert_eq!(
            (glass.ior, glass.roughness, glass.roughness_v),
            (1.33, 0.2, 0.2)
        );
        let metal = s.materials[s.spheres[0].material as usize];
        assert_eq!(metal.bsdf, BsdfKind::Conductor);
        assert_eq!((metal.roughness, metal.roughness_v), (0.1, 0.3));
        let r = metal.record();
        assert_eq!(r.eta, [0.2, 0.9, 1.1, 0.0]);
        assert_eq!(r.k, [3.9, 2.4, 2.1, 0.0]);
        assert_eq!(r.roughness[1..3], [0.1, 0.3]);
        let thin = s.materials[s.spheres[1].material as usize].record();
        assert_eq!(thin.info[0], BsdfKind::ThinDielectric as u32);
        assert_eq!(thin.eta[0], 1.33, "ior is sticky");
        // A dielectric's record holds its ior, not the sticky conductor's eta and k.
        let smooth = s.materials[s.spheres[2].material as usize].record();
        assert_eq!((smooth.eta, smooth.k), ([1.33, 1.33, 1.33, 0.0], [0.0; 4]));
        // Defaults: glass of index 1.5, copper.
        let d = Material::default();
        assert_eq!(d.ior, 1.5);
        assert!(d.k.min_element() > 2.0);
        // Bad values name the line.
        check_err("ior 0", 1, "ior", "must be positive, got 0");
        check_err("ior -1.5", 1, "ior", "must be positive");
        check_err("ior inf", 1, "ior", "expected a finite number");
        check_err("eta 1 -1 1", 1, "eta", "must not be negative");
        check_err("k 1 1 -0.5", 1, "k", "must not be negative");
        check_err("roughness 0.1 -0.2", 1, "roughness", "must not be negative");
        check_err(
            "roughness 0.1 0.2 0.3",
            1,
            "roughness",
            "expected 1 to 2 arguments (roughness a [av]), got 3",
        );
    }

    #[test]
    fn spot_lights() {
        let s = parse("translate 1 1 1\nspot 0 2 0  0 0 0  1 2 3  30 5\n");
        let DeltaLight::Spot {
            position,
            direction,
            intensity,
            cos_falloff_start,
            cos_falloff_end,
        } = s.delta_lights[0]
        else {
            panic!("not a spot light");
        };
        // World space, like the other lights.
        assert_eq!(position, Vec3::new(0.0, 2.0, 0.0));
        assert_eq!(direction, Vec3::new(0.0, -1.0, 0.0));
        assert_eq!(intensity, Vec3::new(1.0, 2.0, 3.0));
        assert!((cos_falloff_end - 30f32.to_radians().cos()).abs() < 1e-6);
        assert!((cos_falloff_start - 25f32.to_radians().cos()).abs() < 1e-6);
        check_err(
            "spot 0 0 0  0 0 0  1 1 1  30 5",
            1,
            "spot",
            "position and target must differ",
        );
        check_err(
            "spot 0 1 0  0 0 0  1 1 1  0 0",
            1,
            "spot",
            "between 0 and 180 degrees, got 0",
        );
        check_err(
            "spot 0 1 0  0 0 0  1 1 1  180 5",
            1,
            "spot",
            "between 0 and 180 degrees",
        );
        check_err("spot 0 1 0  0 0 0  1 1 1  30 31", 1, "spot", "cone delta");
        check_err(
            "spot 0 1 0  0 0 0  1 -1 1  30 5",
            1,
            "spot",
            "the intensity",
        );
        let s = parse("envlight 0.5 0.6 0.7\n");
        assert_eq!(
            s.environments,
            vec![Environment {
                radiance: Vec3::new(0.5, 0.6, 0.7),
                map: None,
                portal: None,
            }]
        );
        check_err("envlight 1 -1 1", 1, "envlight", "must not be negative");
    }

    #[test]
    fn unknown_words() {
        check_err(
            "brdf blinn",
            1,
            "brdf",
            "expected 'phong' or 'ggx' or 'dielectric' or 'thindielectric' or 'conductor' or 'coateddiffuse' or 'diffusetransmission' or 'coatedconductor', got 'blinn'",
        );
        check_err("brdf GGX", 1, "brdf", "got 'GGX'");
        let e = check_err(
            "integrator whitted",
            1,
            "integrator",
            "unknown integrator 'whitted'",
        );
        for kind in INTEGRATORS {
            assert!(e.message.contains(kind.name()), "{e}");
        }
        check_err(
            "integrator PathTracer",
            1,
            "integrator",
            "unknown integrator",
        );
        check_err(
            "nexteventestimation yes",
            1,
            "nexteventestimation",
            "expected 'off' or 'on' or 'mis', got 'yes'",
        );
        check_err(
            "russianroulette true",
            1,
            "russianroulette",
            "expected 'on' or 'off', got 'true'",
        );
        check_err(
            "importancesampling uniform",
            1,
            "importancesampling",
            "expected 'hemisphere' or 'cosine' or 'brdf', got 'uniform'",
        );
        check_err(
            "lightstratify 1",
            1,
            "lightstratify",
            "expected 'on' or 'off', got '1'",
        );
    }

    #[test]
    fn zero_light_direction() {
        check_err(
            "directional 0 0 0  1 1 1",
            1,
            "directional",
            "the direction must not be zero",
        );
    }

    #[test]
    fn bad_cameras() {
        for fov in ["0", "180", "-5", "200"] {
            check_err(
                &format!("camera 0 0 1  0 0 0  0 1 0  {fov}"),
                1,
                "camera",
                "field of view must be between 0 and 180",
            );
        }
        check_err(
            "camera 1 1 1  1 1 1  0 1 0  45",
            1,
            "camera",
            "eye and the look-at point must differ",
        );
        check_err(
            "camera 0 0 0  0 1 0  0 2 0  45",
            1,
            "camera",
            "up vector must be non-zero and not parallel",
        );
        check_err(
            "camera 0 0 1  0 0 0  0 0 0  45",
            1,
            "camera",
            "up vector must be non-zero",
        );
    }

    #[test]
    fn bad_gamma() {
        check_err("gamma 0", 1, "gamma", "gamma must be positive, got 0");
        check_err("gamma -2.2", 1, "gamma", "gamma must be positive");
    }

    #[test]
    fn bad_spheres() {
        check_err(
            "sphere 0 0 0 0",
            1,
            "sphere",
            "the radius must be positive, got 0",
        );
        check_err(
            "sphere 0 0 0 -1",
            1,
            "sphere",
            "the radius must be positive, got -1",
        );
        check_err(
            "scale 1 0 1\nsphere 0 0 0 1",
            2,
            "sphere",
            "the current transform is singular",
        );
    }

    #[test]
    fn negative_colours() {
        for (line, keyword, what) in [
            ("diffuse -1 0 0", "diffuse", "the diffuse colour"),
            ("specular 0 -0.1 0", "specular", "the specular colour"),
            ("emission 0 0 -1", "emission", "the emission"),
            (
                "quadLight 0 0 0  1 0 0  0 1 0  1 1 -1",
                "quadLight",
                "the radiance",
            ),
            ("point 0 0 0  1 -1 1", "point", "the intensity"),
            ("directional 0 1 0  -1 1 1", "directional", "the radiance"),
        ] {
            check_err(line, 1, keyword, &format!("{what} must not be negative"));
        }
        check_err(
            "shininess -1",
            1,
            "shininess",
            "the shininess must not be negative, got -1",
        );
        check_err(
            "roughness -0.5",
            1,
            "roughness",
            "the roughness must not be negative, got -0.5",
        );
    }

    #[test]
    fn degenerate_quad_light() {
        check_err(
            "quadLight 0 0 0  1 0 0  2 0 0  1 1 1",
            1,
            "quadLight",
            "the quad is degenerate",
        );
        check_err(
            "quadLight 0 0 0  0 0 0  0 1 0  1 1 1",
            1,
            "quadLight",
            "degenerate",
        );
    }

    #[test]
    fn the_first_error_stops_parsing() {
        let e = parse_err("size 1 1\nspp x\nfrobnicate\n");
        assert_eq!((e.line, e.command.as_str()), (2, "spp"));
    }

    #[test]
    fn error_line_numbers_count_every_line() {
        check_err(
            "# one\n\n   \n# four\nsize 1 1 # five\nvertex 1 2\n",
            6,
            "vertex",
            "got 2",
        );
    }

    #[test]
    fn parse_file_reports_unreadable_files() {
        let path = std::env::temp_dir().join("lightpath-no-such-dir/missing.test");
        let Err(e) = parse_file(&path) else {
            panic!("parsed a missing file");
        };
        let name = path.display().to_string();
        assert_eq!(e.file, name);
        assert_eq!(e.line, 0);
        assert_eq!(e.command, "");
        assert!(e.message.starts_with("cannot read: "), "{e}");
        assert_eq!(e.to_string(), format!("{name}: {}", e.message));
    }

    #[test]
    fn parse_file_sets_the_source_and_names_the_file_in_errors() {
        let dir = std::env::temp_dir().join(format!("lightpath-parse-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("create a temporary directory");
        let good = dir.join("good.test");
        let bad = dir.join("bad.test");
        std::fs::write(&good, "size 2 3\n").expect("write a test file");
        std::fs::write(&bad, "size 2 3\nspp many\n").expect("write a test file");
        let scene = parse_file(&good).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(scene.source.as_deref(), Some(good.as_path()));
        assert_eq!((scene.width, scene.height), (2, 3));
        let Err(e) = parse_file(&bad) else {
            panic!("parsed a bad file");
        };
        assert_eq!(e.file, bad.display().to_string());
        assert_eq!(
            e.to_string(),
            format!(
                "{}:2: 'spp': expected an integer, got 'many'",
                bad.display()
            )
        );
        std::fs::remove_dir_all(&dir).ok();
    }

    // ---- scene files ----

    /// The repository root. `LIGHTPATH_ROOT` (read at compile time) points elsewhere
    /// when these tests are built outside the crate.
    fn repo_root() -> PathBuf {
        PathBuf::from(option_env!("LIGHTPATH_ROOT").unwrap_or(env!("CARGO_MANIFEST_DIR")))
    }

    /// All `*.test` files under `dir`, recursively, sorted.
    fn scene_files(dir: &Path) -> Vec<PathBuf> {
        let mut files = Vec::new();
        let mut pending = vec![dir.to_path_buf()];
        while let Some(dir) = pending.pop() {
            let entries = std::fs::read_dir(&dir)
                .unwrap_or_else(|e| panic!("cannot list {}: {e}", dir.display()));
            for entry in entries {
                let path = entry
                    .unwrap_or_else(|e| panic!("cannot list {}: {e}", dir.display()))
                    .path();
                if path.is_dir() {
                    pending.push(path);
                } else if path.extension().is_some_and(|x| x == "test") {
                    files.push(path);
                }
            }
        }
        files.sort();
        files
    }

    /// Parses every scene file under `dir`, failing with all errors at once.
    fn parse_all(dir: &Path, what: &str) -> Vec<(String, Scene)> {
        assert!(dir.is_dir(), "{what} not found at {}", dir.display());
        let files = scene_files(dir);
        assert!(!files.is_empty(), "no .test files in {}", dir.display());
        let mut scenes = Vec::new();
        let mut errors = Vec::new();
        for path in files {
            match parse_file(&path) {
                Ok(scene) => {
                    let name = path
                        .strip_prefix(dir)
                        .unwrap_or(&path)
                        .display()
                        .to_string();
                    scenes.push((name, scene));
                }
                Err(e) => errors.push(e.to_string()),
            }
        }
        assert!(
            errors.is_empty(),
            "scenes failed to parse:\n{}",
            errors.join("\n")
        );
        scenes
    }

    fn find<'a>(scenes: &'a [(String, Scene)], name: &str) -> &'a Scene {
        scenes
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, s)| s)
            .unwrap_or_else(|| panic!("{name} is missing"))
    }

    #[test]
    fn every_course_scene_parses() {
        let dir = repo_root().join("scenes/course");
        let scenes = parse_all(&dir, "the course scenes (scenes/course)");
        assert!(scenes.len() >= 14, "only {} course scenes", scenes.len());

        let name = "hw4/dragon.test";
        let dragon = find(&scenes, name);
        let n = dragon.triangles.len();
        assert!((100_000..100_010).contains(&n), "{name}: {n} triangles");
        assert_eq!(dragon.quad_lights.len(), 2, "{name}");
        assert!(
            dragon.materials.len() <= 4,
            "{name}: {} materials",
            dragon.materials.len()
        );

        let cornell = find(&scenes, "hw3/cornellSimple.test");
        assert_eq!(cornell.triangles.len(), 22 + 2);
        assert_eq!(cornell.spheres.len(), 1);
        assert_eq!(cornell.quad_lights.len(), 1);
        assert_eq!((cornell.width, cornell.height), (480, 480));
        assert_eq!(cornell.settings.spp, 64);
        assert_eq!(cornell.output.as_deref(), Some("cornellSimple.png"));

        let ggx = find(&scenes, "hw4/ggx.test");
        assert_eq!(ggx.spheres.len(), 6);
        assert_eq!(ggx.settings.max_depth, -1);
        assert_eq!(ggx.settings.gamma, 2.2);
        assert!(ggx.materials.iter().any(|m| m.bsdf == BsdfKind::Ggx));

        let mis = find(&scenes, "hw4/mis.test");
        assert_eq!(mis.quad_lights.len(), 5);
        assert_eq!(mis.settings.nee, NextEventEstimation::Mis);
        assert!(!mis.settings.russian_roulette);
    }

    /// The axis-aligned bounds of a scene's triangles.
    fn bounds(scene: &Scene) -> (Vec3, Vec3) {
        scene.triangles.iter().flat_map(|t| t.v).fold(
            (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
            |(lo, hi), p| (lo.min(p), hi.max(p)),
        )
    }

    #[test]
    fn every_project_scene_parses() {
        let dir = repo_root().join("scenes");
        let scenes = parse_all(&dir, "the project's scenes");
        for (name, s) in &scenes {
            assert!(!s.triangles.is_empty(), "{name}: no triangles");
            assert!(s.output.is_some(), "{name}: no output");
            assert!(
                s.materials.iter().any(Material::is_emissive) || !s.delta_lights.is_empty(),
                "{name}: no light"
            );
            for t in s.triangles.iter() {
                assert!(
                    normal(t).length() > 0.0,
                    "{name}: degenerate triangle {:?}",
                    t.v
                );
            }
        }

        for name in ["cornell-box.test", "cornell-glossy.test"] {
            let s = find(&scenes, name);
            assert_eq!((s.width, s.height), (256, 256), "{name}");
            assert_eq!(s.settings.integrator, IntegratorKind::PathTracer, "{name}");
            assert_eq!(s.settings.spp, 64, "{name}");
            assert_eq!(s.settings.max_depth, 5, "{name}");
            assert_eq!(s.settings.nee, NextEventEstimation::Mis, "{name}");
            assert_eq!(s.settings.importance_sampling, SampleMode::Brdf, "{name}");
            assert!(s.settings.russian_roulette, "{name}");
            assert_eq!(s.settings.gamma, 2.2, "{name}");
            assert_eq!(s.quad_lights.len(), 1, "{name}");
            assert_eq!(s.camera.eye, Vec3::new(0.0, 1.0, 3.0), "{name}");
            let (lo, hi) = bounds(s);
            close(lo, Vec3::new(-1.0, 0.0, -1.0));
            close(hi, Vec3::new(1.0, 2.0, 1.0));
            // The light's two triangles face down into the box.
            let lights: Vec<&crate::scene::TriangleCorners> = s
                .triangles
                .iter()
                .filter(|t| s.materials[t.material as usize].is_emissive())
                .collect();
            assert_eq!(lights.len(), 2, "{name}");
            for t in lights {
                close(normal(t).normalize(), -Vec3::Y);
            }
            // Spheres sit inside the box (they may touch the floor).
            let (lo, hi) = (lo - 1e-5, hi + 1e-5);
            for sphere in &s.spheres {
                let m = sphere.object_to_world;
                for p in [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z] {
                    let q = m.transform_point3(p);
                    assert!(
                        q.cmpgt(lo).all() && q.cmplt(hi).all(),
                        "{name}: a sphere pokes out at {q}"
                    );
                }
            }
        }
        let cornell = find(&scenes, "cornell-box.test");
        assert_eq!(cornell.output.as_deref(), Some("cornell-box.png"));
        assert_eq!(cornell.spheres.len(), 1);
        // 5 walls, a 12-triangle box and the light.
        assert_eq!(cornell.triangles.len(), 10 + 12 + 2);

        let glossy = find(&scenes, "cornell-glossy.test");
        assert_eq!(glossy.output.as_deref(), Some("cornell-glossy.png"));
        assert_eq!(glossy.spheres.len(), 2);
        let sphere_brdfs: Vec<BsdfKind> = glossy
            .spheres
            .iter()
            .map(|s| glossy.materials[s.material as usize].bsdf)
            .collect();
        assert!(sphere_brdfs.contains(&BsdfKind::Phong) && sphere_brdfs.contains(&BsdfKind::Ggx));

        let furnace = find(&scenes, "furnace.test");
        assert_eq!(furnace.output.as_deref(), Some("furnace.exr"));
        assert_eq!((furnace.width, furnace.height), (64, 64));
        assert_eq!(furnace.triangles.len(), 12);
        assert_eq!(furnace.spheres.len() + furnace.quad_lights.len(), 0);
        assert!(furnace.delta_lights.is_empty());
        assert_eq!(furnace.materials.len(), 1);
        let wall = furnace.materials[0];
        assert_eq!(wall.diffuse, Vec3::splat(0.5));
        assert_eq!(wall.specular, Vec3::ZERO);
        assert_eq!(wall.emission, Vec3::ONE);
        assert!(wall.two_sided_emission);
        let t = furnace.settings;
        assert_eq!(t.integrator, IntegratorKind::PathTracer);
        assert_eq!(t.max_depth, 3);
        assert_eq!(t.nee, NextEventEstimation::Off);
        assert_eq!(t.importance_sampling, SampleMode::Cosine);
        assert_eq!(t.spp, 16);
        let (lo, hi) = bounds(furnace);
        let eye = furnace.camera.eye;
        assert!(
            eye.cmpgt(lo).all() && eye.cmplt(hi).all(),
            "the camera is outside the furnace"
        );
        // Closed: each of the six faces of the bounding box holds two triangles.
        for axis in 0..3 {
            for plane in [lo[axis], hi[axis]] {
                let on_face = furnace
                    .triangles
                    .iter()
                    .filter(|t| t.v.iter().all(|p| p[axis] == plane))
                    .count();
                assert_eq!(on_face, 2, "face {axis} at {plane}");
            }
        }

        let two = find(&scenes, "two-lights.test");
        assert_eq!(two.output.as_deref(), Some("two-lights.png"));
        assert_eq!(two.quad_lights.len(), 2);
        let [l0, l1] = [two.quad_lights[0], two.quad_lights[1]];
        assert_ne!(l0.radiance, l1.radiance);
        assert_ne!(l0.ab.cross(l0.ac).length(), l1.ab.cross(l1.ac).length());
        assert!(matches!(two.delta_lights[..], [DeltaLight::Point { .. }]));
    }
}

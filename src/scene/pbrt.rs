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

use super::parse::MaterialKey;
use super::spectrum;
use super::{
    BsdfKind, Camera, DeltaLight, Environment, EnvironmentMap, IntegratorKind, Material,
    MaterialMix, NextEventEstimation, ParseError, SampleMode, Scene, Sphere, Texture, Triangle,
    MAX_MIX_DEPTH,
};
use crate::texture::{load_image, Encoding, EnvMapping, Projection, Wrap};
use glam::{Mat3, Mat4, Vec2, Vec3, Vec4};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The most files `Include` and `Import` may read (a file including itself stops here).
const MAX_FILES: usize = 4096;
/// The deepest `AttributeBegin` nesting.
const MAX_ATTRIBUTE_NESTING: usize = 1 << 16;
/// The types a parameter of this name may have, whatever the directive (pbrt-v4's
/// names are typed consistently), so that a value of the wrong type is an error rather
/// than a default.
const PARAM_TYPES: &[(&str, &[&str])] = &[
    ("P", &["point3"]),
    ("N", &["normal"]),
    ("uv", &["point2", "float"]),
    ("indices", &["integer"]),
    ("from", &["point3"]),
    ("to", &["point3"]),
    ("filename", &["string"]),
    ("type", &["string"]),
    ("encoding", &["string"]),
    ("wrap", &["string"]),
    ("mapping", &["string"]),
    ("v1", &["vector3"]),
    ("v2", &["vector3"]),
    ("sensor", &["string"]),
    ("twosided", &["bool"]),
    ("remaproughness", &["bool"]),
    ("invert", &["bool"]),
    ("fov", &["float", "integer"]),
    ("xresolution", &["integer"]),
    ("yresolution", &["integer"]),
    ("pixelsamples", &["integer"]),
    ("maxdepth", &["integer"]),
    ("nsamples", &["integer"]),
    ("mutationsperpixel", &["integer"]),
    ("chains", &["integer"]),
    ("bootstrapsamples", &["integer"]),
    ("radius", &["float", "integer"]),
    ("innerradius", &["float", "integer"]),
    ("height", &["float", "integer"]),
    ("zmin", &["float", "integer"]),
    ("zmax", &["float", "integer"]),
    ("phimax", &["float", "integer"]),
    ("coneangle", &["float", "integer"]),
    ("conedeltaangle", &["float", "integer"]),
    ("power", &["float", "integer"]),
    ("illuminance", &["float", "integer"]),
    ("iso", &["float", "integer"]),
    ("thickness", &["float", "integer", "texture"]),
    ("uscale", &["float", "integer"]),
    ("vscale", &["float", "integer"]),
    ("udelta", &["float", "integer"]),
    ("vdelta", &["float", "integer"]),
    ("dimension", &["integer"]),
    ("levels", &["integer"]),
    ("lensradius", &["float", "integer"]),
    ("screenwindow", &["float", "integer"]),
    ("frameaspectratio", &["float", "integer"]),
    ("cropwindow", &["float", "integer"]),
    ("pixelbounds", &["integer"]),
    ("focaldistance", &["float", "integer"]),
    ("sigma", &["float", "integer"]),
    ("largestepprobability", &["float", "integer"]),
    ("scale", &["float", "integer", "texture", "rgb", "spectrum"]),
    ("roughness", &["float", "integer", "texture"]),
    ("amount", &["float", "integer", "texture"]),
    ("materials", &["string"]),
    ("uroughness", &["float", "integer", "texture"]),
    ("vroughness", &["float", "integer", "texture"]),
    ("L", &["rgb", "spectrum", "blackbody"]),
    ("I", &["rgb", "spectrum", "blackbody"]),
];

/// The most triangles a `loopsubdiv` may make.
const MAX_SUBDIVIDED_TRIANGLES: f64 = 8_000_000.0;

/// Segments of a triangulated disk.
const DISK_SEGMENTS: usize = 128;

#[derive(Clone, Debug, PartialEq)]
enum Tok {
    Str(String),
    Num(f64),
    Word(String),
    Open,
    Close,
}

#[derive(Clone, Debug)]
struct Token {
    tok: Tok,
    file: u32,
    line: u32,
}

/// Splits a file's text into tokens: quoted strings (with pbrt's escapes), numbers,
/// words (directives, `true`/`false`) and brackets; `#` comments run to the line's end.
fn tokenize(text: &str, file: u32, name: &str) -> Result<Vec<Token>, ParseError> {
    let bytes = text.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    let mut line = 1u32;
    let err = |line: u32, message: String| ParseError {
        file: name.to_owned(),
        line: line as usize,
        command: String::new(),
        message,
    };
    while i < bytes.len() {
        let c = bytes[i];
        match c {
            b'\n' => {
                line += 1;
                i += 1;
            }
            c if c.is_ascii_whitespace() => i += 1,
            b'#' => {
                while i < bytes.len() && bytes[i] != b'\n' {
                    i += 1;
                }
            }
            b'[' | b']' => {
                out.push(Token {
                    tok: if c == b'[' { Tok::Open } else { Tok::Close },
                    file,
                    line,
                });
                i += 1;
            }
            b'"' => {
                let start_line = line;
                i += 1;
                let mut s = Vec::new();
                loop {
                    if i >= bytes.len() {
                        return Err(err(start_line, "unterminated string".into()));
                    }
                    match bytes[i] {
                        b'"' => break,
                        b'\n' => return Err(err(line, "a newline inside a quoted string".into())),
                        b'\\' if i + 1 < bytes.len() => {
                            i += 1;
                            s.push(match bytes[i] {
                                b'n' => b'\n',
                                b't' => b'\t',
                                b'b' => 8,
                                b'f' => 12,
                                b'r' => b'\r',
                                other => other,
                            });
                        }
                        b => s.push(b),
                    }
                    i += 1;
                }
                i += 1;
                let s = String::from_utf8(s)
                    .map_err(|_| err(start_line, "a string that is not UTF-8".into()))?;
                out.push(Token {
                    tok: Tok::Str(s),
                    file,
                    line: start_line,
                });
            }
            _ => {
                let start = i;
                while i < bytes.len()
                    && !bytes[i].is_ascii_whitespace()
                    && !matches!(bytes[i], b'"' | b'[' | b']' | b'#')
                {
                    i += 1;
                }
                let word = std::str::from_utf8(&bytes[start..i])
                    .map_err(|_| err(line, "a token that is not UTF-8".into()))?;
                let first = word.as_bytes()[0];
                let tok = if first.is_ascii_digit() || matches!(first, b'-' | b'+' | b'.') {
                    match word.parse::<f64>() {
                        Ok(x) if x.is_finite() => Tok::Num(x),
                        _ => return Err(err(line, format!("expected a number, got '{word}'"))),
                    }
                } else {
                    Tok::Word(word.to_owned())
                };
                out.push(Token { tok, file, line });
            }
        }
    }
    Ok(out)
}

/// One parameter of a directive: `"type name" value(s)`.
#[derive(Clone, Debug)]
struct Param {
    ty: String,
    name: String,
    nums: Vec<f64>,
    strs: Vec<String>,
    bools: Vec<bool>,
    line: u32,
    file: u32,
    used: std::cell::Cell<bool>,
}

/// A directive's parameter list, with the parameters it has read marked.
#[derive(Clone, Debug, Default)]
struct Params(Vec<Param>);

/// A value a material reads (a named texture's too): a constant or a texture of the scene.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Value {
    Const(Vec3),
    Texture(u32),
}

/// The part of the film that is rendered.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Crop {
    /// `cropwindow`: x0 x1 y0 y1 as fractions of the image ((0, 0) the top-left corner).
    Window([f32; 4]),
    /// `pixelbounds`: x0 x1 y0 y1 in pixels (the ends excluded).
    Pixels([i64; 4]),
}

/// An area light as declared (applies to the shapes that follow it).
#[derive(Clone, Debug)]
struct AreaLight {
    radiance: Vec3,
    two_sided: bool,
    /// pbrt-v4's `power` (W), which rescales the radiance by the shape's area.
    power: Option<f32>,
}

/// How deep mixes nest in a material (0: not a mix).
fn mix_depth(m: &MaterialRef) -> u32 {
    match m {
        MaterialRef::Mix(refs, _) => 1 + mix_depth(&refs[0]).max(mix_depth(&refs[1])),
        _ => 0,
    }
}

/// The material a shape uses.
#[derive(Clone, Debug)]
enum MaterialRef {
    Material(Material),
    /// `interface`: no surface (a boundary between media); its shapes are not rendered.
    Interface,
    /// `mix`: two materials and the second's probability (a constant or a float texture).
    Mix(Box<[MaterialRef; 2]>, Value),
}

#[derive(Clone, Debug)]
struct GraphicsState {
    ctm: Mat4,
    /// `ActiveTransform`: whether transform directives change the shutter-open transform,
    /// the one lightpath renders at (false after `ActiveTransform EndTime`: they change
    /// only the shutter-close one, which motion blur alone would use).
    start_active: bool,
    reverse: bool,
    material: MaterialRef,
    area: Option<AreaLight>,
    /// `Attribute` defaults: (target, parameter), the latest of a name first.
    attributes: Vec<(String, Param)>,
}

/// A shape as declared, in its object space, with what applies to it.
#[derive(Clone, Debug)]
struct ShapeDecl {
    kind: ShapeKind,
    ctm: Mat4,
    reverse: bool,
    material: MaterialRef,
    area: Option<AreaLight>,
    alpha: Option<super::Alpha>,
}

#[derive(Clone, Debug)]
enum ShapeKind {
    Mesh {
        p: Vec<Vec3>,
        indices: Vec<u32>,
        n: Option<Vec<Vec3>>,
        uv: Option<Vec<Vec2>>,
    },
    Sphere {
        radius: f32,
    },
}

struct Parser {
    scene: Scene,
    files: Vec<String>,
    tokens: Vec<Token>,
    pos: usize,
    /// The directory of the top file (Include/Import paths are relative to the
    /// including file's directory, as pbrt's).
    dirs: Vec<PathBuf>,
    gs: GraphicsState,
    stack: Vec<(GraphicsState, bool)>,
    named_coords: HashMap<String, Mat4>,
    named_materials: HashMap<String, MaterialRef>,
    textures: HashMap<String, Value>,
    float_textures: HashMap<String, Value>,
    material_lookup: HashMap<MaterialKey, u32>,
    image_textures: HashMap<(PathBuf, Encoding), Arc<crate::io::Image>>,
    objects: HashMap<String, Vec<ShapeDecl>>,
    /// The object being defined (ObjectBegin .. ObjectEnd).
    defining: Option<(String, Vec<ShapeDecl>)>,
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
    /// The film's `cropwindow` or `pixelbounds`, with the file and line that gave it.
    crop: Option<(Crop, u32, u32)>,
    /// The film's share of the imaging ratio: ISO / 100 times the film's `scale`.
    film_ratio: f32,
    /// pbrt-v4's exposure time: the camera's shutterclose − shutteropen (1 by default).
    exposure: f32,
    in_world: bool,
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
            area: None,
            attributes: Vec::new(),
        },
        stack: Vec::new(),
        named_coords: HashMap::new(),
        named_materials: HashMap::new(),
        textures: HashMap::new(),
        float_textures: HashMap::new(),
        material_lookup: HashMap::new(),
        image_textures: HashMap::new(),
        objects: HashMap::new(),
        defining: None,
        unsupported: Vec::new(),
        warned: Default::default(),
        warnings: Vec::new(),
        camera_seen: false,
        mlt_mutations: None,
        film_size: (1280, 720),
        screen_window: None,
        frame_aspect: None,
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
    p.run()?;
    p.finish()
}

fn diffuse(kd: Vec3) -> Material {
    Material {
        bsdf: BsdfKind::Phong,
        diffuse: kd,
        specular: Vec3::ZERO,
        ..Material::default()
    }
}

// Tests only: the parameter names each directive type asks for, whether or not the file
// gives them (`names_read`), to check them against pbrt-v4's own names.
#[cfg(test)]
thread_local! {
    static ASKED: std::cell::RefCell<Vec<String>> = const { std::cell::RefCell::new(Vec::new()) };
    static NAMES_READ: std::cell::RefCell<std::collections::BTreeSet<(String, String, String)>> =
        const { std::cell::RefCell::new(std::collections::BTreeSet::new()) };
}

impl Params {
    fn find(&self, name: &str) -> Option<&Param> {
        #[cfg(test)]
        ASKED.with(|a| a.borrow_mut().push(name.to_owned()));
        let p = self.0.iter().find(|p| p.name == name)?;
        p.used.set(true);
        Some(p)
    }
}

impl Parser {
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

    fn peek(&self) -> Option<&Token> {
        self.tokens.get(self.pos)
    }

    fn next_token(&mut self) -> Option<Token> {
        let t = self.tokens.get(self.pos).cloned();
        self.pos += 1;
        t
    }

    /// The line of the last token read (for messages at the end of input).
    fn here(&self) -> (u32, u32) {
        self.tokens
            .get(self.pos.saturating_sub(1))
            .map_or((0, 0), |t| (t.file, t.line))
    }

    /// "EXPECTED, got TOKEN" at the token, or "..., got the end of the file" at the last
    /// token read.
    fn unexpected(&self, got: Option<Token>, directive: &str, expected: &str) -> ParseError {
        match got {
            Some(t) => self.err_at(
                t.file,
                t.line,
                directive,
                format!("{expected}, got {}", describe(&t.tok)),
            ),
            None => {
                let (f, l) = self.here();
                self.err_at(
                    f,
                    l,
                    directive,
                    format!("{expected}, got the end of the file"),
                )
            }
        }
    }

    fn expect_string(&mut self, directive: &str, what: &str) -> Result<String, ParseError> {
        match self.next_token() {
            Some(Token {
                tok: Tok::Str(s), ..
            }) => Ok(s),
            t => Err(self.unexpected(t, directive, &format!("expected {what} (a quoted string)"))),
        }
    }

    /// `n` numbers, bracketed or not.
    fn numbers(&mut self, directive: &str, n: usize) -> Result<Vec<f32>, ParseError> {
        let bracketed = matches!(self.peek(), Some(Token { tok: Tok::Open, .. }));
        if bracketed {
            self.pos += 1;
        }
        let mut out = Vec::with_capacity(n);
        for _ in 0..n {
            match self.next_token() {
                Some(Token {
                    tok: Tok::Num(x), ..
                }) => out.push(x as f32),
                t => return Err(self.unexpected(t, directive, &format!("expected {n} numbers"))),
            }
        }
        if bracketed {
            match self.next_token() {
                Some(Token {
                    tok: Tok::Close, ..
                }) => {}
                t => {
                    let expected = format!("expected ']' after {n} numbers");
                    return Err(self.unexpected(t, directive, &expected));
                }
            }
        }
        Ok(out)
    }

    /// A parameter list: `"type name" value` or `"type name" [ values ]`, until the next
    /// directive.
    fn params(&mut self, directive: &str) -> Result<Params, ParseError> {
        let mut out = Vec::new();
        while let Some(Token {
            tok: Tok::Str(decl),
            file,
            line,
        }) = self.peek().cloned()
        {
            self.pos += 1;
            let words: Vec<&str> = decl.split_whitespace().collect();
            let [ty, name] = words[..] else {
                return Err(self.err_at(
                    file,
                    line,
                    directive,
                    format!("expected a parameter declaration \"type name\", got \"{decl}\""),
                ));
            };
            let ty = match ty {
                "point" => "point3",
                "vector" => "vector3",
                "normal3" => "normal",
                "color" => "rgb",
                t => t,
            };
            const TYPES: [&str; 13] = [
                "integer",
                "float",
                "point2",
                "vector2",
                "point3",
                "vector3",
                "normal",
                "rgb",
                "spectrum",
                "blackbody",
                "bool",
                "string",
                "texture",
            ];
            if !TYPES.contains(&ty) {
                return Err(self.err_at(
                    file,
                    line,
                    directive,
                    format!("unknown parameter type '{ty}' in \"{decl}\""),
                ));
            }
            let mut values = Vec::new();
            match self.next_token() {
                Some(Token { tok: Tok::Open, .. }) => loop {
                    match self.next_token() {
                        Some(Token {
                            tok: Tok::Close, ..
                        }) => break,
                        Some(Token {
                            tok: Tok::Open,
                            file,
                            line,
                        }) => {
                            return Err(self.err_at(
                                file,
                                line,
                                directive,
                                "a '[' inside a parameter's values",
                            ))
                        }
                        Some(t) => values.push(t),
                        None => {
                            return Err(self.err_at(
                                file,
                                line,
                                directive,
                                format!("parameter \"{decl}\": no ']' before the end of the file"),
                            ))
                        }
                    }
                },
                Some(
                    t @ Token {
                        tok: Tok::Num(_) | Tok::Str(_) | Tok::Word(_),
                        ..
                    },
                ) => values.push(t),
                t => {
                    let expected = format!("parameter \"{decl}\": expected a value");
                    return Err(self.unexpected(t, directive, &expected));
                }
            }
            let mut p = Param {
                ty: ty.to_owned(),
                name: name.to_owned(),
                nums: Vec::new(),
                strs: Vec::new(),
                bools: Vec::new(),
                line,
                file,
                used: std::cell::Cell::new(false),
            };
            for v in values {
                match (&v.tok, ty) {
                    (
                        Tok::Num(x),
                        "integer" | "float" | "point2" | "vector2" | "point3" | "vector3"
                        | "normal" | "rgb" | "blackbody" | "spectrum",
                    ) => {
                        if ty == "integer" && x.fract() != 0.0 {
                            return Err(self.err_at(
                                v.file,
                                v.line,
                                directive,
                                format!("parameter \"{decl}\": expected an integer, got {x}"),
                            ));
                        }
                        p.nums.push(*x);
                    }
                    (Tok::Str(s), "string" | "texture" | "spectrum") => p.strs.push(s.clone()),
                    (Tok::Word(w) | Tok::Str(w), "bool") if w == "true" || w == "false" => {
                        p.bools.push(w == "true")
                    }
                    (t, _) => {
                        return Err(self.err_at(
                            v.file,
                            v.line,
                            directive,
                            format!("parameter \"{decl}\": {} is not a {ty} value", describe(t)),
                        ))
                    }
                }
            }
            let count = p.nums.len() + p.strs.len() + p.bools.len();
            let per = match ty {
                "point2" | "vector2" => 2,
                "point3" | "vector3" | "normal" | "rgb" => 3,
                _ => 1,
            };
            if count == 0 || p.nums.len() % per != 0 {
                return Err(self.err_at(
                    file,
                    line,
                    directive,
                    format!(
                        "parameter \"{decl}\": expected a multiple of {per} values, got {count}"
                    ),
                ));
            }
            if ty == "spectrum" && !p.strs.is_empty() && !p.nums.is_empty() {
                return Err(self.err_at(
                    file,
                    line,
                    directive,
                    format!("parameter \"{decl}\": a spectrum is numbers or a name, not both"),
                ));
            }
            if let Some((_, allowed)) = PARAM_TYPES.iter().find(|(n, _)| *n == p.name) {
                if !allowed.contains(&p.ty.as_str()) {
                    return Err(self.err_at(
                        file,
                        line,
                        directive,
                        format!("parameter \"{decl}\": expected {}", allowed.join(" or ")),
                    ));
                }
            }
            if p.name == "uv" && p.nums.len() % 2 != 0 {
                return Err(self.err_at(
                    file,
                    line,
                    directive,
                    format!("parameter \"{decl}\": an odd number of values"),
                ));
            }
            out.push(p);
        }
        // A parameter given twice takes its last value, as in pbrt-v4 (whose dictionary
        // looks parameters up from the last).
        let mut kept: Vec<Param> = Vec::with_capacity(out.len());
        for p in out.into_iter().rev() {
            if kept.iter().any(|q| q.name == p.name) {
                let at = format!("{}:{}", self.files[p.file as usize], p.line);
                self.warn(
                    &format!("twice {at} {}", p.name),
                    format!(
                        "{at}: {directive}: parameter \"{}\" given twice; the last value is used",
                        p.name
                    ),
                );
                continue;
            }
            kept.push(p);
        }
        kept.reverse();
        Ok(Params(kept))
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

    /// The sensor's imaging ratio folded into every emitter: pbrt-v4's exposure time ×
    /// ISO / 100 (cie1931 sensor), times the film's `scale`.
    fn imaging_ratio(&self) -> f32 {
        self.film_ratio * self.exposure
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
                if ty != "perspective" {
                    self.unsupported(file, line, format!("Camera \"{ty}\""));
                }
                self.named_coords.insert("camera".into(), ctm.inverse());
                self.camera_seen = true;
                self.camera(ctm, &params, file, line)?;
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
                self.expect_string(d, "a name")?;
                self.params(d)?;
                self.unsupported(file, line, "MakeNamedMedium (participating media)");
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
                if !inside.is_empty() || !outside.is_empty() {
                    self.unsupported(file, line, "MediumInterface (participating media)");
                }
            }
            "Material" => {
                let ty = self.expect_string(d, "a material type")?;
                let params = self.params(d)?;
                let params = self.with_attributes("material", params);
                self.gs.material = self.material(&ty, &params, file, line)?;
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
                let m = self.material(&ty, &params, file, line)?;
                self.named_materials.insert(name, m);
            }
            "NamedMaterial" => {
                let name = self.expect_string(d, "a name")?;
                match self.named_materials.get(&name) {
                    Some(m) => self.gs.material = m.clone(),
                    None => {
                        return Err(self.err_at(
                            file,
                            line,
                            d,
                            format!("no material named \"{name}\""),
                        ))
                    }
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
                self.shape(&ty, &params, file, line)?;
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
                self.stack.push((self.gs.clone(), false));
                self.defining = Some((name, Vec::new()));
            }
            "ObjectEnd" => {
                let Some((name, shapes)) = self.defining.take() else {
                    return Err(self.err_at(file, line, d, "ObjectEnd without ObjectBegin"));
                };
                self.objects.insert(name, shapes);
                match self.stack.pop() {
                    Some((gs, _)) => self.gs = gs,
                    None => {
                        return Err(self.err_at(file, line, d, "without a matching ObjectBegin"))
                    }
                }
            }
            "ObjectInstance" => {
                let name = self.expect_string(d, "a name")?;
                let Some(shapes) = self.objects.get(&name).cloned() else {
                    return Err(self.err_at(file, line, d, format!("no object named \"{name}\"")));
                };
                for mut s in shapes {
                    s.ctm = ctm * s.ctm;
                    self.emit(s)?;
                }
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
        let base = self.dirs[file as usize].clone();
        let path = base.join(name);
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

    fn camera(
        &mut self,
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
        self.check_used("Camera", "\"perspective\"", params);
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

    fn film(&mut self, ty: &str, params: &Params, file: u32, line: u32) -> Result<(), ParseError> {
        if ty != "rgb" {
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
        if let Some(p) = params.find("sensor") {
            if p.strs.first().map(String::as_str) != Some("cie1931") {
                self.unsupported(p.file, p.line, "Film: a sensor other than cie1931");
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
        for name in ["diagonal", "savefp16", "maxcomponentvalue", "whitebalance"] {
            params.find(name);
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
    fn film_window(&mut self) -> Result<(), ParseError> {
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

    fn integrator(
        &mut self,
        ty: &str,
        params: &Params,
        file: u32,
        line: u32,
    ) -> Result<(), ParseError> {
        self.mlt_mutations = None;
        let s = &mut self.scene.settings;
        s.integrator = match ty {
            "path" | "volpath" => IntegratorKind::PathTracer,
            "bdpt" => IntegratorKind::Bdpt,
            "mlt" => IntegratorKind::Mmlt,
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

    /// A spectrum parameter as RGB (see spectrum.rs): `rgb` values, a `blackbody`
    /// temperature, sampled (λ, value) pairs, a named spectrum lightpath knows or an
    /// `.spd` file (relative to the file that names it). `emitted`: a light's spectrum
    /// (normalized to luminance 1, as pbrt-v4's lights); otherwise a bounded one.
    fn rgb(
        &mut self,
        p: &Param,
        directive: &str,
        emitted: bool,
    ) -> Result<Option<Vec3>, ParseError> {
        let bad = |this: &Self, msg: String| {
            this.err_at(
                p.file,
                p.line,
                directive,
                format!("parameter \"{} {}\": {msg}", p.ty, p.name),
            )
        };
        let sampled = |this: &Self, s: spectrum::Sampled| -> Result<Vec3, ParseError> {
            if emitted {
                s.emitted_rgb().map_err(|m| bad(this, m))
            } else {
                Ok(s.bounded_rgb())
            }
        };
        match p.ty.as_str() {
            "rgb" => Ok(Some(Vec3::new(
                p.nums[0] as f32,
                p.nums[1] as f32,
                p.nums[2] as f32,
            ))),
            "float" => Ok(Some(Vec3::splat(p.nums[0] as f32))),
            "blackbody" => {
                if p.nums.len() != 1 {
                    return Err(bad(
                        self,
                        format!("expected one temperature, got {} values", p.nums.len()),
                    ));
                }
                spectrum::blackbody_rgb(p.nums[0])
                    .map(Some)
                    .map_err(|m| bad(self, m))
            }
            "spectrum" if !p.strs.is_empty() => {
                if let Some(c) = named_spectrum(&p.strs[0]) {
                    return Ok(Some(c));
                }
                if !p.strs[0].to_ascii_lowercase().ends_with(".spd") {
                    self.unsupported(
                        p.file,
                        p.line,
                        format!("{directive}: spectrum \"{}\"", p.strs[0]),
                    );
                    return Ok(None);
                }
                let path = self.dirs[p.file as usize].join(&p.strs[0]);
                let text = std::fs::read_to_string(&path)
                    .map_err(|e| bad(self, format!("cannot read {}: {e}", path.display())))?;
                let s = spectrum::Sampled::from_spd(&text)
                    .map_err(|m| bad(self, format!("{}: {m}", path.display())))?;
                sampled(self, s).map(Some)
            }
            "spectrum" => {
                let s = spectrum::Sampled::from_interleaved(&p.nums).map_err(|m| bad(self, m))?;
                sampled(self, s).map(Some)
            }
            _ => Err(self.err_at(
                p.file,
                p.line,
                directive,
                format!(
                    "parameter \"{}\": expected rgb, spectrum or float, got {}",
                    p.name, p.ty
                ),
            )),
        }
    }

    /// A colour or float a material reads: a constant or a texture by name.
    fn value(
        &mut self,
        params: &Params,
        name: &str,
        float: bool,
        directive: &str,
    ) -> Result<Option<Value>, ParseError> {
        let Some(p) = params.find(name).cloned() else {
            return Ok(None);
        };
        if p.ty == "texture" {
            let table = if float {
                &self.float_textures
            } else {
                &self.textures
            };
            return match table.get(&p.strs[0]) {
                Some(&t) => Ok(Some(t)),
                None => Err(self.err_at(
                    p.file,
                    p.line,
                    directive,
                    format!(
                        "no {} texture named \"{}\"",
                        if float { "float" } else { "spectrum" },
                        p.strs[0]
                    ),
                )),
            };
        }
        Ok(self.rgb(&p, directive, false)?.map(Value::Const))
    }

    /// A texture's input as a texture made of textures holds it.
    fn operand(&self, v: Value) -> crate::texture::Operand {
        match v {
            Value::Const(c) => crate::texture::Operand::Const(c),
            Value::Texture(i) => {
                crate::texture::Operand::Texture(Box::new(self.scene.textures[i as usize].clone()))
            }
        }
    }

    /// Adds a texture made of textures, if its program fits the kernels'.
    fn graph_texture(&mut self, tex: Texture, file: u32, line: u32) -> Result<Value, ParseError> {
        let n = tex.program_length();
        if n > crate::abi::MAX_TEXTURE_PROGRAM as usize {
            return Err(self.err_at(
                file,
                line,
                "Texture",
                format!(
                    "a texture made of {n} textures (at most {} in one tree)",
                    crate::abi::MAX_TEXTURE_PROGRAM
                ),
            ));
        }
        self.scene.textures.push(tex);
        Ok(Value::Texture(self.scene.textures.len() as u32 - 1))
    }

    fn material(
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
            "interface" => {
                self.check_used(d, "\"interface\"", params);
                return Ok(MaterialRef::Interface);
            }
            "mix" => return self.mix_material(params, file, line),
            "diffuse" => {
                m = diffuse(Vec3::splat(0.5));
                match self.value(params, "reflectance", false, d)? {
                    Some(Value::Const(c)) => m.diffuse = c,
                    Some(Value::Texture(t)) => m.diffuse_texture = Some(t),
                    None => {}
                }
            }
            "coateddiffuse" => {
                m.bsdf = BsdfKind::CoatedDiffuse;
                m.diffuse = Vec3::splat(0.5);
                match self.value(params, "reflectance", false, d)? {
                    Some(Value::Const(c)) => m.diffuse = c,
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
                            if scale != 1.0 {
                                self.unsupported(
                                    file,
                                    line,
                                    format!("diffusetransmission: scale with a textured {name}"),
                                );
                            }
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
                conductor(self, &mut m, "", false)?;
            }
            other => {
                self.unsupported(file, line, format!("Material \"{other}\""));
                for p in &params.0 {
                    p.used.set(true);
                }
                return Ok(MaterialRef::Material(diffuse(Vec3::splat(0.5))));
            }
        }
        m.shading_map = self.shading_map(params, d)?;
        self.check_used(d, &format!("\"{ty}\""), params);
        Ok(MaterialRef::Material(m))
    }

    /// A material's `normalmap` (an image file, read as linear RGB, repeating) or else its
    /// `displacement` (a float texture), as pbrt-v4 prefers them.
    fn shading_map(
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
            let path = self.dirs[p.file as usize].join(name);
            let key = (path.clone(), Encoding::Linear);
            let image = match self.image_textures.get(&key) {
                Some(i) => i.clone(),
                None => {
                    let image =
                        Arc::new(load_image(&path, Encoding::Linear).map_err(|e| {
                            self.err_at(p.file, p.line, d, format!("normalmap: {e}"))
                        })?);
                    self.image_textures.insert(key, image.clone());
                    image
                }
            };
            self.scene.textures.push(Texture::Image {
                image,
                scale: Vec3::ONE,
                mapping: crate::texture::UV_MAPPING,
                wrap: Wrap::Repeat,
                projection: Projection::Uv,
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
    fn mix_material(
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
            match self.named_materials.get(name) {
                Some(MaterialRef::Interface) => {
                    self.unsupported(file, line, "mix: an interface material");
                    refs.push(MaterialRef::Material(diffuse(Vec3::splat(0.5))));
                }
                Some(m) => {
                    if mix_depth(m) >= MAX_MIX_DEPTH {
                        return Err(self.err_at(
                            file,
                            line,
                            d,
                            format!("mixes nest more than {MAX_MIX_DEPTH} deep"),
                        ));
                    }
                    refs.push(m.clone())
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

    /// The scene's index of a shape's material, with the emission of its area light (a
    /// mix's materials carry it too, since the kernels resolve a mix to one of them).
    fn intern_ref(&mut self, r: &MaterialRef, emission: Option<(Vec3, bool)>) -> u32 {
        let mut m = match r {
            MaterialRef::Material(m) => *m,
            MaterialRef::Interface => diffuse(Vec3::splat(0.5)),
            MaterialRef::Mix(refs, amount) => {
                let materials = [
                    self.intern_ref(&refs[0], emission),
                    self.intern_ref(&refs[1], emission),
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
        self.intern(m)
    }

    fn texture(
        &mut self,
        name: &str,
        ty: &str,
        class: &str,
        params: &Params,
        file: u32,
        line: u32,
    ) -> Result<(), ParseError> {
        let d = "Texture";
        let float = match ty {
            "float" => true,
            "spectrum" | "color" => false,
            other => {
                return Err(self.err_at(
                    file,
                    line,
                    d,
                    format!("expected \"spectrum\" or \"float\", got \"{other}\""),
                ))
            }
        };
        let num = |n: &str, default: f64| {
            params
                .find(n)
                .and_then(|p| p.nums.first().copied())
                .unwrap_or(default) as f32
        };
        // Only pbrt-v4's 2D-mapped textures read a mapping.
        let mapped = matches!(class, "imagemap" | "checkerboard" | "dots" | "bilerp");
        let mapping = if mapped {
            [
                num("uscale", 1.0),
                num("vscale", 1.0),
                num("udelta", 0.0),
                num("vdelta", 0.0),
            ]
        } else {
            [1.0, 1.0, 0.0, 0.0]
        };
        // pbrt-v4's TextureMapping2D: uv, or the point in texture space (the inverse of
        // the transform in force here).
        let texture_from_world = self.gs.ctm.inverse();
        let mut projection = Projection::Uv;
        if let Some(p) = mapped.then(|| params.find("mapping")).flatten() {
            match p.strs.first().map(String::as_str) {
                Some("uv") => {}
                Some("spherical") => projection = Projection::Spherical { texture_from_world },
                Some("cylindrical") => projection = Projection::Cylindrical { texture_from_world },
                Some("planar") => {
                    let axis = |name: &str, default: Vec3| {
                        params
                            .find(name)
                            .filter(|p| p.nums.len() == 3)
                            .map(|p| {
                                Vec3::new(p.nums[0] as f32, p.nums[1] as f32, p.nums[2] as f32)
                            })
                            .unwrap_or(default)
                    };
                    let (vs, vt) = (axis("v1", Vec3::X), axis("v2", Vec3::Y));
                    let row = |v: Vec3, delta: f32| {
                        // delta + v · (texture_from_world p), as a row on (p, 1).
                        let r = texture_from_world.transpose() * v.extend(0.0);
                        r + Vec4::new(0.0, 0.0, 0.0, delta)
                    };
                    projection = Projection::Planar {
                        rows: [row(vs, num("udelta", 0.0)), row(vt, num("vdelta", 0.0))],
                    };
                }
                other => {
                    return Err(self.err_at(
                        p.file,
                        p.line,
                        d,
                        format!(
                        "expected a mapping uv, spherical, cylindrical or planar, got {other:?}"
                    ),
                    ))
                }
            }
        }
        if !texture_from_world.is_finite() && projection != Projection::Uv {
            return Err(self.err_at(file, line, d, "the texture's transform is singular"));
        }
        let value = match class {
            "constant" => match self.value(params, "value", float, d)? {
                Some(v) => v,
                None => Value::Const(Vec3::ONE),
            },
            "scale" => {
                let t = self
                    .value(params, "tex", float, d)?
                    .unwrap_or(Value::Const(Vec3::ONE));
                let s = self
                    .value(params, "scale", true, d)?
                    .unwrap_or(Value::Const(Vec3::ONE));
                // A leaf texture times a constant (or a grey constant times a float leaf)
                // is a scaled copy of the leaf; anything else is made of textures.
                let copy = match (t, s) {
                    (Value::Const(a), Value::Const(b)) => Some(Err(Value::Const(a * b.x))),
                    (Value::Texture(i), Value::Const(b)) => Some(Ok((i, b.x))),
                    (Value::Const(c), Value::Texture(i)) if c.x == c.y && c.y == c.z => {
                        Some(Ok((i, c.x)))
                    }
                    _ => None,
                };
                match copy {
                    Some(Err(v)) => v,
                    Some(Ok((i, k))) if !self.scene.textures[i as usize].is_graph() => {
                        let mut tex = self.scene.textures[i as usize].clone();
                        match &mut tex {
                            Texture::Image { scale, .. } => *scale *= k,
                            Texture::Checkerboard { even, odd, .. } => {
                                *even *= k;
                                *odd *= k;
                            }
                            Texture::Scale { .. } | Texture::Mix { .. } => unreachable!(),
                        }
                        self.scene.textures.push(tex);
                        Value::Texture(self.scene.textures.len() as u32 - 1)
                    }
                    _ => {
                        let tex = Texture::Scale {
                            tex: self.operand(t),
                            scale: self.operand(s),
                        };
                        self.graph_texture(tex, file, line)?
                    }
                }
            }
            "mix" => {
                let t1 = self
                    .value(params, "tex1", float, d)?
                    .unwrap_or(Value::Const(Vec3::ZERO));
                let t2 = self
                    .value(params, "tex2", float, d)?
                    .unwrap_or(Value::Const(Vec3::ONE));
                let amount = self
                    .value(params, "amount", true, d)?
                    .unwrap_or(Value::Const(Vec3::splat(0.5)));
                match (t1, t2, amount) {
                    (Value::Const(a), Value::Const(b), Value::Const(k)) => {
                        Value::Const((1.0 - k.x) * a + k.x * b)
                    }
                    _ => {
                        let tex = Texture::Mix {
                            tex1: self.operand(t1),
                            tex2: self.operand(t2),
                            amount: self.operand(amount),
                        };
                        self.graph_texture(tex, file, line)?
                    }
                }
            }
            "imagemap" => {
                let Some(p) = params.find("filename").cloned() else {
                    return Err(self.err_at(file, line, d, "imagemap: no \"string filename\""));
                };
                let path = self.dirs[file as usize].join(&p.strs[0]);
                let encoding = match params
                    .find("encoding")
                    .and_then(|p| p.strs.first().cloned())
                    .as_deref()
                {
                    None => {
                        let ext = path
                            .extension()
                            .map(|e| e.to_string_lossy().to_ascii_lowercase());
                        if matches!(ext.as_deref(), Some("png" | "tga")) {
                            Encoding::Srgb
                        } else {
                            Encoding::Linear
                        }
                    }
                    Some("sRGB") => Encoding::Srgb,
                    Some("linear") => Encoding::Linear,
                    Some(other) => {
                        self.unsupported(file, line, format!("imagemap: encoding \"{other}\""));
                        Encoding::Linear
                    }
                };
                let invert = params
                    .find("invert")
                    .is_some_and(|p| p.bools.first() == Some(&true));
                let wrap = match params.find("wrap") {
                    None => Wrap::Repeat,
                    Some(p) => match p.strs.first().map(String::as_str) {
                        Some("repeat") => Wrap::Repeat,
                        Some("clamp") => Wrap::Clamp,
                        Some("black") => Wrap::Black,
                        other => {
                            self.unsupported(
                                p.file,
                                p.line,
                                format!("imagemap: wrap {other:?} (lightpath reads repeat, clamp and black)"),
                            );
                            Wrap::Repeat
                        }
                    },
                };
                params.find("filter");
                params.find("maxanisotropy");
                let scale = num("scale", 1.0);
                let key = (path.clone(), encoding);
                let image = match self.image_textures.get(&key) {
                    Some(i) => i.clone(),
                    None => {
                        let image = Arc::new(
                            load_image(&path, encoding)
                                .map_err(|e| self.err_at(p.file, p.line, d, e))?,
                        );
                        self.image_textures.insert(key, image.clone());
                        image
                    }
                };
                // pbrt-v4's invert: max(0, 1 - scale · v), made once on the texels (the
                // same as after the lookup wherever scale · v <= 1, as in [0, 1] images).
                let (image, scale) = if invert {
                    let mut inverted = (*image).clone();
                    for p in &mut inverted.pixels {
                        *p = p.map(|v| (1.0 - scale * v).max(0.0));
                    }
                    (Arc::new(inverted), 1.0)
                } else {
                    (image, scale)
                };
                self.scene.textures.push(Texture::Image {
                    image,
                    scale: Vec3::splat(scale),
                    mapping,
                    wrap,
                    projection,
                });
                Value::Texture(self.scene.textures.len() as u32 - 1)
            }
            "checkerboard" => {
                let dim = params
                    .find("dimension")
                    .and_then(|p| p.nums.first().copied())
                    .unwrap_or(2.0);
                // The 3D checkerboard: pbrt-v4's TextureMapping3D, the point in the space
                // of the transform in force here (the 2D mapping parameters unused).
                let projection = if dim == 3.0 {
                    if !texture_from_world.is_finite() {
                        return Err(self.err_at(
                            file,
                            line,
                            d,
                            "the texture's transform is singular",
                        ));
                    }
                    Projection::Solid { texture_from_world }
                } else {
                    if dim != 2.0 {
                        return Err(self.err_at(
                            file,
                            line,
                            d,
                            format!("checkerboard: dimension must be 2 or 3, got {dim}"),
                        ));
                    }
                    projection
                };
                let even = self
                    .value(params, "tex1", float, d)?
                    .unwrap_or(Value::Const(Vec3::ONE));
                let odd = self
                    .value(params, "tex2", float, d)?
                    .unwrap_or(Value::Const(Vec3::ZERO));
                match (even, odd) {
                    (Value::Const(even), Value::Const(odd)) => {
                        self.scene.textures.push(Texture::Checkerboard {
                            even,
                            odd,
                            mapping,
                            projection,
                        });
                        Value::Texture(self.scene.textures.len() as u32 - 1)
                    }
                    _ => {
                        self.unsupported(file, line, "checkerboard of textures");
                        Value::Const(Vec3::splat(0.5))
                    }
                }
            }
            other => {
                self.unsupported(file, line, format!("Texture \"{other}\""));
                for p in &params.0 {
                    p.used.set(true);
                }
                Value::Const(Vec3::splat(0.5))
            }
        };
        self.check_used(d, &format!("\"{class}\""), params);
        let table = if float {
            &mut self.float_textures
        } else {
            &mut self.textures
        };
        table.insert(name.to_owned(), value);
        Ok(())
    }

    /// A light's colour: `name`'s RGB times `scale`, times the film's imaging ratio.
    fn light_colour(
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

    fn light(&mut self, ty: &str, params: &Params, file: u32, line: u32) -> Result<(), ParseError> {
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
                        let path = self.dirs[p.file as usize].join(&p.strs[0]);
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
                self.scene.environment = Some(match self.scene.environment.take() {
                    None => light,
                    Some(before) if before.portal.is_some() || light.portal.is_some() => {
                        self.unsupported(
                            file,
                            line,
                            "a portal light and another infinite light (a portal light is read alone)",
                        );
                        before
                    }
                    Some(before) => match add_environments(before, light) {
                        Ok(sum) => sum,
                        Err(before) => {
                            self.unsupported(
                                file,
                                line,
                                "a second infinite light with an image map (one map and any number of constant ones are read)",
                            );
                            before
                        }
                    },
                });
            }
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

    fn area_light(
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

    fn shape(&mut self, ty: &str, params: &Params, file: u32, line: u32) -> Result<(), ParseError> {
        let d = "Shape";
        let vec3s = |p: &Param| {
            p.nums
                .chunks(3)
                .map(|c| Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32))
                .collect::<Vec<_>>()
        };
        let kind = match ty {
            "trianglemesh" | "bilinearmesh" => {
                let Some(pp) = params.find("P") else {
                    return Err(self.err_at(file, line, d, format!("{ty}: no \"point3 P\"")));
                };
                let p = vec3s(pp);
                let corners = if ty == "trianglemesh" { 3 } else { 4 };
                let mut indices: Vec<u32> = match params.find("indices") {
                    Some(ip) => {
                        if let Some(bad) = ip.nums.iter().find(|&&x| x < 0.0) {
                            return Err(self.err_at(ip.file, ip.line, d, format!("{ty}: a negative index {bad}")));
                        }
                        ip.nums.iter().map(|&x| x as u32).collect()
                    }
                    None if p.len() == corners => (0..corners as u32).collect(),
                    None => return Err(self.err_at(file, line, d, format!("{ty}: no \"integer indices\" (needed unless there are exactly {corners} points)"))),
                };
                if indices.len() % corners != 0 {
                    return Err(self.err_at(
                        file,
                        line,
                        d,
                        format!(
                            "{ty}: {} indices, not a multiple of {corners}",
                            indices.len()
                        ),
                    ));
                }
                if let Some(bad) = indices.iter().find(|&&i| i as usize >= p.len()) {
                    return Err(self.err_at(
                        file,
                        line,
                        d,
                        format!("{ty}: index {bad} out of range ({} points)", p.len()),
                    ));
                }
                let n = match params.find("N") {
                    Some(np) => {
                        let n = vec3s(np);
                        if n.len() != p.len() {
                            return Err(self.err_at(
                                np.file,
                                np.line,
                                d,
                                format!("{ty}: {} normals for {} points", n.len(), p.len()),
                            ));
                        }
                        Some(n)
                    }
                    None => None,
                };
                let uv = match params.find("uv") {
                    Some(up) => {
                        let uv: Vec<Vec2> = up
                            .nums
                            .chunks(2)
                            .map(|c| Vec2::new(c[0] as f32, c[1] as f32))
                            .collect();
                        if uv.len() != p.len() {
                            return Err(self.err_at(
                                up.file,
                                up.line,
                                d,
                                format!("{ty}: {} uv for {} points", uv.len(), p.len()),
                            ));
                        }
                        Some(uv)
                    }
                    None => None,
                };
                if corners == 4 {
                    // A bilinear patch p00 p10 p01 p11 as two triangles (exact when planar).
                    indices = indices
                        .chunks(4)
                        .flat_map(|q| [q[0], q[1], q[3], q[0], q[3], q[2]])
                        .collect();
                }
                params.find("faceIndices");
                if corners == 3 {
                    params.find("S");
                }
                ShapeKind::Mesh { p, indices, n, uv }
            }
            "loopsubdiv" => {
                let Some(pp) = params.find("P") else {
                    return Err(self.err_at(file, line, d, "loopsubdiv: no \"point3 P\""));
                };
                let p = vec3s(pp);
                let Some(ip) = params.find("indices") else {
                    return Err(self.err_at(file, line, d, "loopsubdiv: no \"integer indices\""));
                };
                if let Some(bad) = ip.nums.iter().find(|&&x| x < 0.0) {
                    return Err(self.err_at(
                        ip.file,
                        ip.line,
                        d,
                        format!("loopsubdiv: a negative index {bad}"),
                    ));
                }
                let indices: Vec<u32> = ip.nums.iter().map(|&x| x as u32).collect();
                let levels = params
                    .find("levels")
                    .and_then(|lp| lp.nums.first().copied())
                    .unwrap_or(3.0);
                // Each level multiplies the triangles by 4.
                let triangles = (indices.len() / 3) as f64 * 4f64.powf(levels.max(0.0));
                if !(0.0..=12.0).contains(&levels) || triangles > MAX_SUBDIVIDED_TRIANGLES {
                    return Err(self.err_at(file, line, d, format!("loopsubdiv: {levels} levels would make {triangles} triangles (at most {MAX_SUBDIVIDED_TRIANGLES})")));
                }
                let (p, indices, n) = super::subdiv::loop_subdivide(&p, &indices, levels as u32)
                    .map_err(|e| self.err_at(file, line, d, format!("loopsubdiv: {e}")))?;
                ShapeKind::Mesh {
                    p,
                    indices,
                    n: Some(n),
                    uv: None,
                }
            }
            "plymesh" => {
                let Some(fp) = params.find("filename").cloned() else {
                    return Err(self.err_at(file, line, d, "plymesh: no \"string filename\""));
                };
                let path = self.dirs[fp.file as usize].join(&fp.strs[0]);
                let mesh =
                    super::ply::read_ply(&path).map_err(|e| self.err_at(fp.file, fp.line, d, e))?;
                // (displacement is refused below, with every shape's; its edge length
                // then does not matter.)
                params.find("edgelength");
                ShapeKind::Mesh {
                    p: mesh.p,
                    indices: mesh.indices,
                    n: mesh.n,
                    uv: mesh.uv,
                }
            }
            "sphere" => {
                let radius = params
                    .find("radius")
                    .and_then(|p| p.nums.first().copied())
                    .unwrap_or(1.0) as f32;
                if !(radius > 0.0) {
                    return Err(self.err_at(
                        file,
                        line,
                        d,
                        format!("sphere: radius must be positive, got {radius}"),
                    ));
                }
                for (name, full) in [("zmin", -radius), ("zmax", radius), ("phimax", 360.0)] {
                    if let Some(p) = params.find(name) {
                        let x = p.nums.first().copied().unwrap_or(full as f64) as f32;
                        let whole = if name == "zmin" {
                            x <= -radius
                        } else {
                            x >= full
                        };
                        if !whole {
                            self.unsupported(
                                p.file,
                                p.line,
                                format!("sphere: {name} (a partial sphere)"),
                            );
                        }
                    }
                }
                ShapeKind::Sphere { radius }
            }
            "disk" => {
                let num = |n: &str, default: f64| {
                    params
                        .find(n)
                        .and_then(|p| p.nums.first().copied())
                        .unwrap_or(default) as f32
                };
                let (radius, inner, height) = (
                    num("radius", 1.0),
                    num("innerradius", 0.0),
                    num("height", 0.0),
                );
                if let Some(p) = params.find("phimax") {
                    if p.nums.first().copied().unwrap_or(360.0) < 360.0 {
                        self.unsupported(p.file, p.line, "disk: phimax (a partial disk)");
                    }
                }
                if !(radius > 0.0 && inner >= 0.0 && inner < radius) {
                    return Err(self.err_at(file, line, d, "disk: need 0 <= innerradius < radius"));
                }
                // An annulus of DISK_SEGMENTS quads (or a fan), normal +z as pbrt's.
                let mut p = Vec::new();
                let mut uv = Vec::new();
                let mut indices = Vec::new();
                for k in 0..DISK_SEGMENTS {
                    let phi = k as f32 / DISK_SEGMENTS as f32 * std::f32::consts::TAU;
                    let (s, c) = phi.sin_cos();
                    p.push(Vec3::new(radius * c, radius * s, height));
                    p.push(Vec3::new(inner * c, inner * s, height));
                    let u = k as f32 / DISK_SEGMENTS as f32;
                    uv.push(Vec2::new(u, 0.0));
                    uv.push(Vec2::new(u, 1.0 - inner / radius));
                }
                for k in 0..DISK_SEGMENTS as u32 {
                    let next = (k + 1) % DISK_SEGMENTS as u32;
                    let (o0, i0, o1, i1) = (2 * k, 2 * k + 1, 2 * next, 2 * next + 1);
                    indices.extend([o0, o1, i1]);
                    if inner > 0.0 {
                        indices.extend([o0, i1, i0]);
                    }
                }
                ShapeKind::Mesh {
                    p,
                    indices,
                    n: None,
                    uv: Some(uv),
                }
            }
            other => {
                self.unsupported(file, line, format!("Shape \"{other}\""));
                for p in &params.0 {
                    p.used.set(true);
                }
                return Ok(());
            }
        };
        // pbrt-v4's alpha: a float or a float texture; 1 (opaque) by default.
        let alpha = match self.value(params, "alpha", true, d)? {
            None => None,
            Some(Value::Const(c)) if c.x >= 1.0 => None,
            Some(Value::Const(c)) => Some(super::Alpha::Constant(c.x)),
            Some(Value::Texture(t)) => Some(super::Alpha::Texture(t)),
        };
        if alpha.is_some() {
            if matches!(kind, ShapeKind::Sphere { .. }) {
                self.unsupported(
                    file,
                    line,
                    "Shape \"sphere\": alpha (lightpath cuts out triangles only)",
                );
            }
            if self.gs.area.is_some() {
                self.unsupported(
                    file,
                    line,
                    format!("Shape \"{ty}\": alpha on an area light"),
                );
            }
        }
        let refused: &[&str] = match ty {
            "plymesh" => &["displacement"],
            "bilinearmesh" => &["emissionfilename"],
            _ => &[],
        };
        for &name in refused {
            if let Some(p) = params.find(name) {
                self.unsupported(p.file, p.line, format!("Shape \"{ty}\": {name}"));
            }
        }
        self.check_used(d, &format!("\"{ty}\""), params);
        let decl = ShapeDecl {
            kind,
            ctm: self.gs.ctm,
            reverse: self.gs.reverse,
            material: self.gs.material.clone(),
            area: self.gs.area.clone(),
            alpha,
        };
        if self.defining.is_some() {
            if decl.area.is_some() {
                self.unsupported(file, line, "an area light inside an object instance");
            }
            if let Some((_, shapes)) = &mut self.defining {
                shapes.push(decl);
            }
            return Ok(());
        }
        self.emit(decl)
    }

    fn intern(&mut self, m: Material) -> u32 {
        let materials = &mut self.scene.materials;
        *self
            .material_lookup
            .entry(MaterialKey::of(&m))
            .or_insert_with(|| {
                materials.push(m);
                (materials.len() - 1) as u32
            })
    }

    /// Adds a declared shape to the scene, in world space.
    fn emit(&mut self, s: ShapeDecl) -> Result<(), ParseError> {
        if matches!(s.material, MaterialRef::Interface) {
            return Ok(());
        }
        let ctm = s.ctm;
        let swaps = Mat3::from_mat4(ctm).determinant() < 0.0;
        let area = |tris: &[Triangle]| {
            tris.iter()
                .map(|t| 0.5 * (t.v[1] - t.v[0]).cross(t.v[2] - t.v[0]).length())
                .sum::<f32>()
        };
        match s.kind {
            ShapeKind::Mesh { p, indices, n, uv } => {
                let wp: Vec<Vec3> = p.iter().map(|&x| ctm.transform_point3(x)).collect();
                let normal_matrix = Mat3::from_mat4(ctm).inverse().transpose();
                let wn: Option<Vec<Vec3>> = n.map(|n| {
                    n.iter()
                        .map(|&x| {
                            let v = (normal_matrix * x).normalize_or_zero();
                            if s.reverse {
                                -v
                            } else {
                                v
                            }
                        })
                        .collect()
                });
                let mut tris = Vec::with_capacity(indices.len() / 3);
                for c in indices.chunks(3) {
                    let (a, b, cc) = (c[0] as usize, c[1] as usize, c[2] as usize);
                    let mut t = Triangle::new([wp[a], wp[b], wp[cc]], 0);
                    // pbrt's default uv for a triangle without them: (0,0), (1,0), (1,1).
                    t.uv = Some(match &uv {
                        Some(uv) => [uv[a], uv[b], uv[cc]],
                        None => [Vec2::ZERO, Vec2::X, Vec2::ONE],
                    });
                    t.alpha = s.alpha;
                    if (t.v[1] - t.v[0]).cross(t.v[2] - t.v[0]).length_squared() == 0.0 {
                        continue;
                    }
                    t = match &wn {
                        Some(wn) => {
                            t.normals = Some([wn[a], wn[b], wn[cc]]);
                            t.facing_its_normals()
                        }
                        // pbrt flips the geometric normal for reverse orientation or a
                        // transform that swaps handedness.
                        None if s.reverse ^ swaps => flip(t),
                        None => t,
                    };
                    tris.push(t);
                }
                let emission = s
                    .area
                    .as_ref()
                    .map(|a| (a.radiance * self.imaging_ratio(), a.two_sided));
                let power = s.area.as_ref().and_then(|a| {
                    a.power
                        .map(|phi| (phi, if a.two_sided { 2.0 } else { 1.0 }))
                });
                let index = self.intern_ref(&s.material, emission);
                for mut t in tris {
                    t.material = match (power, emission) {
                        // pbrt-v4 makes one light per triangle of a mesh, each emitting
                        // `power`: radiance power / (sides π area) per triangle.
                        (Some((phi, sides)), Some((e, two_sided))) => {
                            let scale = phi
                                / (sides * area(std::slice::from_ref(&t)) * std::f32::consts::PI);
                            self.intern_ref(&s.material, Some((e * scale, two_sided)))
                        }
                        _ => index,
                    };
                    self.scene.triangles.push(t);
                }
            }
            ShapeKind::Sphere { radius } => {
                let emission = s.area.as_ref().map(|a| {
                    let mut e = a.radiance * self.imaging_ratio();
                    if let Some(phi) = a.power {
                        let scale = Mat3::from_mat4(ctm);
                        let r = radius * scale.determinant().abs().cbrt();
                        let sides = if a.two_sided { 2.0 } else { 1.0 };
                        e *= phi
                            / (sides * 4.0 * std::f32::consts::PI * r * r * std::f32::consts::PI);
                    }
                    (e, a.two_sided)
                });
                let material = self.intern_ref(&s.material, emission);
                self.scene.spheres.push(Sphere {
                    object_to_world: ctm * Mat4::from_scale(Vec3::splat(radius)),
                    material,
                    inward: s.reverse ^ swaps,
                });
            }
        }
        Ok(())
    }

    fn finish(mut self) -> Result<Scene, ParseError> {
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
        let ratio = self.imaging_ratio();
        for l in &mut self.scene.delta_lights {
            match l {
                DeltaLight::Point { intensity, .. } | DeltaLight::Spot { intensity, .. } => {
                    *intensity *= ratio
                }
                DeltaLight::Directional { radiance, .. } => *radiance *= ratio,
            }
        }
        if let Some(e) = &mut self.scene.environment {
            e.radiance *= ratio;
        }
        Ok(self.scene)
    }
}

/// The triangle with its orientation reversed (its geometric normal flipped).
fn flip(mut t: Triangle) -> Triangle {
    t.v.swap(1, 2);
    if let Some(uv) = &mut t.uv {
        uv.swap(1, 2);
    }
    if let Some(n) = &mut t.normals {
        n.swap(1, 2);
    }
    t
}

/// Named spectra lightpath knows, as RGB (docs/scene-format.md): the metals' η and k at
/// the sRGB primaries' dominant wavelengths (about 610, 550 and 465 nm).
/// The illuminance an equal-area environment map (radiance in linear sRGB) gives a
/// surface facing its +z: the sum over the pixels above the horizon of their luminance
/// times cos θ times their solid angle (4π over the pixel count).
fn upper_hemisphere_illuminance(image: &crate::io::Image) -> f32 {
    let (w, h) = (image.width as usize, image.height as usize);
    let mut sum = 0.0f64;
    for y in 0..h {
        for x in 0..w {
            let uv = Vec2::new((x as f32 + 0.5) / w as f32, (y as f32 + 0.5) / h as f32);
            let z = crate::texture::equal_area_square_to_sphere(uv).z;
            if z > 0.0 {
                let p = image.pixels[y * w + x];
                let luminance = 0.212_672_9 * p[0] + 0.715_152_2 * p[1] + 0.072_175 * p[2];
                sum += (luminance * z) as f64;
            }
        }
    }
    (sum * 4.0 * std::f64::consts::PI / (w * h) as f64) as f32
}

fn named_spectrum(name: &str) -> Option<Vec3> {
    Some(match name {
        "metal-Cu-eta" => super::COPPER_ETA,
        "metal-Cu-k" => super::COPPER_K,
        "metal-Au-eta" => Vec3::new(0.143_119, 0.374_957, 1.442_48),
        "metal-Au-k" => Vec3::new(3.983_16, 2.385_72, 1.603_22),
        "metal-Ag-eta" => Vec3::new(0.155_265, 0.116_723, 0.138_342),
        "metal-Ag-k" => Vec3::new(4.828_35, 3.122_25, 2.146_96),
        "metal-Al-eta" => Vec3::new(1.657_46, 0.880_369, 0.521_229),
        "metal-Al-k" => Vec3::new(9.223_87, 6.269_52, 4.837),
        "glass-BK7" => Vec3::splat(1.5168),
        "glass-BAF10" => Vec3::splat(1.67),
        "glass-F11" => Vec3::splat(1.62),
        _ => return None,
    })
}

fn describe(t: &Tok) -> String {
    match t {
        Tok::Str(s) => format!("\"{s}\""),
        Tok::Num(x) => format!("{x}"),
        Tok::Word(w) => format!("'{w}'"),
        Tok::Open => "'['".into(),
        Tok::Close => "']'".into(),
    }
}

/// Two infinite lights as one: constants add; a constant adds to each texel of a map
/// (scaled by the map's radiance), which is exact for the bilinear lookup and leaves the
/// map's sampling proportional to what it emits. Two maps cannot be one (Err: the first).
fn add_environments(a: Environment, b: Environment) -> Result<Environment, Environment> {
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

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Scene {
        parse_pbrt_str(text, "t.pbrt").unwrap_or_else(|e| panic!("{e}"))
    }

    fn parse_err(text: &str) -> ParseError {
        parse_pbrt_str(text, "t.pbrt").expect_err("should not parse")
    }

    const QUAD: &str = r#"Shape "trianglemesh" "point3 P" [ -1 -1 0  1 -1 0  1 1 0  -1 1 0 ]
        "integer indices" [ 0 1 2  0 2 3 ]"#;

    /// Every parameter name the reader asks for, for every directive type it reads, is
    /// one of pbrt-v4's own for that type (src/scene/data/pbrt-v4-parameters.txt, from
    /// its Create functions): a name pbrt-v4 does not know would make the reader accept
    /// what pbrt-v4 rejects and refuse what it accepts (a spot light's `conedelta` for
    /// `conedeltaangle`). The names asked for are recorded whether or not the file gives
    /// them, so each directive type is parsed once, with the parameters it needs.
    #[test]
    fn every_parameter_name_read_is_pbrt_v4s_own() {
        let table = include_str!("data/pbrt-v4-parameters.txt");
        let mut names: HashMap<(String, String), std::collections::HashSet<String>> =
            HashMap::new();
        for line in table
            .lines()
            .filter(|l| !l.starts_with('#') && !l.is_empty())
        {
            let (head, list) = line.split_once(':').expect("Directive type: names");
            let words: Vec<&str> = head.split_whitespace().collect();
            // "Texture float imagemap" and "Texture imagemap" are both "Texture imagemap".
            let key = (words[0].to_owned(), words[words.len() - 1].to_owned());
            let set = names.entry(key).or_default();
            for item in list.split_whitespace() {
                set.insert(item.split(':').next().expect("name:kind").to_owned());
            }
        }
        // MakeNamedMaterial's "type" is read for every material.
        for ((d, _), set) in names.iter_mut() {
            if d == "Material" {
                set.insert("type".to_owned());
            }
        }
        let world = |body: &str| format!("WorldBegin\n{body}\n");
        let mut files = vec![
            "Camera \"perspective\"\nWorldBegin\n".to_owned(),
            "Film \"rgb\"\nWorldBegin\n".to_owned(),
            "Film \"gbuffer\"\nWorldBegin\n".to_owned(),
            "Film \"spectral\"\nWorldBegin\n".to_owned(),
            world("AreaLightSource \"diffuse\"\nShape \"sphere\""),
            world(QUAD),
            world(
                "Shape \"bilinearmesh\" \"point3 P\" [ 0 0 0  1 0 0  0 1 0  1 1 0 ] \"integer indices\" [ 0 1 2 3 ]",
            ),
            world(
                "Shape \"loopsubdiv\" \"point3 P\" [ 0 0 0  1 0 0  0 1 0 ] \"integer indices\" [ 0 1 2 ]",
            ),
        ];
        for ty in [
            "path",
            "volpath",
            "bdpt",
            "mlt",
            "simplepath",
            "lightpath",
            "sppm",
        ] {
            files.push(format!("Integrator \"{ty}\"\nWorldBegin\n"));
        }
        for ty in [
            "point",
            "spot",
            "distant",
            "infinite",
            "goniometric",
            "projection",
        ] {
            files.push(world(&format!("LightSource \"{ty}\"")));
        }
        for ty in ["sphere", "disk", "cylinder", "curve", "plymesh"] {
            files.push(world(&format!("Shape \"{ty}\"")));
        }
        for ty in [
            "diffuse",
            "dielectric",
            "thindielectric",
            "conductor",
            "coateddiffuse",
            "coatedconductor",
            "diffusetransmission",
            "measured",
            "interface",
            "hair",
            "subsurface",
        ] {
            files.push(world(&format!("Material \"{ty}\"")));
            files.push(world(&format!(
                "MakeNamedMaterial \"m\" \"string type\" \"{ty}\""
            )));
        }
        files.push(world(
            "MakeNamedMaterial \"a\" \"string type\" \"diffuse\"\n\
             Material \"mix\" \"string materials\" [ \"a\" \"a\" ]",
        ));
        for ty in ["float", "spectrum"] {
            for class in [
                "constant",
                "scale",
                "mix",
                "directionmix",
                "checkerboard",
                "dots",
                "fbm",
                "wrinkled",
                "windy",
                "marble",
                "bilerp",
                "ptex",
            ] {
                files.push(world(&format!("Texture \"t\" \"{ty}\" \"{class}\"")));
            }
            files.push(world(&format!(
                "Texture \"t\" \"{ty}\" \"imagemap\" \"string filename\" \"missing.png\""
            )));
        }
        NAMES_READ.with(|r| r.borrow_mut().clear());
        for f in &files {
            let _ = parse_pbrt_str(f, "names.pbrt");
        }
        let read = NAMES_READ.with(|r| r.borrow().clone());
        let mut foreign = Vec::new();
        // Names the published scenes use that an earlier pbrt-v4 read (Film "scale", which
        // multiplied the image; the path integrator's Russian roulette "rrthreshold").
        let earlier = [("Film", "scale"), ("Integrator", "rrthreshold")];
        for (d, ty, name) in &read {
            let known = names
                .get(&(d.clone(), ty.clone()))
                .is_some_and(|set| set.contains(name))
                || earlier.contains(&(d.as_str(), name.as_str()));
            if !known {
                foreign.push(format!("{d} \"{ty}\": \"{name}\""));
            }
        }
        assert!(
            foreign.is_empty(),
            "the reader asks for names pbrt-v4 does not read:\n{}",
            foreign.join("\n")
        );
        // (The check has teeth: the directives it covers were read.)
        for (d, ty) in [
            ("LightSource", "spot"),
            ("Shape", "sphere"),
            ("Material", "coateddiffuse"),
            ("Film", "rgb"),
        ] {
            assert!(
                read.iter().any(|(a, b, _)| a == d && b == ty),
                "no names recorded for {d} {ty}"
            );
        }
    }

    /// imagemap's `wrap` (repeat, clamp, black), `invert` (max(0, 1 - scale v), made on the
    /// texels) and `mapping`; octahedralsphere is refused.
    #[test]
    fn imagemap_wrap_modes_invert_and_mappings() {
        let d = std::env::temp_dir().join(format!("lightpath-wrap-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        let mut pfm = b"PF\n2 1\n-1.0\n".to_vec();
        for v in [0.2f32, 0.2, 0.2, 3.0, 3.0, 3.0] {
            pfm.extend(v.to_le_bytes());
        }
        std::fs::write(d.join("t.pfm"), pfm).unwrap();
        let text = |extra: &str| {
            format!(
                "WorldBegin\nTexture \"t\" \"spectrum\" \"imagemap\" \"string filename\" \"t.pfm\" {extra}\n\
                 Material \"diffuse\" \"texture reflectance\" \"t\"\n{QUAD}\n"
            )
        };
        let image = |extra: &str| {
            std::fs::write(d.join("s.pbrt"), text(extra)).unwrap();
            let s = parse_pbrt_file(&d.join("s.pbrt")).unwrap_or_else(|e| panic!("{e}"));
            match &s.textures[0] {
                Texture::Image {
                    image, scale, wrap, ..
                } => (image.pixels.clone(), *scale, *wrap),
                other => panic!("{other:?}"),
            }
        };
        let (pixels, scale, wrap) = image("");
        assert_eq!(
            (pixels[1], scale, wrap),
            ([3.0; 3], Vec3::ONE, Wrap::Repeat)
        );
        assert_eq!(image("\"string wrap\" \"clamp\"").2, Wrap::Clamp);
        assert_eq!(image("\"string wrap\" \"black\"").2, Wrap::Black);
        let (pixels, scale, _) = image("\"bool invert\" true \"float scale\" 0.5");
        assert_eq!(scale, Vec3::ONE);
        assert_eq!(pixels, vec![[0.9; 3], [0.0; 3]]);
        // Mappings: spherical and cylindrical about the texture's own space (the inverse
        // of the transform in force), planar with v1, v2, udelta, vdelta; another, an error.
        let projection = |extra: &str, transform: &str| {
            let t = text(extra).replacen("WorldBegin\n", &format!("WorldBegin\n{transform}\n"), 1);
            std::fs::write(d.join("s.pbrt"), t).unwrap();
            let s = parse_pbrt_file(&d.join("s.pbrt")).unwrap_or_else(|e| panic!("{e}"));
            match &s.textures[0] {
                Texture::Image { projection, .. } => *projection,
                other => panic!("{other:?}"),
            }
        };
        assert_eq!(projection("", ""), Projection::Uv);
        let moved = Mat4::from_translation(Vec3::new(1.0, 2.0, 3.0)).inverse();
        assert_eq!(
            projection("\"string mapping\" \"spherical\"", "Translate 1 2 3"),
            Projection::Spherical {
                texture_from_world: moved
            }
        );
        assert_eq!(
            projection("\"string mapping\" \"cylindrical\"", "Translate 1 2 3"),
            Projection::Cylindrical {
                texture_from_world: moved
            }
        );
        let planar = projection(
            "\"string mapping\" \"planar\" \"vector3 v1\" [ 0 0 2 ] \"float udelta\" 0.5 \"float vdelta\" -1",
            "Translate 1 2 3",
        );
        let p = Vec3::new(0.3, -0.4, 5.0);
        // s = 0.5 + (0, 0, 2) . (p - (1, 2, 3)), t = -1 + (0, 1, 0) . (p - (1, 2, 3)).
        assert!(
            (planar.st(&[1.0, 1.0, 0.0, 0.0], Vec2::ZERO, p) - Vec2::new(4.5, -3.4)).length()
                < 1e-5,
            "{planar:?}"
        );
        std::fs::write(d.join("s.pbrt"), text("\"string mapping\" \"conical\"")).unwrap();
        let e = parse_pbrt_file(&d.join("s.pbrt")).expect_err("conical");
        assert!(e.message.contains("expected a mapping"), "{e}");
        std::fs::write(
            d.join("s.pbrt"),
            text("\"string wrap\" \"octahedralsphere\""),
        )
        .unwrap();
        let e = parse_pbrt_file(&d.join("s.pbrt")).expect_err("octahedralsphere");
        assert!(e.message.contains("octahedralsphere"), "{e}");
        std::fs::remove_dir_all(&d).ok();
    }

    /// Several infinite lights: constants add, a constant adds to a map's texels (times
    /// the map's scale), and a second map is refused.
    #[test]
    fn several_infinite_lights_add() {
        let s = parse(
            "WorldBegin\nLightSource \"infinite\" \"rgb L\" [ 0.1 0.2 0.3 ]\n\
             LightSource \"infinite\" \"rgb L\" [ 1 1 2 ]\n",
        );
        let e = s.environment.expect("an environment");
        assert!(e.map.is_none() && (e.radiance - Vec3::new(1.1, 1.2, 2.3)).length() < 1e-6);
        let d = std::env::temp_dir().join(format!("lightpath-envs-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        let mut pfm = b"PF\n2 2\n-1.0\n".to_vec();
        for v in [1.0f32, 2.0, 3.0, 4.0].iter().flat_map(|&x| [x, x, x]) {
            pfm.extend(v.to_le_bytes());
        }
        std::fs::write(d.join("sky.pfm"), pfm).unwrap();
        let map = "LightSource \"infinite\" \"string filename\" \"sky.pfm\" \"float scale\" 2\n";
        let constant = "LightSource \"infinite\" \"rgb L\" [ 0.5 0.5 0.5 ]\n";
        for order in [format!("{map}{constant}"), format!("{constant}{map}")] {
            std::fs::write(d.join("s.pbrt"), format!("WorldBegin\n{order}")).unwrap();
            let s = parse_pbrt_file(&d.join("s.pbrt")).unwrap_or_else(|e| panic!("{e}"));
            let e = s.environment.expect("an environment");
            let m = e.map.expect("the map");
            assert_eq!(e.radiance, Vec3::ONE);
            let mut values: Vec<f32> = m.image.pixels.iter().map(|p| p[0]).collect();
            values.sort_by(f32::total_cmp);
            assert_eq!(values, vec![2.5, 4.5, 6.5, 8.5]);
        }
        std::fs::write(d.join("s.pbrt"), format!("WorldBegin\n{map}{map}")).unwrap();
        let e = parse_pbrt_file(&d.join("s.pbrt")).expect_err("two maps");
        assert!(e.message.contains("second infinite light"), "{e}");
        std::fs::remove_dir_all(&d).ok();
    }

    /// A parameter given twice takes its last value (pbrt-v4's lookup order), with a
    /// warning; a parameter given once is read as before.
    #[test]
    fn a_parameter_given_twice_takes_its_last_value() {
        let s = parse(&format!(
            r#"WorldBegin
            Material "diffuse" "rgb reflectance" [ 0.1 0.2 0.3 ] "rgb reflectance" [ 0.4 0.5 0.6 ]
            {QUAD}
            LightSource "point" "rgb I" [ 1 1 1 ] "point3 from" [ 0 1 0 ] "rgb I" [ 2 3 4 ]
            "#
        ));
        assert_eq!(s.materials[0].diffuse, Vec3::new(0.4, 0.5, 0.6));
        assert!(
            matches!(s.delta_lights[0], DeltaLight::Point { intensity, .. } if intensity == Vec3::new(2.0, 3.0, 4.0))
        );
    }

    /// An infinite light's `portal`: four points of a rectangle, under the transform; not
    /// a rectangle, too few points, or beside another infinite light: errors.
    #[test]
    fn a_portal_is_a_transformed_rectangle() {
        let s = parse(&format!(
            "WorldBegin\nTranslate 0 1 0\nLightSource \"infinite\" \"point3 portal\" [ 0 0 0  1 0 0  1 0 1  0 0 1 ]\n{QUAD}"
        ));
        let q = s
            .environment
            .as_ref()
            .and_then(|e| e.portal)
            .expect("a portal");
        assert_eq!(q[2], Vec3::new(1.0, 1.0, 1.0));
        for bad in [
            "\"point3 portal\" [ 0 0 0  1 0 0  1.5 0 1  0 0 1 ]",
            "\"point3 portal\" [ 0 0 0  1 0 0  1 0 1 ]",
        ] {
            let e = parse_err(&format!(
                "WorldBegin\nLightSource \"infinite\" {bad}\n{QUAD}"
            ));
            assert!(e.message.contains("portal"), "{e}");
        }
        let e = parse_err(&format!(
            "WorldBegin\nLightSource \"infinite\" \"point3 portal\" [ 0 0 0  1 0 0  1 0 1  0 0 1 ]\nLightSource \"infinite\"\n{QUAD}"
        ));
        assert!(e.to_string().contains("portal"), "{e}");
    }

    /// The published scenes' `rrthreshold` (an earlier pbrt-v4's) is read and ignored: it
    /// changes noise only.
    #[test]
    fn rrthreshold_is_accepted() {
        for ty in ["path", "volpath", "bdpt"] {
            parse(&format!(
                "Integrator \"{ty}\" \"float rrthreshold\" 0.5\nWorldBegin\n{QUAD}"
            ));
        }
    }

    /// pbrt-v4's imaging ratio: the exposure time (shutterclose − shutteropen) × ISO / 100,
    /// and the film's `scale` (the published scenes' pbrt-v4), multiply every emitter; a
    /// shutter that never opens is an error.
    #[test]
    fn exposure_iso_and_film_scale_scale_every_emitter() {
        let light = "LightSource \"point\" \"rgb I\" [ 1 2 3 ]\nLightSource \"infinite\" \"rgb L\" [ 1 1 1 ]\n";
        for (options, want) in [
            ("", 1.0),
            ("Camera \"perspective\" \"float shutteropen\" 0.25 \"float shutterclose\" 0.75\n", 0.5),
            ("Film \"rgb\" \"float iso\" 400 \"float scale\" 1.5\n", 6.0),
            (
                "Film \"rgb\" \"float scale\" 2\nCamera \"perspective\" \"float shutterclose\" 0.5\n",
                1.0,
            ),
        ] {
            let s = parse(&format!("{options}WorldBegin\n{light}{QUAD}"));
            let DeltaLight::Point { intensity, .. } = s.delta_lights[0] else {
                panic!("a point light")
            };
            assert!((intensity - want * Vec3::new(1.0, 2.0, 3.0)).length() < 1e-6, "{options}: {intensity}");
            let env = s.environment.as_ref().expect("the infinite light");
            assert!((env.radiance - Vec3::splat(want)).length() < 1e-6, "{options}");
        }
        let e =
            parse_err("Camera \"perspective\" \"float shutteropen\" 1 \"float shutterclose\" 1\n");
        assert!(e.message.contains("never opens"), "{e}");
        let e = parse_err("Film \"rgb\" \"float scale\" -1\n");
        assert!(e.message.contains("scale"), "{e}");
    }

    /// Animated transforms render at the shutter-open time: transforms after
    /// `ActiveTransform EndTime` leave the rendered (start) transform as it was, `StartTime`
    /// and `All` change it, and an attribute block restores which is active; the camera's
    /// shutter interval is read (a warning), a bad one an error.
    #[test]
    fn animated_transforms_render_at_the_shutter_open_time() {
        let s = parse(
            r#"Camera "perspective" "float shutteropen" 0 "float shutterclose" 0.5
            WorldBegin
            AttributeBegin
            ActiveTransform EndTime
            Translate 10 0 0
            ActiveTransform StartTime
            Translate 0 1 0
            Shape "sphere"
            AttributeEnd
            AttributeBegin
            ActiveTransform EndTime
            AttributeBegin
            ActiveTransform All
            Translate 0 0 2
            Shape "sphere"
            AttributeEnd
            Scale 5 5 5
            Shape "sphere"
            AttributeEnd
            "#,
        );
        let to_world: Vec<Mat4> = s.spheres.iter().map(|sp| sp.object_to_world).collect();
        assert_eq!(
            to_world,
            vec![
                Mat4::from_translation(Vec3::new(0.0, 1.0, 0.0)),
                Mat4::from_translation(Vec3::new(0.0, 0.0, 2.0)),
                Mat4::IDENTITY
            ]
        );
        let e = parse_err("Camera \"perspective\" \"float shutteropen\" [ ]\n");
        assert!(e.message.contains("shutteropen"), "{e}");
        let e = parse_err("WorldBegin\nActiveTransform Later\n");
        assert!(e.message.contains("StartTime"), "{e}");
    }

    /// pbrt-v4's diffusetransmission: R and T default to 0.25, `scale` multiplies both and
    /// each is clamped to [0, 1]; a texture replaces either.
    #[test]
    fn diffuse_transmission_reads_reflectance_transmittance_and_scale() {
        let s = parse(&format!(
            r#"WorldBegin
            Material "diffusetransmission"
            {QUAD}
            Material "diffusetransmission" "rgb reflectance" [ 0.2 0.3 0.6 ] "rgb transmittance" [ 0.1 0.5 0.4 ] "float scale" 2
            {QUAD}
            Texture "t" "spectrum" "checkerboard" "rgb tex1" [ 0.1 0.1 0.1 ] "rgb tex2" [ 0.9 0.9 0.9 ]
            Material "diffusetransmission" "texture transmittance" "t"
            {QUAD}
            "#
        ));
        let m = |i: usize| s.materials[s.triangles[2 * i].material as usize];
        assert!((0..3).all(|i| m(i).bsdf == BsdfKind::DiffuseTransmission));
        assert_eq!(m(0).diffuse, Vec3::splat(0.25));
        assert_eq!(m(0).transmittance, Vec3::splat(0.25));
        assert_eq!(m(1).diffuse, Vec3::new(0.4, 0.6, 1.0));
        assert_eq!(m(1).transmittance, Vec3::new(0.2, 1.0, 0.8));
        assert!(m(2).transmittance_texture.is_some() && m(2).diffuse_texture.is_none());
        // The record carries T in `specular` and its texture in info.w.
        let r = m(1).record();
        assert_eq!(r.specular[..3], [0.2, 1.0, 0.8]);
        assert_eq!(m(2).record().info[3], m(2).transmittance_texture.unwrap());
    }

    /// pbrt-v4's coatedconductor: the coating's `interface.*` and the conductor's
    /// `conductor.*` (copper by default, named spectra, or a constant or textured
    /// `reflectance`), each roughness remapped; the record holds the conductor's eta and k
    /// over the coating's index (pbrt-v4 divides them so), its alphas in `base`, a
    /// textured thickness in base.w. A textured albedo is refused.
    #[test]
    fn coated_conductor_reads_its_coating_and_its_conductor() {
        let s = parse(&format!(
            r#"WorldBegin
            Material "coatedconductor"
            {QUAD}
            Material "coatedconductor" "float interface.roughness" 0.04 "spectrum conductor.eta" "metal-Al-eta" "spectrum conductor.k" "metal-Al-k" "float conductor.uroughness" 0.09 "float conductor.vroughness" 0.16 "float interface.eta" 1.33 "float thickness" 0.2 "integer maxdepth" 5 "integer nsamples" 2
            {QUAD}
            Texture "r" "spectrum" "checkerboard" "rgb tex1" [ 0.1 0.1 0.1 ] "rgb tex2" [ 0.9 0.9 0.9 ]
            Texture "ir" "float" "checkerboard" "float tex1" 0.01 "float tex2" 0.2
            Material "coatedconductor" "texture reflectance" "r" "texture interface.roughness" "ir" "float conductor.roughness" 0.01 "bool remaproughness" false
            {QUAD}
            Material "coatedconductor" "rgb reflectance" [ 0.5 0.5 0.5 ]
            {QUAD}
            Material "coateddiffuse" "texture thickness" "ir"
            {QUAD}
            "#
        ));
        let m = |i: usize| s.materials[s.triangles[2 * i].material as usize];
        assert!((0..4).all(|i| m(i).bsdf == BsdfKind::CoatedConductor));
        let d = m(0);
        assert_eq!(
            (d.eta, d.k),
            (crate::scene::COPPER_ETA, crate::scene::COPPER_K)
        );
        assert_eq!((d.ior, d.roughness, d.base_roughness), (1.5, 0.0, 0.0));
        assert_eq!(
            (d.thickness, d.layer_max_depth, d.layer_samples),
            (0.01, 10, 1)
        );
        let a = m(1);
        assert!((a.roughness - 0.2).abs() < 1e-6 && (a.roughness_v - 0.2).abs() < 1e-6);
        assert!((a.base_roughness - 0.3).abs() < 1e-6 && (a.base_roughness_v - 0.4).abs() < 1e-6);
        assert_eq!(
            (a.ior, a.thickness, a.layer_max_depth, a.layer_samples),
            (1.33, 0.2, 5, 2)
        );
        // Aluminium (RGB of pbrt-v4's spectra): eta 1.66-0.52, k 9.2-4.8.
        assert!(
            a.eta.max_element() < 2.0 && a.k.min_element() > 4.0,
            "{} {}",
            a.eta,
            a.k
        );
        let r = a.record();
        for c in 0..3 {
            assert!((r.specular[c] - a.eta[c] / 1.33).abs() < 1e-6);
            assert!((r.diffuse[c] - a.k[c] / 1.33).abs() < 1e-6);
        }
        assert_eq!(r.eta[0], 1.33);
        assert_eq!(r.base[..2], [a.base_roughness, a.base_roughness_v]);
        assert_eq!(r.base[2].to_bits(), crate::abi::NO_TEXTURE);
        let t = m(2);
        assert!(t.diffuse_texture.is_some() && t.roughness_texture.is_some());
        assert!(!t.remap_roughness_texture && t.base_roughness == 0.01);
        assert_eq!(t.record().info[2], t.diffuse_texture.unwrap());
        assert_eq!(t.record().info[1] & crate::abi::MATERIAL_REMAP_ROUGHNESS, 0);
        // A reflectance r: eta 1, k = 2 sqrt(r) / sqrt(1 - r) = 2.
        let c = m(3);
        assert_eq!(c.eta, Vec3::ONE);
        assert!((c.k - Vec3::splat(2.0)).abs().max_element() < 1e-6);
        // A textured thickness (either coated kind): base.w.
        let th = m(4);
        assert_eq!(th.thickness_texture, t.roughness_texture);
        assert_eq!(th.record().base[3].to_bits(), th.thickness_texture.unwrap());
        assert_eq!(c.record().base[3].to_bits(), crate::abi::NO_TEXTURE);
        let e = parse_err(&format!(
            "WorldBegin\nTexture \"r\" \"spectrum\" \"checkerboard\"\n\
             Material \"coatedconductor\" \"texture albedo\" \"r\"\n{QUAD}"
        ));
        assert!(e.to_string().contains("textured albedo"), "{e}");
        // A scattering layer: albedo clamped to [0, 1] and g to [-1, 1], in eta.yzw and k.w.
        let s = parse(&format!(
            "WorldBegin\nMaterial \"coateddiffuse\" \"rgb albedo\" [ 0.5 1.5 0.2 ] \"float g\" -2\n{QUAD}"
        ));
        let m = s.materials[s.triangles[0].material as usize];
        assert_eq!(
            (m.layer_albedo, m.layer_g),
            (Vec3::new(0.5, 1.0, 0.2), -1.0)
        );
        let r = m.record();
        assert_eq!((r.eta[1..4].to_vec(), r.k[3]), (vec![0.5, 1.0, 0.2], -1.0));
    }

    /// pbrt-v4's `scale` and `mix` textures: constants fold into constants, a leaf
    /// texture times a constant is a scaled copy of the leaf, and anything else (a texture
    /// of textures, a colour times a float texture, a mix with a textured amount) is a
    /// texture made of textures; a tree larger than the kernels' programs is an error.
    #[test]
    fn scale_and_mix_textures_fold_copy_or_make_a_tree() {
        use crate::texture::Operand;
        let s = parse(&format!(
            r#"WorldBegin
            Texture "c" "spectrum" "checkerboard" "rgb tex1" [ 0.1 0.1 0.1 ] "rgb tex2" [ 0.9 0.9 0.9 ]
            Texture "f" "float" "checkerboard" "float tex1" 0.2 "float tex2" 0.6
            Texture "k" "spectrum" "scale" "rgb tex" [ 0.5 0.5 0.5 ] "float scale" 0.5
            Texture "cs" "spectrum" "scale" "texture tex" "c" "float scale" 2
            Texture "tint" "spectrum" "scale" "rgb tex" [ 0.9 0.5 0.2 ] "texture scale" "f"
            Texture "m" "spectrum" "mix" "texture tex1" "c" "texture amount" "f"
            Texture "mc" "spectrum" "mix" "rgb tex1" [ 1 0 0 ] "rgb tex2" [ 0 0 1 ] "float amount" 0.25
            Texture "sm" "spectrum" "scale" "texture tex" "m" "texture scale" "f"
            Material "diffuse" "texture reflectance" "k"
            {QUAD}
            Material "diffuse" "texture reflectance" "cs"
            {QUAD}
            Material "diffuse" "texture reflectance" "tint"
            {QUAD}
            Material "diffuse" "texture reflectance" "m"
            {QUAD}
            Material "diffuse" "texture reflectance" "mc"
            {QUAD}
            Material "diffuse" "texture reflectance" "sm"
            {QUAD}
            "#
        ));
        let m = |i: usize| s.materials[s.triangles[2 * i].material as usize];
        let tex = |i: usize| &s.textures[m(i).diffuse_texture.unwrap() as usize];
        assert!(m(0).diffuse_texture.is_none() && m(0).diffuse == Vec3::splat(0.25));
        assert!(
            matches!(tex(1), Texture::Checkerboard { even, odd, .. } if *even == Vec3::splat(0.2) && *odd == Vec3::splat(1.8))
        );
        match tex(2) {
            Texture::Scale {
                tex: Operand::Const(c),
                scale: Operand::Texture(f),
            } => {
                assert_eq!(*c, Vec3::new(0.9, 0.5, 0.2));
                assert!(matches!(**f, Texture::Checkerboard { .. }));
            }
            other => panic!("{other:?}"),
        }
        match tex(3) {
            Texture::Mix {
                tex1: Operand::Texture(_),
                tex2: Operand::Const(c),
                amount: Operand::Texture(_),
            } => assert_eq!(*c, Vec3::ONE),
            other => panic!("{other:?}"),
        }
        assert!(m(4).diffuse_texture.is_none());
        assert!(
            (m(4).diffuse - Vec3::new(0.75, 0.0, 0.25))
                .abs()
                .max_element()
                < 1e-6
        );
        assert_eq!(tex(5).program_length(), 5);
        // A tree of nine textures.
        let mut text = String::from("WorldBegin\nTexture \"t0\" \"float\" \"checkerboard\"\n");
        for i in 1..5 {
            text += &format!(
                "Texture \"t{i}\" \"float\" \"scale\" \"texture tex\" \"t{}\" \"texture scale\" \"t0\"\n",
                i - 1
            );
        }
        let e = parse_err(&text);
        assert!(e.to_string().contains("at most 8"), "{e}");
    }

    #[test]
    fn tokens_parameters_and_defaults() {
        let s = parse(&format!(
            r#"# a comment
            LookAt 0 0 5  0 0 0  0 1 0
            Camera "perspective" "float fov" 40
            Film "rgb" "integer xresolution" [ 64 ] "integer yresolution" 32 "string filename" "out.exr"
            Sampler "zsobol" "integer pixelsamples" 8
            Integrator "bdpt" "integer maxdepth" [ 7 ]
            WorldBegin
            Material "diffuse" "rgb reflectance" [ 0.2 0.3 0.4 ]
            {QUAD}
            "#
        ));
        assert_eq!((s.width, s.height), (64, 32));
        assert_eq!(s.output.as_deref(), Some("out.exr"));
        assert_eq!(s.settings.spp, 8);
        assert_eq!(s.settings.max_depth, 7);
        assert_eq!(s.settings.integrator, IntegratorKind::Bdpt);
        assert_eq!(s.triangles.len(), 2);
        assert_eq!(s.materials[0].diffuse, Vec3::new(0.2, 0.3, 0.4));
        assert_eq!(s.materials[0].bsdf, BsdfKind::Phong);
        assert_eq!(s.materials[0].specular, Vec3::ZERO);
        // fov spans the shorter side (here the height): the vertical fov is 40°.
        assert!((s.camera.fovy_degrees - 40.0).abs() < 1e-4);
        // pbrt's LookAt camera: world +x is on the image's left.
        assert!(s.camera.mirror);
        assert!((s.camera.eye - Vec3::new(0.0, 0.0, 5.0)).length() < 1e-5);
        assert!(((s.camera.look_at - s.camera.eye).normalize() - Vec3::NEG_Z).length() < 1e-5);
        // A portrait image: fov spans the width.
        let s = parse(
            r#"Camera "perspective" "float fov" 90 Film "rgb" "integer xresolution" 50 "integer yresolution" 100 WorldBegin"#,
        );
        let expected = (2.0 * (2.0f32).atan()).to_degrees();
        assert!(
            (s.camera.fovy_degrees - expected).abs() < 1e-3,
            "{}",
            s.camera.fovy_degrees
        );
        // `Scale -1 1 1` before LookAt (as exporters write) makes it unmirrored.
        let s = parse("Scale -1 1 1 LookAt 0 0 5 0 0 0 0 1 0 Camera \"perspective\" WorldBegin");
        assert!(!s.camera.mirror);
    }

    #[test]
    fn mixes_name_two_materials_and_carry_the_light() {
        use crate::abi::MATERIAL_MIX;
        let s = parse(&format!(
            r#"WorldBegin
            MakeNamedMaterial "a" "string type" "diffuse" "rgb reflectance" [ 0.8 0.8 0.8 ]
            MakeNamedMaterial "b" "string type" "conductor"
            MakeNamedMaterial "ab" "string type" "mix" "string materials" [ "a" "b" ] "float amount" 0.3
            Texture "t" "float" "checkerboard"
            MakeNamedMaterial "abt" "string type" "mix" "string materials" [ "ab" "a" ] "texture amount" "t"
            NamedMaterial "ab"
            {QUAD}
            AttributeBegin
            AreaLightSource "diffuse" "rgb L" [ 2 2 2 ]
            NamedMaterial "abt"
            {QUAD}
            AttributeEnd
            "#
        ));
        let m = &s.materials;
        let mix = |i: u32| m[i as usize].mix.expect("a mix");
        let ab = mix(s.triangles[0].material);
        assert_eq!(ab.amount, 0.3);
        assert_eq!(m[ab.materials[0] as usize].diffuse, Vec3::splat(0.8));
        assert_eq!(m[ab.materials[1] as usize].bsdf, BsdfKind::Conductor);
        // The emitter's mix, and every material it can resolve to, emit.
        let abt = mix(s.triangles[2].material);
        assert!(abt.amount_texture.is_some());
        assert!(m[s.triangles[2].material as usize].emission == Vec3::splat(2.0));
        let inner = mix(abt.materials[0]);
        for i in [abt.materials[1], inner.materials[0], inner.materials[1]] {
            assert_eq!(m[i as usize].emission, Vec3::splat(2.0));
            assert!(m[i as usize].mix.is_none());
        }
        // The record the kernels read: flag, children, amount.
        let r = m[s.triangles[0].material as usize].record();
        assert_eq!(r.info[1] & MATERIAL_MIX, MATERIAL_MIX);
        assert_eq!(r.specular[0].to_bits(), ab.materials[0]);
        assert_eq!(r.specular[2], 0.3);
        for (text, what) in [
            ("MakeNamedMaterial \"m\" \"string type\" \"mix\" \"string materials\" \"a\"", "two material names"),
            ("MakeNamedMaterial \"m\" \"string type\" \"mix\" \"string materials\" [ \"a\" \"nope\" ]", "no material named \"nope\""),
        ] {
            let e = parse_err(&format!("WorldBegin\nMakeNamedMaterial \"a\" \"string type\" \"diffuse\"\n{text}\n"));
            assert!(e.message.contains(what) && e.line == 3, "{e}");
        }
        let mut deep =
            String::from("WorldBegin\nMakeNamedMaterial \"m0\" \"string type\" \"diffuse\"\n");
        for i in 1..=9 {
            deep += &format!("MakeNamedMaterial \"m{i}\" \"string type\" \"mix\" \"string materials\" [ \"m{}\" \"m0\" ]\n", i - 1);
        }
        let e = parse_err(&deep);
        assert!(
            e.message.contains("nest more than 8") && e.line == 11,
            "{e}"
        );
    }

    #[test]
    fn lens_screen_window_frame_and_crop() {
        let camera = |params: &str, film: &str| {
            parse(&format!(
                "Camera \"perspective\" \"float fov\" 90 {params} Film \"rgb\" \"integer xresolution\" 20 \"integer yresolution\" 10 {film} WorldBegin"
            ))
        };
        let s = camera("\"float lensradius\" 0.5 \"float focaldistance\" 3", "");
        assert_eq!((s.camera.lens_radius, s.camera.focal_distance), (0.5, 3.0));
        // No window, frame or crop: the film follows the image (so --size keeps pbrt's rule).
        assert_eq!(s.camera.window, None);
        assert_eq!(camera("", "").camera.focal_distance, 1e6);
        // A screen window is scaled by tan(fov / 2) = 1.
        let s = camera("\"float screenwindow\" [ -0.5 1 -0.25 0.75 ]", "");
        assert_eq!(s.camera.window, Some([-0.5, 1.0, -0.25, 0.75]));
        // frameaspectratio 1 on a 2:1 image: [-1, 1]², stretched.
        let s = camera("\"float frameaspectratio\" 1", "");
        assert_eq!(s.camera.window, Some([-1.0, 1.0, -1.0, 1.0]));
        // A crop renders ceil(resolution × crop): x 2..11, y 0..3 of the [-2, 2] × [-1, 1]
        // film, whose rows run down from y = 1.
        let s = camera("", "\"float cropwindow\" [ 0.55 0.1 0 0.3 ]");
        assert_eq!((s.width, s.height), (9, 3));
        let w = s.camera.window.unwrap();
        let expected = [
            -2.0 + 4.0 * 2.0 / 20.0,
            -2.0 + 4.0 * 11.0 / 20.0,
            1.0 - 2.0 * 3.0 / 10.0,
            1.0,
        ];
        for (a, b) in w.iter().zip(expected) {
            assert!((a - b).abs() < 1e-6, "{w:?} vs {expected:?}");
        }
        // pixelbounds, clamped to the film, wins over cropwindow.
        let s = camera(
            "",
            "\"integer pixelbounds\" [ 5 30 2 4 ] \"float cropwindow\" [ 0 0.1 0 0.1 ]",
        );
        assert_eq!((s.width, s.height), (15, 2));
        for (params, film, what) in [
            (
                "\"float lensradius\" -1",
                "",
                "lensradius must be zero or positive",
            ),
            (
                "\"float focaldistance\" 0",
                "",
                "focaldistance must be positive",
            ),
            (
                "\"float screenwindow\" [ 0 1 2 ]",
                "",
                "screenwindow must be 4 finite numbers",
            ),
            (
                "\"float screenwindow\" [ 0 0 0 1 ]",
                "",
                "screenwindow must be 4 finite numbers",
            ),
            (
                "",
                "\"float cropwindow\" [ 0 1.5 0 1 ]",
                "cropwindow must be 4 numbers",
            ),
            (
                "",
                "\"float cropwindow\" [ 0.51 0.52 0 1 ]",
                "holds no pixel",
            ),
            (
                "",
                "\"integer pixelbounds\" [ 3 3 0 1 ]",
                "pixelbounds must be 4 integers",
            ),
        ] {
            let e = parse_err(&format!(
                "Camera \"perspective\" {params}\nFilm \"rgb\" \"integer xresolution\" 20 \"integer yresolution\" 10 {film}\nWorldBegin"
            ));
            assert!(e.message.contains(what), "{e}");
            assert_eq!(e.line, if film.is_empty() { 1 } else { 2 }, "{e}");
        }
    }

    #[test]
    fn mlt_renders_its_mutations_per_pixel() {
        let s = parse("Integrator \"mlt\" \"float sigma\" 0.02 Sampler \"halton\" \"integer pixelsamples\" 4 WorldBegin");
        assert_eq!(
            (s.settings.integrator, s.settings.spp),
            (IntegratorKind::Mmlt, 100)
        );
        assert!((s.settings.mmlt.sigma - 0.02).abs() < 1e-7);
        let s = parse("Sampler \"halton\" \"integer pixelsamples\" 4 Integrator \"mlt\" \"integer mutationsperpixel\" 7 WorldBegin");
        assert_eq!(s.settings.spp, 7);
        let s = parse("Integrator \"mlt\" Integrator \"bdpt\" Sampler \"halton\" \"integer pixelsamples\" 4 WorldBegin");
        assert_eq!(
            (s.settings.integrator, s.settings.spp),
            (IntegratorKind::Bdpt, 4)
        );
    }

    #[test]
    fn transforms_attributes_and_instances() {
        let s = parse(&format!(
            r#"WorldBegin
            AttributeBegin
              Translate 10 0 0
              Scale 2 2 2
              {QUAD}
            AttributeEnd
            ObjectBegin "q"
              Rotate 90 0 0 1
              {QUAD}
            ObjectEnd
            Translate 0 0 -3
            ObjectInstance "q"
            {QUAD}
            "#
        ));
        assert_eq!(s.triangles.len(), 6);
        // Translated and scaled: corner (-1, -1, 0) at (8, -2, 0).
        assert!((s.triangles[0].v[0] - Vec3::new(8.0, -2.0, 0.0)).length() < 1e-5);
        // The instance: rotated 90° about z, then translated by the instance's transform.
        assert!((s.triangles[2].v[0] - Vec3::new(1.0, -1.0, -3.0)).length() < 1e-5);
        // After the instance, the plain quad is only translated.
        assert!((s.triangles[4].v[0] - Vec3::new(-1.0, -1.0, -3.0)).length() < 1e-5);
        // Transform takes the matrix column by column (translation last).
        let s = parse(&format!(
            "WorldBegin Transform [1 0 0 0  0 1 0 0  0 0 1 0  5 6 7 1] {QUAD}"
        ));
        assert!((s.triangles[0].v[0] - Vec3::new(4.0, 5.0, 7.0)).length() < 1e-5);
    }

    #[test]
    fn materials_textures_and_lights() {
        let s = parse(&format!(
            r#"WorldBegin
            Texture "checks" "spectrum" "checkerboard" "rgb tex1" [1 0 0] "rgb tex2" [0 0 1] "float uscale" 4 "float vscale" 4
            MakeNamedMaterial "glass" "string type" "dielectric" "float eta" 1.33 "float roughness" 0.04
            MakeNamedMaterial "gold" "string type" "conductor" "spectrum eta" "metal-Au-eta" "spectrum k" "metal-Au-k" "float roughness" 0.01 "bool remaproughness" false
            NamedMaterial "glass"
            {QUAD}
            NamedMaterial "gold"
            {QUAD}
            Material "diffuse" "texture reflectance" "checks"
            {QUAD}
            AttributeBegin
              AreaLightSource "diffuse" "rgb L" [ 4 4 4 ] "float scale" 2
              Material "diffuse" "rgb reflectance" [0 0 0]
              {QUAD}
            AttributeEnd
            LightSource "point" "rgb I" [ 1 2 3 ] "point3 from" [ 0 5 0 ]
            LightSource "spot" "point3 from" [0 0 0] "point3 to" [0 -1 0] "float coneangle" 30 "float conedeltaangle" 10
            LightSource "distant" "point3 from" [0 1 0] "point3 to" [0 0 0] "rgb L" [2 2 2]
            LightSource "infinite" "rgb L" [0.1 0.2 0.3]
            "#
        ));
        let m = |t: usize| s.materials[s.triangles[t].material as usize];
        assert_eq!(m(0).bsdf, BsdfKind::Dielectric);
        assert!((m(0).ior - 1.33).abs() < 1e-6);
        // remaproughness (the default): alpha = sqrt(roughness).
        assert!((m(0).roughness - 0.2).abs() < 1e-6);
        assert_eq!(m(2).bsdf, BsdfKind::Conductor);
        assert!((m(2).roughness - 0.01).abs() < 1e-6);
        assert!((m(2).eta.x - 0.143_119).abs() < 1e-6);
        assert_eq!(m(4).bsdf, BsdfKind::Phong);
        let t = m(4).diffuse_texture.expect("textured") as usize;
        assert!(
            matches!(s.textures[t], Texture::Checkerboard { mapping, .. } if mapping == [4.0, 4.0, 0.0, 0.0])
        );
        assert_eq!(m(6).emission, Vec3::splat(8.0));
        assert!(!m(6).two_sided_emission);
        // The area light ended with its attributes.
        assert_eq!(s.delta_lights.len(), 3);
        assert!(
            matches!(s.delta_lights[0], DeltaLight::Point { position, intensity } if position == Vec3::new(0.0, 5.0, 0.0) && intensity == Vec3::new(1.0, 2.0, 3.0))
        );
        match s.delta_lights[1] {
            DeltaLight::Spot {
                direction,
                cos_falloff_start,
                cos_falloff_end,
                ..
            } => {
                assert!((direction - Vec3::NEG_Y).length() < 1e-6);
                assert!((cos_falloff_start - 20f32.to_radians().cos()).abs() < 1e-6);
                assert!((cos_falloff_end - 30f32.to_radians().cos()).abs() < 1e-6);
            }
            _ => panic!("a spot light"),
        }
        assert!(
            matches!(s.delta_lights[2], DeltaLight::Directional { direction, radiance } if direction == Vec3::Y && radiance == Vec3::splat(2.0))
        );
        assert_eq!(
            s.environment.as_ref().unwrap().radiance,
            Vec3::new(0.1, 0.2, 0.3)
        );
    }

    /// pbrt's emitting side: the triangle's normal (p0 - p2) × (p1 - p2), flipped by
    /// ReverseOrientation or a mirroring transform, or turned toward the mesh's normals.
    #[test]
    fn emission_faces_pbrts_side() {
        let facing = |text: &str| {
            let s = parse(&format!("WorldBegin AreaLightSource \"diffuse\" {text}"));
            let t = &s.triangles[0];
            (t.v[1] - t.v[0]).cross(t.v[2] - t.v[0]).normalize()
        };
        assert!((facing(QUAD) - Vec3::Z).length() < 1e-6);
        assert!((facing(&format!("ReverseOrientation {QUAD}")) + Vec3::Z).length() < 1e-6);
        // A mirroring transform turns the normal as a normal transforms.
        assert!((facing(&format!("Scale 1 1 -1 {QUAD}")) + Vec3::Z).length() < 1e-6);
        assert!((facing(&format!("Scale -1 1 1 {QUAD}")) - Vec3::Z).length() < 1e-6);
        let with_normals = format!("{QUAD} \"normal N\" [0 0 -1 0 0 -1 0 0 -1 0 0 -1]");
        assert!((facing(&with_normals) + Vec3::Z).length() < 1e-6);
        // A mesh light with `power`: each triangle emits it (pbrt-v4 makes one light per
        // triangle): L = power / (π area), area 2 per triangle.
        let s = parse(&format!(
            "WorldBegin AreaLightSource \"diffuse\" \"float power\" 10 {QUAD}"
        ));
        let l = s.materials[s.triangles[0].material as usize].emission;
        assert!(
            (l.x - 10.0 / (std::f32::consts::PI * 2.0)).abs() < 1e-5,
            "{l}"
        );
    }

    #[test]
    fn unsupported_features_are_listed_together() {
        let e = parse_err(&format!(
            r#"WorldBegin
            MakeNamedMedium "fog" "string type" "homogeneous"
            Shape "curve" "point3 P" [0 0 0 1 1 1 2 2 2 3 3 3]
            Material "hair"
            Shape "sphere" "float alpha" 0.5
            LightSource "goniometric"
            "#
        ));
        let text = e.to_string();
        for what in [
            "t.pbrt:2: MakeNamedMedium",
            "t.pbrt:3: Shape \"curve\"",
            "t.pbrt:4: Material \"hair\"",
            "alpha",
            "t.pbrt:6: LightSource \"goniometric\"",
        ] {
            assert!(text.contains(what), "{what} missing from:\n{text}");
        }
        assert_eq!(e.line, 2);
        // An unknown parameter is unsupported too (it would be silently ignored).
        let e = parse_err(&format!(
            "WorldBegin Material \"diffuse\" \"rgb reflectanse\" [1 1 1] {QUAD}"
        ));
        assert!(
            e.to_string()
                .contains("\"rgb reflectanse\" is not supported"),
            "{e}"
        );
    }

    #[test]
    fn syntax_errors_name_the_line() {
        let e = parse_err("WorldBegin\n\nShape \"sphere\" \"float radius\" [ 1 \n");
        assert!(e.message.contains("']'"), "{e}");
        let e = parse_err("WorldBegin\nFrobnicate 1 2\n");
        assert_eq!((e.line, e.command.as_str()), (2, "Frobnicate"));
        let e = parse_err("WorldBegin\nShape \"sphere\" \"float radius\" \"big\"\n");
        assert_eq!(e.line, 2);
        let e = parse_err("Film \"rgb\" \"integer xresolution\" 1.5");
        assert!(e.message.contains("integer"), "{e}");
        let e = parse_err("WorldBegin\nAttributeEnd");
        assert!(e.message.contains("without a matching"), "{e}");
        let e = parse_err("WorldBegin\nShape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0] \"integer indices\" [0 1 5]");
        assert!(e.message.contains("out of range"), "{e}");
        let e = parse_err("Shape \"sphere\" \"string radius\" \"unterminated");
        assert!(e.message.contains("unterminated"), "{e}");
        let e = parse_err("WorldBegin NamedMaterial \"nothing\"");
        assert!(e.message.contains("no material named"), "{e}");
    }

    #[test]
    fn includes_are_relative_to_the_including_file() {
        let d = std::env::temp_dir().join(format!("lightpath-pbrt-{}", std::process::id()));
        std::fs::create_dir_all(d.join("sub/deeper")).unwrap();
        std::fs::write(d.join("main.pbrt"), "WorldBegin\nInclude \"sub/a.pbrt\"\n").unwrap();
        std::fs::write(
            d.join("sub/a.pbrt"),
            format!("Include \"deeper/b.pbrt\"\n{QUAD}\n"),
        )
        .unwrap();
        std::fs::write(
            d.join("sub/deeper/b.pbrt"),
            "Material \"diffuse\" \"rgb reflectance\" [0.1 0.2 0.3]\n\nShape \"bogus\"\n",
        )
        .unwrap();
        let e = parse_pbrt_file(&d.join("main.pbrt")).expect_err("bogus shape");
        assert!(e.to_string().contains("b.pbrt:3: Shape \"bogus\""), "{e}");
        std::fs::write(
            d.join("sub/deeper/b.pbrt"),
            "Material \"diffuse\" \"rgb reflectance\" [0.1 0.2 0.3]\n",
        )
        .unwrap();
        let s = parse_pbrt_file(&d.join("main.pbrt")).unwrap();
        assert_eq!(s.triangles.len(), 2);
        assert_eq!(s.materials[0].diffuse, Vec3::new(0.1, 0.2, 0.3));
        // A gzip-compressed include (pbrt-v4's `.pbrt.gz`); a corrupt one is an error
        // naming the file.
        let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
        std::io::Write::write_all(&mut gz, format!("{QUAD}\n").as_bytes()).unwrap();
        std::fs::write(d.join("sub/c.pbrt.gz"), gz.finish().unwrap()).unwrap();
        std::fs::write(
            d.join("gz.pbrt"),
            "WorldBegin\nInclude \"sub/c.pbrt.gz\"\nImport \"sub/c.pbrt.gz\"\n",
        )
        .unwrap();
        let s = parse_pbrt_file(&d.join("gz.pbrt")).unwrap();
        assert_eq!(s.triangles.len(), 4);
        std::fs::write(d.join("sub/bad.pbrt.gz"), "not gzip").unwrap();
        std::fs::write(
            d.join("bad.pbrt"),
            "WorldBegin\nInclude \"sub/bad.pbrt.gz\"\n",
        )
        .unwrap();
        let e = parse_pbrt_file(&d.join("bad.pbrt")).expect_err("not gzip");
        assert!(
            e.to_string().contains("bad.pbrt:2") && e.message.contains("bad.pbrt.gz"),
            "{e}"
        );
        std::fs::write(d.join("loop.pbrt"), "Include \"loop.pbrt\"\n").unwrap();
        let e = parse_pbrt_file(&d.join("loop.pbrt")).expect_err("a loop");
        assert!(e.message.contains("include itself"), "{e}");
        std::fs::remove_dir_all(&d).ok();
    }

    /// Blackbody, sampled and file spectra: emitted ones at luminance 1 (times scale),
    /// bounded ones grey when constant; bad ones are errors naming the line.
    #[test]
    fn blackbody_sampled_and_file_spectra() {
        let lum = |c: Vec3| 0.212_672_9 * c.x + 0.715_152_2 * c.y + 0.072_175 * c.z;
        let s = parse(&format!(
            "WorldBegin\nAttributeBegin\nAreaLightSource \"diffuse\" \"blackbody L\" [2700] \"float scale\" 2\n{QUAD}\nAttributeEnd\n\
             Material \"diffuse\" \"spectrum reflectance\" [300 0.25 900 0.25]\n{QUAD}\n"
        ));
        let light = s.materials[s.triangles[0].material as usize].emission;
        assert!((lum(light) - 2.0).abs() < 1e-3, "{light}");
        assert!(
            light.x > light.y && light.y > light.z,
            "2700 K is orange: {light}"
        );
        let grey = s.materials[s.triangles[2].material as usize].diffuse;
        assert!(
            (grey - Vec3::splat(0.25)).abs().max_element() < 1e-5,
            "{grey}"
        );
        let e = parse_err("WorldBegin\nLightSource \"point\"\n  \"blackbody I\" [-5]\n");
        assert!(e.line == 2 || e.line == 3, "{e}");
        assert!(e.message.contains("temperature"), "{e}");
        let e =
            parse_err("WorldBegin\nMaterial \"diffuse\" \"spectrum reflectance\" [500 1 400 1]\n");
        assert!(e.message.contains("increase"), "{e}");

        let d = std::env::temp_dir().join(format!("lightpath-spd-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        std::fs::write(d.join("lamp.spd"), "# a lamp\n400 0.2\n550 1.0\n700 3.0\n").unwrap();
        std::fs::write(
            d.join("main.pbrt"),
            "WorldBegin\nLightSource \"point\" \"spectrum I\" \"lamp.spd\" \"float scale\" 3\n",
        )
        .unwrap();
        let s = parse_pbrt_file(&d.join("main.pbrt")).unwrap();
        let DeltaLight::Point { intensity: i, .. } = s.delta_lights[0] else {
            panic!("a point light")
        };
        assert!((lum(i) - 3.0).abs() < 1e-3 && i.x > i.z, "{i}");
        std::fs::write(d.join("lamp.spd"), "400 0.2\n550 x\n").unwrap();
        let e = parse_pbrt_file(&d.join("main.pbrt")).expect_err("a bad spd");
        assert!(
            e.message.contains("lamp.spd") && e.message.contains("line 2"),
            "{e}"
        );
        std::fs::remove_dir_all(&d).ok();
    }

    /// `Attribute` sets defaults for later directives of its kind, within its block;
    /// a directive's own parameter wins.
    #[test]
    fn attributes_give_default_parameters() {
        let s = parse(
            r#"WorldBegin
            AttributeBegin
              Attribute "shape" "float radius" 2
              Attribute "material" "rgb reflectance" [0.1 0.2 0.3]
              Material "diffuse"
              Shape "sphere"
              Shape "sphere" "float radius" 3
            AttributeEnd
            Shape "sphere"
            "#,
        );
        let radius = |i: usize| s.spheres[i].object_to_world.x_axis.length();
        assert_eq!([radius(0), radius(1), radius(2)], [2.0, 3.0, 1.0]);
        assert_eq!(
            s.materials[s.spheres[0].material as usize].diffuse,
            Vec3::new(0.1, 0.2, 0.3)
        );
        let e = parse_err("WorldBegin\nAttribute \"camera\" \"float fov\" 30\n");
        assert!(e.message.contains("unknown target"), "{e}");
        let e = parse_err("WorldBegin\nAttribute \"medium\" \"rgb sigma_a\" [1 1 1]\n");
        assert!(e.message.contains("medium"), "{e}");
    }

    /// loopsubdiv: `levels` of Loop subdivision, with normals; too many is an error.
    #[test]
    fn loop_subdivision_surfaces() {
        let oct = r#""point3 P" [1 0 0 -1 0 0 0 1 0 0 -1 0 0 0 1 0 0 -1]
            "integer indices" [0 2 4 2 1 4 1 3 4 3 0 4 2 0 5 1 2 5 3 1 5 0 3 5]"#;
        let s = parse(&format!(
            "WorldBegin\nShape \"loopsubdiv\" \"integer levels\" 2 {oct}\n"
        ));
        assert_eq!(s.triangles.len(), 8 * 16);
        assert!(s.triangles.iter().all(|t| t.normals.is_some()));
        let s = parse(&format!("WorldBegin\nShape \"loopsubdiv\" {oct}\n"));
        assert_eq!(s.triangles.len(), 8 * 64, "3 levels by default");
        let e = parse_err(&format!(
            "WorldBegin\nShape \"loopsubdiv\" \"integer levels\" 12 {oct}\n"
        ));
        assert!(e.message.contains("triangles"), "{e}");
    }

    /// An infinite light's `illuminance` with an image: a constant map of radiance 1
    /// gives π, so asking for 2π doubles it.
    #[test]
    fn illuminance_scales_an_environment_map() {
        let d = std::env::temp_dir().join(format!("lightpath-illum-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        let n = 64usize;
        let mut pfm = format!("PF\n{n} {n}\n-1.0\n").into_bytes();
        for _ in 0..n * n * 3 {
            pfm.extend(1.0f32.to_le_bytes());
        }
        std::fs::write(d.join("sky.pfm"), pfm).unwrap();
        std::fs::write(
            d.join("main.pbrt"),
            "WorldBegin\nLightSource \"infinite\" \"string filename\" \"sky.pfm\" \"float illuminance\" 6.2831853\n",
        )
        .unwrap();
        let s = parse_pbrt_file(&d.join("main.pbrt")).unwrap();
        let l = s.environment.expect("an environment").radiance;
        assert!((l - Vec3::splat(2.0)).abs().max_element() < 0.02, "{l}");
        std::fs::remove_dir_all(&d).ok();
    }

    /// A PLY quad (one 4-gon face) gives the triangles of the same trianglemesh.
    #[test]
    fn plymesh_reads_like_a_trianglemesh() {
        let d = std::env::temp_dir().join(format!("lightpath-pbrt-ply-{}", std::process::id()));
        std::fs::create_dir_all(d.join("geometry")).unwrap();
        std::fs::write(
            d.join("geometry/quad.ply"),
            "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n\
             property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n\
             -1 -1 0\n1 -1 0\n1 1 0\n-1 1 0\n4 0 1 2 3\n",
        )
        .unwrap();
        std::fs::write(
            d.join("s.pbrt"),
            "WorldBegin\nTranslate 0 0 2\nShape \"plymesh\" \"string filename\" \"geometry/quad.ply\"\n",
        )
        .unwrap();
        let ply = parse_pbrt_file(&d.join("s.pbrt")).unwrap();
        let mesh = parse(&format!("WorldBegin Translate 0 0 2 {QUAD}"));
        assert_eq!(ply.triangles, mesh.triangles);
        std::fs::write(
            d.join("s.pbrt"),
            "WorldBegin\nShape \"plymesh\" \"string filename\" \"missing.ply\"\n",
        )
        .unwrap();
        let e = parse_pbrt_file(&d.join("s.pbrt")).unwrap_err();
        assert_eq!(e.line, 2);
        assert!(e.message.contains("missing.ply"), "{e}");
        std::fs::remove_dir_all(&d).ok();
    }

    #[test]
    fn spheres_disks_and_bilinear_patches() {
        let s = parse(
            r#"WorldBegin
            Translate 1 2 3
            Shape "sphere" "float radius" 2
            Shape "disk" "float radius" 1
            Shape "bilinearmesh" "point3 P" [0 0 0 1 0 0 0 1 0 1 1 0]
            "#,
        );
        assert_eq!(s.spheres.len(), 1);
        let c = s.spheres[0].object_to_world.transform_point3(Vec3::X);
        assert!((c - Vec3::new(3.0, 2.0, 3.0)).length() < 1e-5);
        let disk: f32 = s.triangles[..DISK_SEGMENTS]
            .iter()
            .map(|t| 0.5 * (t.v[1] - t.v[0]).cross(t.v[2] - t.v[0]).length())
            .sum();
        assert!((disk - std::f32::consts::PI).abs() < 2e-3, "{disk}");
        assert_eq!(s.triangles.len(), DISK_SEGMENTS + 2);
        let patch: f32 = s.triangles[DISK_SEGMENTS..]
            .iter()
            .map(|t| 0.5 * (t.v[1] - t.v[0]).cross(t.v[2] - t.v[0]).length())
            .sum();
        assert!((patch - 1.0).abs() < 1e-6);
        let e = parse_err("WorldBegin Shape \"sphere\" \"float zmax\" 0.5");
        assert!(e.message.contains("partial sphere"), "{e}");
    }
}

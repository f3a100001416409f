//! Tokens and parameter lists: pbrt-v4's syntax, and the values a parameter gives
//! (numbers, spectra as RGB, constants or textures).

use super::*;

/// The types a parameter of this name may have, whatever the directive (pbrt-v4's
/// names are typed consistently), so that a value of the wrong type is an error rather
/// than a default.
pub(super) const PARAM_TYPES: &[(&str, &[&str])] = &[
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
    ("dir", &["vector3"]),
    ("octaves", &["integer"]),
    ("variation", &["float", "integer"]),
    ("uroughness", &["float", "integer", "texture"]),
    ("vroughness", &["float", "integer", "texture"]),
    ("L", &["rgb", "spectrum", "blackbody"]),
    ("I", &["rgb", "spectrum", "blackbody"]),
];

#[derive(Clone, Debug, PartialEq)]
pub(super) enum Tok {
    Str(String),
    Num(f64),
    Word(String),
    Open,
    Close,
}

#[derive(Clone, Debug)]
pub(super) struct Token {
    pub(super) tok: Tok,
    pub(super) file: u32,
    pub(super) line: u32,
}

/// Splits a file's text into tokens: quoted strings (with pbrt's escapes), numbers,
/// words (directives, `true`/`false`) and brackets; `#` comments run to the line's end.
pub(super) fn tokenize(text: &str, file: u32, name: &str) -> Result<Vec<Token>, ParseError> {
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
pub(super) struct Param {
    pub(super) ty: String,
    pub(super) name: String,
    pub(super) nums: Vec<f64>,
    pub(super) strs: Vec<String>,
    pub(super) bools: Vec<bool>,
    pub(super) line: u32,
    pub(super) file: u32,
    pub(super) used: std::cell::Cell<bool>,
}

/// A directive's parameter list, with the parameters it has read marked.
#[derive(Clone, Debug, Default)]
pub(super) struct Params(pub(super) Vec<Param>);

/// A value a material reads (a named texture's too): a constant or a texture of the scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Value {
    Const(Vec3),
    Texture(u32),
}

// Tests only: the parameter names each directive type asks for, whether or not the file
// gives them (`names_read`), to check them against pbrt-v4's own names.
#[cfg(test)]
thread_local! {
    pub(super) static ASKED: std::cell::RefCell<Vec<String>> = const { std::cell::RefCell::new(Vec::new()) };
    pub(super) static NAMES_READ: std::cell::RefCell<std::collections::BTreeSet<(String, String, String)>> =
        const { std::cell::RefCell::new(std::collections::BTreeSet::new()) };
}

impl Params {
    pub(super) fn find(&self, name: &str) -> Option<&Param> {
        #[cfg(test)]
        ASKED.with(|a| a.borrow_mut().push(name.to_owned()));
        let p = self.0.iter().find(|p| p.name == name)?;
        p.used.set(true);
        Some(p)
    }
}

pub(super) fn describe(t: &Tok) -> String {
    match t {
        Tok::Str(s) => format!("\"{s}\""),
        Tok::Num(x) => format!("{x}"),
        Tok::Word(w) => format!("'{w}'"),
        Tok::Open => "'['".into(),
        Tok::Close => "']'".into(),
    }
}

impl Parser {
    pub(super) fn peek(&self) -> Option<&Token> {
        self.tokens.get(self.pos)
    }

    pub(super) fn next_token(&mut self) -> Option<Token> {
        let t = self.tokens.get(self.pos).cloned();
        self.pos += 1;
        t
    }

    /// The line of the last token read (for messages at the end of input).
    pub(super) fn here(&self) -> (u32, u32) {
        self.tokens
            .get(self.pos.saturating_sub(1))
            .map_or((0, 0), |t| (t.file, t.line))
    }

    /// "EXPECTED, got TOKEN" at the token, or "..., got the end of the file" at the last
    /// token read.
    pub(super) fn unexpected(
        &self,
        got: Option<Token>,
        directive: &str,
        expected: &str,
    ) -> ParseError {
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

    pub(super) fn expect_string(
        &mut self,
        directive: &str,
        what: &str,
    ) -> Result<String, ParseError> {
        match self.next_token() {
            Some(Token {
                tok: Tok::Str(s), ..
            }) => Ok(s),
            t => Err(self.unexpected(t, directive, &format!("expected {what} (a quoted string)"))),
        }
    }

    /// `n` numbers, bracketed or not.
    pub(super) fn numbers(&mut self, directive: &str, n: usize) -> Result<Vec<f32>, ParseError> {
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
    pub(super) fn params(&mut self, directive: &str) -> Result<Params, ParseError> {
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

    /// A spectrum parameter as RGB (see spectrum.rs): `rgb` values, a `blackbody`
    /// temperature, sampled (λ, value) pairs, a named spectrum lightpath knows or an
    /// `.spd` file (relative to the file that names it). `emitted`: a light's spectrum
    /// (normalized to luminance 1, as pbrt-v4's lights); otherwise a bounded one.
    pub(super) fn rgb(
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
                let path = self.resolve(p.file, &p.strs[0]);
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
    pub(super) fn value(
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
}

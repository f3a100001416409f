//! PLY meshes (pbrt-v4's `plymesh`): ASCII and binary in either byte order, optionally
//! gzip-compressed (`.ply.gz`), with positions, normals and texture coordinates; faces of
//! three or more vertices (quads and larger polygons as fans of triangles). Elements
//! other than `vertex` and `face` are read past.
use glam::{Vec2, Vec3};
use std::io::Read;
use std::path::Path;

/// A triangle mesh as read from a PLY file, in its own space.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PlyMesh {
    pub p: Vec<Vec3>,
    pub n: Option<Vec<Vec3>>,
    pub uv: Option<Vec<Vec2>>,
    /// Three per triangle.
    pub indices: Vec<u32>,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(name: &str) -> Option<Scalar> {
        Some(match name {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }
    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }
}

#[derive(Clone, Debug)]
struct Property {
    name: String,
    /// `Some(count type)` for a list property.
    list: Option<Scalar>,
    ty: Scalar,
}

#[derive(Clone, Debug)]
struct Element {
    name: String,
    count: usize,
    props: Vec<Property>,
}

#[derive(Clone, Copy, PartialEq)]
enum Format {
    Ascii,
    Little,
    Big,
}

/// Reads a PLY file (gzip-compressed when its name ends in `.gz`).
///
/// # Errors
/// A message naming what is wrong (the header line, or the element that is truncated).
pub fn read_ply(path: &Path) -> Result<PlyMesh, String> {
    let cannot = |e: std::io::Error| format!("cannot read {}: {e}", path.display());
    let file = std::fs::File::open(path).map_err(cannot)?;
    let gz = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("gz"));
    if gz {
        let mut out = Vec::new();
        flate2::read::GzDecoder::new(std::io::BufReader::new(file))
            .read_to_end(&mut out)
            .map_err(|e| format!("{}: not a valid gzip file: {e}", path.display()))?;
        return parse_ply(&out).map_err(|e| format!("{}: {e}", path.display()));
    }
    // The file's pages mapped where they lie (no copy of a mesh's hundreds of megabytes
    // into fresh memory); an empty file, which cannot be mapped, parses as empty bytes.
    // SAFETY: the map is only read, while this function runs; a file changed meanwhile
    // by another program reads as whatever bytes it then holds (or, cut short, ends the
    // process with SIGBUS, as for any reader that maps its input).
    let map = match file.metadata().map_err(cannot)?.len() {
        0 => None,
        _ => Some(unsafe { memmap2::Mmap::map(&file) }.map_err(cannot)?),
    };
    parse_ply(map.as_deref().unwrap_or(&[])).map_err(|e| format!("{}: {e}", path.display()))
}

/// Parses a PLY file's bytes.
pub fn parse_ply(bytes: &[u8]) -> Result<PlyMesh, String> {
    parse(bytes, true)
}

/// [`parse_ply`]; `fast`: a binary file's vertices and faces read in bulk where their
/// layout allows (else, and in the tests that compare the two, value by value).
fn parse(bytes: &[u8], fast: bool) -> Result<PlyMesh, String> {
    // The header: ASCII lines up to `end_header`.
    let mut pos = 0;
    let mut lines = Vec::new();
    loop {
        let Some(len) = bytes[pos..].iter().position(|&b| b == b'\n') else {
            return Err("no end_header line".into());
        };
        let line = String::from_utf8_lossy(&bytes[pos..pos + len])
            .trim_end_matches('\r')
            .to_string();
        pos += len + 1;
        let end = line.trim() == "end_header";
        lines.push(line);
        if end {
            break;
        }
        if lines.len() > 100_000 {
            return Err("a header of more than 100000 lines".into());
        }
    }
    if lines.first().map(|l| l.trim()) != Some("ply") {
        return Err("not a PLY file (the first line is not 'ply')".into());
    }
    let mut format = None;
    let mut elements: Vec<Element> = Vec::new();
    for (i, line) in lines.iter().enumerate().skip(1) {
        let n = i + 1;
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.first().copied() {
            None | Some("comment") | Some("obj_info") | Some("end_header") => {}
            Some("format") => {
                format = Some(match words.get(1).copied() {
                    Some("ascii") => Format::Ascii,
                    Some("binary_little_endian") => Format::Little,
                    Some("binary_big_endian") => Format::Big,
                    other => return Err(format!("header line {n}: unknown format {other:?}")),
                });
            }
            Some("element") => {
                let (Some(name), Some(count)) = (words.get(1), words.get(2)) else {
                    return Err(format!("header line {n}: expected 'element NAME COUNT'"));
                };
                let count = count
                    .parse::<usize>()
                    .map_err(|_| format!("header line {n}: bad element count '{count}'"))?;
                elements.push(Element {
                    name: name.to_string(),
                    count,
                    props: Vec::new(),
                });
            }
            Some("property") => {
                let Some(e) = elements.last_mut() else {
                    return Err(format!("header line {n}: a property before any element"));
                };
                let bad = || format!("header line {n}: cannot read property '{line}'");
                let prop = if words.get(1) == Some(&"list") {
                    let (Some(c), Some(t), Some(name)) = (words.get(2), words.get(3), words.get(4))
                    else {
                        return Err(bad());
                    };
                    Property {
                        name: name.to_string(),
                        list: Some(Scalar::parse(c).ok_or_else(bad)?),
                        ty: Scalar::parse(t).ok_or_else(bad)?,
                    }
                } else {
                    let (Some(t), Some(name)) = (words.get(1), words.get(2)) else {
                        return Err(bad());
                    };
                    Property {
                        name: name.to_string(),
                        list: None,
                        ty: Scalar::parse(t).ok_or_else(bad)?,
                    }
                };
                e.props.push(prop);
            }
            Some(other) => return Err(format!("header line {n}: unknown keyword '{other}'")),
        }
    }
    let format = format.ok_or("no format line in the header")?;
    let mut body = Body {
        bytes: &bytes[pos..],
        pos: 0,
        format,
    };
    let mut mesh = PlyMesh::default();
    let mut normals = Vec::new();
    let mut uvs = Vec::new();
    let mut have_normals = false;
    let mut have_uv = false;
    for e in &elements {
        // Every value takes at least one byte (a binary one its size): a count beyond
        // the remaining bytes is a truncated or corrupt file, not an allocation.
        if e.props.is_empty() {
            continue;
        }
        let min_size: usize = if format == Format::Ascii {
            e.props.len()
        } else {
            e.props
                .iter()
                .map(|p| p.list.map_or(p.ty.size(), Scalar::size))
                .sum::<usize>()
        };
        if e.count.saturating_mul(min_size) > body.remaining() + 1 {
            return Err(format!(
                "element '{}': {} entries cannot fit in the file's remaining {} bytes",
                e.name,
                e.count,
                body.remaining()
            ));
        }
        match e.name.as_str() {
            "vertex" => {
                let find = |names: &[&str]| {
                    names.iter().find_map(|n| {
                        e.props
                            .iter()
                            .position(|p| p.name == *n && p.list.is_none())
                    })
                };
                let (Some(x), Some(y), Some(z)) = (find(&["x"]), find(&["y"]), find(&["z"])) else {
                    return Err("the vertex element has no x, y and z".into());
                };
                let nx = find(&["nx"]);
                let ny = find(&["ny"]);
                let nz = find(&["nz"]);
                let u = find(&["u", "s", "texture_u", "texture_s"]);
                let v = find(&["v", "t", "texture_v", "texture_t"]);
                have_normals = nx.is_some() && ny.is_some() && nz.is_some();
                have_uv = u.is_some() && v.is_some();
                let mut values = vec![0.0f64; e.props.len()];
                mesh.p.reserve(e.count.min(1 << 24));
                let mut push = |values: &[f64]| {
                    let f = |i: usize| values[i] as f32;
                    mesh.p.push(Vec3::new(f(x), f(y), f(z)));
                    if have_normals {
                        normals.push(Vec3::new(f(nx.unwrap()), f(ny.unwrap()), f(nz.unwrap())));
                    }
                    if have_uv {
                        uvs.push(Vec2::new(f(u.unwrap()), f(v.unwrap())));
                    }
                };
                // A binary file's vertices without lists all have one size: each value is
                // read where it lies (the same values and errors as value by value).
                let stride: usize = e.props.iter().map(|p| p.ty.size()).sum();
                let fixed = fast
                    && format != Format::Ascii
                    && e.props.iter().all(|p| p.list.is_none())
                    && e.count.saturating_mul(stride) <= body.remaining();
                if fixed {
                    let big = format == Format::Big;
                    let offsets: Vec<usize> = e
                        .props
                        .iter()
                        .scan(0, |at, p| {
                            *at += p.ty.size();
                            Some(*at - p.ty.size())
                        })
                        .collect();
                    let data = &body.bytes[body.pos..body.pos + e.count * stride];
                    for (k, vertex) in data.chunks_exact(stride.max(1)).enumerate() {
                        for (j, p) in e.props.iter().enumerate() {
                            values[j] = finite(decode(&vertex[offsets[j]..], p.ty, big))
                                .map_err(|m| format!("vertex {k}: {m}"))?;
                        }
                        push(&values);
                    }
                    body.pos += e.count * stride;
                    continue;
                }
                for k in 0..e.count {
                    for (j, p) in e.props.iter().enumerate() {
                        match p.list {
                            None => {
                                values[j] =
                                    body.scalar(p.ty).map_err(|m| format!("vertex {k}: {m}"))?
                            }
                            Some(c) => {
                                let count =
                                    body.scalar(c).map_err(|m| format!("vertex {k}: {m}"))?;
                                for _ in 0..count.max(0.0) as usize {
                                    body.scalar(p.ty).map_err(|m| format!("vertex {k}: {m}"))?;
                                }
                            }
                        }
                    }
                    push(&values);
                }
            }
            "face" => {
                let Some(list) = e.props.iter().position(|p| {
                    p.list.is_some() && (p.name == "vertex_indices" || p.name == "vertex_index")
                }) else {
                    return Err("the face element has no vertex_indices list".into());
                };
                mesh.indices.reserve(3 * e.count.min(1 << 26));
                let integer = |t: Scalar| !matches!(t, Scalar::F32 | Scalar::F64);
                if fast
                    && format != Format::Ascii
                    && e.props
                        .iter()
                        .all(|p| p.list.is_none_or(|c| integer(c) && integer(p.ty)))
                {
                    body.pos = binary_faces(e, list, body.bytes, body.pos, format, &mut mesh)?;
                    continue;
                }
                let mut corners = Vec::new();
                for k in 0..e.count {
                    for (j, p) in e.props.iter().enumerate() {
                        match p.list {
                            None => {
                                body.scalar(p.ty).map_err(|m| format!("face {k}: {m}"))?;
                            }
                            Some(c) => {
                                let count = body.scalar(c).map_err(|m| format!("face {k}: {m}"))?;
                                if !(0.0..=1e6).contains(&count) {
                                    return Err(format!("face {k}: a list of {count} entries"));
                                }
                                corners.clear();
                                for _ in 0..count as usize {
                                    corners.push(
                                        body.scalar(p.ty).map_err(|m| format!("face {k}: {m}"))?,
                                    );
                                }
                                if j != list {
                                    continue;
                                }
                                if corners.len() < 3 {
                                    return Err(format!("face {k}: {} vertices", corners.len()));
                                }
                                for &c in &corners {
                                    if c < 0.0 || c.fract() != 0.0 || c >= u32::MAX as f64 {
                                        return Err(format!("face {k}: bad vertex index {c}"));
                                    }
                                }
                                // A fan: (0, 1, 2), (0, 2, 3), ...
                                for t in 1..corners.len() - 1 {
                                    mesh.indices.extend([
                                        corners[0] as u32,
                                        corners[t] as u32,
                                        corners[t + 1] as u32,
                                    ]);
                                }
                            }
                        }
                    }
                }
            }
            _ => {
                for k in 0..e.count {
                    for p in &e.props {
                        let count = match p.list {
                            Some(c) => {
                                body.scalar(c).map_err(|m| format!("{} {k}: {m}", e.name))?
                            }
                            None => 1.0,
                        };
                        for _ in 0..count.max(0.0) as usize {
                            body.scalar(p.ty)
                                .map_err(|m| format!("{} {k}: {m}", e.name))?;
                        }
                    }
                }
            }
        }
    }
    if let Some(bad) = mesh.indices.iter().find(|&&i| i as usize >= mesh.p.len()) {
        return Err(format!(
            "vertex index {bad} out of range ({} vertices)",
            mesh.p.len()
        ));
    }
    if mesh.p.is_empty() {
        return Err("no vertices".into());
    }
    mesh.n = have_normals.then_some(normals);
    mesh.uv = have_uv.then_some(uvs);
    Ok(mesh)
}

/// The faces of a binary file whose lists hold integers, read from `pos` (the same
/// triangles and errors as value by value; `list`: the vertex_indices property). Returns
/// where they end.
fn binary_faces(
    e: &Element,
    list: usize,
    bytes: &[u8],
    mut pos: usize,
    format: Format,
    mesh: &mut PlyMesh,
) -> Result<usize, String> {
    let big = format == Format::Big;
    let early = |k: usize| format!("face {k}: the file ends early");
    for k in 0..e.count {
        for (j, p) in e.props.iter().enumerate() {
            let size = p.ty.size();
            let Some(c) = p.list else {
                if bytes.len() - pos < size {
                    return Err(early(k));
                }
                finite(decode(&bytes[pos..], p.ty, big)).map_err(|m| format!("face {k}: {m}"))?;
                pos += size;
                continue;
            };
            if bytes.len() - pos < c.size() {
                return Err(early(k));
            }
            let count = decode(&bytes[pos..], c, big);
            pos += c.size();
            if !(0.0..=1e6).contains(&count) {
                return Err(format!("face {k}: a list of {count} entries"));
            }
            let count = count as usize;
            if bytes.len() - pos < count * size {
                return Err(early(k));
            }
            let values = &bytes[pos..pos + count * size];
            pos += count * size;
            if j != list {
                continue;
            }
            if count < 3 {
                return Err(format!("face {k}: {count} vertices"));
            }
            let corner = |t: usize| decode(&values[t * size..], p.ty, big);
            for t in 0..count {
                let c = corner(t);
                if c < 0.0 || c >= u32::MAX as f64 {
                    return Err(format!("face {k}: bad vertex index {c}"));
                }
            }
            // A fan: (0, 1, 2), (0, 2, 3), ...
            let first = corner(0) as u32;
            for t in 1..count - 1 {
                mesh.indices
                    .extend([first, corner(t) as u32, corner(t + 1) as u32]);
            }
        }
    }
    Ok(pos)
}

struct Body<'a> {
    bytes: &'a [u8],
    pos: usize,
    format: Format,
}

impl Body<'_> {
    fn remaining(&self) -> usize {
        self.bytes.len() - self.pos
    }

    #[inline]
    fn scalar(&mut self, ty: Scalar) -> Result<f64, String> {
        if self.format == Format::Ascii {
            while self.pos < self.bytes.len() && self.bytes[self.pos].is_ascii_whitespace() {
                self.pos += 1;
            }
            let start = self.pos;
            while self.pos < self.bytes.len() && !self.bytes[self.pos].is_ascii_whitespace() {
                self.pos += 1;
            }
            if start == self.pos {
                return Err("the file ends early".into());
            }
            let word = std::str::from_utf8(&self.bytes[start..self.pos]).unwrap_or("?");
            return word
                .parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| format!("expected a number, got '{word}'"));
        }
        let n = ty.size();
        if self.remaining() < n {
            return Err("the file ends early".into());
        }
        let x = decode(
            &self.bytes[self.pos..self.pos + n],
            ty,
            self.format == Format::Big,
        );
        self.pos += n;
        finite(x)
    }
}

/// A binary value of type `ty` at the start of `b` (at least its size).
#[inline(always)]
fn decode(b: &[u8], ty: Scalar, big: bool) -> f64 {
    macro_rules! read {
        ($t:ty, $n:literal) => {{
            let a: [u8; $n] = b[..$n].try_into().unwrap();
            if big {
                <$t>::from_be_bytes(a) as f64
            } else {
                <$t>::from_le_bytes(a) as f64
            }
        }};
    }
    match ty {
        Scalar::I8 => b[0] as i8 as f64,
        Scalar::U8 => b[0] as f64,
        Scalar::I16 => read!(i16, 2),
        Scalar::U16 => read!(u16, 2),
        Scalar::I32 => read!(i32, 4),
        Scalar::U32 => read!(u32, 4),
        Scalar::F32 => read!(f32, 4),
        Scalar::F64 => read!(f64, 8),
    }
}

/// `x`, or the error of a non-finite value (only a float's can be).
#[inline(always)]
fn finite(x: f64) -> Result<f64, String> {
    if x.is_finite() {
        Ok(x)
    } else {
        Err(format!("a non-finite value {x}"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const HEADER: &str = "ply\nformat {FORMAT} 1.0\ncomment a unit square and a triangle\n\
        element vertex 5\nproperty float x\nproperty float y\nproperty float z\n\
        property float nx\nproperty float ny\nproperty float nz\nproperty float u\nproperty float v\n\
        element face 2\nproperty list uchar int vertex_indices\nproperty int face_indices\n\
        element edge 1\nproperty int vertex1\nproperty list uchar short extra\nend_header\n";

    fn vertices() -> Vec<[f32; 8]> {
        vec![
            [0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0],
            [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 0.0],
            [1.0, 1.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0],
            [0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0],
            [5.0, 5.0, 5.0, 0.0, 1.0, 0.0, 0.5, 0.5],
        ]
    }

    fn binary(big: bool) -> Vec<u8> {
        let mut out = HEADER
            .replace(
                "{FORMAT}",
                if big {
                    "binary_big_endian"
                } else {
                    "binary_little_endian"
                },
            )
            .into_bytes();
        let f = |x: f32| {
            if big {
                x.to_be_bytes()
            } else {
                x.to_le_bytes()
            }
        };
        let i = |x: i32| {
            if big {
                x.to_be_bytes()
            } else {
                x.to_le_bytes()
            }
        };
        for v in vertices() {
            for x in v {
                out.extend(f(x));
            }
        }
        out.push(4);
        for k in [0, 1, 2, 3] {
            out.extend(i(k));
        }
        out.extend(i(7));
        out.push(3);
        for k in [0, 2, 4] {
            out.extend(i(k));
        }
        out.extend(i(8));
        // The edge element: an int and a list of two shorts.
        out.extend(i(1));
        out.push(2);
        out.extend(if big {
            3i16.to_be_bytes()
        } else {
            3i16.to_le_bytes()
        });
        out.extend(if big {
            4i16.to_be_bytes()
        } else {
            4i16.to_le_bytes()
        });
        out
    }

    fn check(m: &PlyMesh) {
        assert_eq!(m.p.len(), 5);
        assert_eq!(m.p[4], Vec3::splat(5.0));
        assert_eq!(m.indices, vec![0, 1, 2, 0, 2, 3, 0, 2, 4]);
        assert_eq!(m.n.as_ref().unwrap()[4], Vec3::Y);
        assert_eq!(m.uv.as_ref().unwrap()[2], Vec2::ONE);
    }

    #[test]
    fn ascii_and_binary_in_both_byte_orders_read_alike() {
        let mut ascii = HEADER.replace("{FORMAT}", "ascii");
        for v in vertices() {
            ascii += &v.map(|x| x.to_string()).join(" ");
            ascii += "\n";
        }
        ascii += "4 0 1 2 3 7\n3 0 2 4 8\n1 2 3 4\n";
        check(&parse_ply(ascii.as_bytes()).unwrap());
        check(&parse_ply(&binary(false)).unwrap());
        check(&parse_ply(&binary(true)).unwrap());
    }

    #[test]
    fn bulk_reads_match_value_by_value_reads() {
        // Random binary files (property types and orders, lists of 0 to 5 corners, extra
        // properties and elements), whole, cut short and with bytes changed: the bulk
        // paths give the same mesh or the same error as the value-by-value ones.
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = |n: u64| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state % n
        };
        let types = [
            ("char", 1),
            ("uchar", 1),
            ("short", 2),
            ("ushort", 2),
            ("int", 4),
            ("uint", 4),
            ("float", 4),
            ("double", 8),
        ];
        let (mut bulk, mut errors) = (0, 0);
        for file in 0..300 {
            let big = file % 2 == 1;
            let vertices = 1 + next(20) as usize;
            let mut header = format!(
                "ply\nformat binary_{}_endian 1.0\nelement vertex {vertices}\n",
                if big { "big" } else { "little" }
            );
            let mut names = vec!["x", "y", "z", "u", "v", "nx", "ny", "nz", "w"];
            names.truncate(3 + next(7) as usize);
            for i in (1..names.len()).rev() {
                names.swap(i, next(i as u64 + 1) as usize);
            }
            let vtypes: Vec<(&str, usize)> =
                names.iter().map(|_| types[next(8) as usize]).collect();
            for (n, t) in names.iter().zip(&vtypes) {
                header += &format!("property {} {n}\n", t.0);
            }
            let faces = next(30) as usize;
            let count_type = types[next(6) as usize];
            let index_type = types[2 + next(if file % 5 == 0 { 6 } else { 4 }) as usize];
            let extra = next(2) == 0;
            header += &format!(
                "element face {faces}\nproperty list {} {} vertex_indices\n",
                count_type.0, index_type.0
            );
            if extra {
                header += "property float quality\n";
            }
            header += "end_header\n";
            let mut out = header.into_bytes();
            let value = |out: &mut Vec<u8>, (t, size): (&str, usize), x: f64| {
                let b: Vec<u8> = match t {
                    "char" => vec![x as i8 as u8],
                    "uchar" => vec![x as u8],
                    "short" => (x as i16).to_le_bytes().to_vec(),
                    "ushort" => (x as u16).to_le_bytes().to_vec(),
                    "int" => (x as i32).to_le_bytes().to_vec(),
                    "uint" => (x as u32).to_le_bytes().to_vec(),
                    "float" => (x as f32).to_le_bytes().to_vec(),
                    _ => x.to_le_bytes().to_vec(),
                };
                assert_eq!(b.len(), size);
                out.extend(
                    b.iter()
                        .rev()
                        .filter(|_| big)
                        .chain(b.iter().filter(|_| !big)),
                );
            };
            for _ in 0..vertices {
                for &t in &vtypes {
                    value(&mut out, t, next(200) as f64 / 8.0);
                }
            }
            for _ in 0..faces {
                // (Now and then a list too short or an index out of range.)
                let corners = if next(50) == 0 { next(3) } else { 3 + next(3) };
                value(&mut out, count_type, corners as f64);
                for _ in 0..corners {
                    let index = match next(400) {
                        0 => vertices as f64 + 9.0,
                        1 => u32::MAX as f64,
                        _ => next(vertices as u64) as f64,
                    };
                    value(&mut out, index_type, index);
                }
                if extra {
                    value(&mut out, ("float", 4), 0.5);
                }
            }
            let mut files = vec![out.clone()];
            for _ in 0..8 {
                let mut cut = out.clone();
                cut.truncate(next(out.len() as u64) as usize);
                files.push(cut);
                let mut bad = out.clone();
                let at = next(out.len() as u64) as usize;
                bad[at] = [0, 0xff, 0x7f, 0x80][next(4) as usize];
                files.push(bad);
            }
            for f in &files {
                let (a, b) = (parse(f, true), parse(f, false));
                assert_eq!(a, b, "file {file}");
                bulk += a.is_ok() as usize;
                errors += a.is_err() as usize;
            }
        }
        // Both outcomes are common.
        assert!(bulk > 300 && errors > 1000, "{bulk} read, {errors} errors");
    }

    #[test]
    fn gzip_files_are_read() {
        use std::io::Write;
        let d = std::env::temp_dir().join(format!("lightpath-ply-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        let path = d.join("m.ply.gz");
        let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
        gz.write_all(&binary(false)).unwrap();
        std::fs::write(&path, gz.finish().unwrap()).unwrap();
        check(&read_ply(&path).unwrap());
        std::fs::remove_dir_all(&d).ok();
    }

    #[test]
    fn bad_files_are_errors_not_panics() {
        let good = binary(false);
        // Every truncation is an error (or, cut in the trailing edge element, still an
        // error: the file ends early).
        for cut in 0..good.len() {
            assert!(parse_ply(&good[..cut]).is_err(), "cut at {cut}");
        }
        // Every single-byte corruption parses or fails cleanly.
        for at in 0..good.len() {
            for b in [0u8, 0xff, b'\n', b'9'] {
                let mut bad = good.clone();
                bad[at] = b;
                let _ = parse_ply(&bad);
            }
        }
        let e = parse_ply(
            b"ply\nformat ascii 1.0\nelement vertex 99999999999\nproperty float x\nend_header\n1\n",
        )
        .unwrap_err();
        assert!(e.contains("cannot fit"), "{e}");
        let e = parse_ply(b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n3 0 1 2\n").unwrap_err();
        assert!(e.contains("out of range"), "{e}");
    }
}

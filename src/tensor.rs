//! Tensor files: the container format of the RGL material database's `.bsdf` files, as read
//! by pbrt-v4's `measured` material and Mitsuba 3's `measured` BSDF.
//!
//! Layout, little-endian throughout:
//! - 12 bytes magic, `tensor_file` and a NUL byte;
//! - 2 bytes version, major 1 and minor 0;
//! - u32 field count;
//! - per field: u16 name length, the UTF-8 name, u16 ndim, u8 dtype code, u64 absolute byte
//!   offset of the data, ndim × u64 shape;
//! - per field, at its offset (no alignment assumed): product(shape) elements of its dtype in
//!   C (row-major) order.
//!
//! Parsing checks every length, offset and product, so malformed input gives an error naming
//! the file, never a panic or a huge allocation.
use anyhow::{anyhow, bail, Context, Result};
use std::path::Path;

/// The magic bytes that open every tensor file.
const MAGIC: &[u8; 12] = b"tensor_file\0";
/// Magic, version and field count.
const HEADER_LEN: usize = 12 + 2 + 4;
/// The smallest field header: name length, ndim, dtype code and offset (empty name, ndim 0).
const MIN_FIELD_HEADER_LEN: usize = 2 + 2 + 1 + 8;

/// Element type of a field, with the format's numeric codes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Dtype {
    U8,
    I8,
    U16,
    I16,
    U32,
    I32,
    U64,
    I64,
    F16,
    F32,
    F64,
}

impl Dtype {
    /// The format's code for this type (1 = u8 … 11 = f64).
    pub fn code(self) -> u8 {
        match self {
            Dtype::U8 => 1,
            Dtype::I8 => 2,
            Dtype::U16 => 3,
            Dtype::I16 => 4,
            Dtype::U32 => 5,
            Dtype::I32 => 6,
            Dtype::U64 => 7,
            Dtype::I64 => 8,
            Dtype::F16 => 9,
            Dtype::F32 => 10,
            Dtype::F64 => 11,
        }
    }

    /// The type with format code `code`, or `None` for an unknown code.
    pub fn from_code(code: u8) -> Option<Dtype> {
        Some(match code {
            1 => Dtype::U8,
            2 => Dtype::I8,
            3 => Dtype::U16,
            4 => Dtype::I16,
            5 => Dtype::U32,
            6 => Dtype::I32,
            7 => Dtype::U64,
            8 => Dtype::I64,
            9 => Dtype::F16,
            10 => Dtype::F32,
            11 => Dtype::F64,
            _ => return None,
        })
    }

    /// Size of one element in bytes.
    pub fn size(self) -> usize {
        match self {
            Dtype::U8 | Dtype::I8 => 1,
            Dtype::U16 | Dtype::I16 | Dtype::F16 => 2,
            Dtype::U32 | Dtype::I32 | Dtype::F32 => 4,
            Dtype::U64 | Dtype::I64 | Dtype::F64 => 8,
        }
    }
}

/// One named array of a tensor file. The data is kept as raw little-endian bytes, whose
/// length is always `len() * dtype.size()`.
#[derive(Clone, Debug, PartialEq)]
pub struct Field {
    pub name: String,
    pub shape: Vec<usize>,
    pub dtype: Dtype,
    bytes: Vec<u8>,
}

/// Product of `shape`, or `None` on overflow (1 for an empty shape).
fn checked_len(shape: &[usize]) -> Option<usize> {
    shape.iter().try_fold(1usize, |n, &d| n.checked_mul(d))
}

/// IEEE 754 binary16 to binary32, exact for every value: subnormals, infinities, NaN payloads
/// and signed zeros included.
pub fn f16_to_f32(h: u16) -> f32 {
    let sign = u32::from(h >> 15) << 31;
    let exp = u32::from((h >> 10) & 0x1f);
    let mant = u32::from(h & 0x3ff);
    let bits = match exp {
        0 => {
            // Zero or subnormal: mant × 2^-24, exact in f32 since mant < 2^10.
            let magnitude = mant as f32 * f32::from_bits(0x3380_0000);
            return if sign != 0 { -magnitude } else { magnitude };
        }
        0x1f => sign | 0x7f80_0000 | (mant << 13),
        _ => sign | ((exp + 127 - 15) << 23) | (mant << 13),
    };
    f32::from_bits(bits)
}

impl Field {
    /// Number of elements: the product of the shape, 1 for ndim 0.
    pub fn len(&self) -> usize {
        self.bytes.len() / self.dtype.size()
    }

    /// Whether the field has no elements (some dimension is 0).
    pub fn is_empty(&self) -> bool {
        self.bytes.is_empty()
    }

    /// The raw little-endian data bytes.
    pub fn bytes(&self) -> &[u8] {
        &self.bytes
    }

    /// The elements converted to f32, whatever the dtype: f16 exactly, integers and f64
    /// rounded to nearest.
    pub fn to_f32(&self) -> Vec<f32> {
        fn conv<const N: usize>(bytes: &[u8], f: impl Fn([u8; N]) -> f32) -> Vec<f32> {
            bytes
                .chunks_exact(N)
                .map(|c| {
                    let mut a = [0u8; N];
                    a.copy_from_slice(c);
                    f(a)
                })
                .collect()
        }
        let b = &self.bytes;
        match self.dtype {
            Dtype::U8 => b.iter().map(|&x| f32::from(x)).collect(),
            Dtype::I8 => b.iter().map(|&x| f32::from(x as i8)).collect(),
            Dtype::U16 => conv(b, |a| f32::from(u16::from_le_bytes(a))),
            Dtype::I16 => conv(b, |a| f32::from(i16::from_le_bytes(a))),
            Dtype::U32 => conv(b, |a| u32::from_le_bytes(a) as f32),
            Dtype::I32 => conv(b, |a| i32::from_le_bytes(a) as f32),
            Dtype::U64 => conv(b, |a| u64::from_le_bytes(a) as f32),
            Dtype::I64 => conv(b, |a| i64::from_le_bytes(a) as f32),
            Dtype::F16 => conv(b, |a| f16_to_f32(u16::from_le_bytes(a))),
            Dtype::F32 => conv(b, f32::from_le_bytes),
            Dtype::F64 => conv(b, |a| f64::from_le_bytes(a) as f32),
        }
    }

    /// The elements of a `U8` field; `None` for any other dtype.
    pub fn to_u8(&self) -> Option<Vec<u8>> {
        (self.dtype == Dtype::U8).then(|| self.bytes.clone())
    }

    /// A `U8` field as text (invalid UTF-8 replaced), trailing NULs trimmed; `None` for any
    /// other dtype.
    pub fn text(&self) -> Option<String> {
        if self.dtype != Dtype::U8 {
            return None;
        }
        let end = self
            .bytes
            .iter()
            .rposition(|&b| b != 0)
            .map_or(0, |i| i + 1);
        Some(String::from_utf8_lossy(&self.bytes[..end]).into_owned())
    }

    /// An `F32` field.
    ///
    /// # Panics
    /// If `values.len()` is not the product of `shape`.
    pub fn from_f32(name: &str, shape: &[usize], values: &[f32]) -> Field {
        assert_eq!(
            checked_len(shape),
            Some(values.len()),
            "tensor field `{name}`: {} values for shape {shape:?}",
            values.len()
        );
        Field {
            name: name.to_string(),
            shape: shape.to_vec(),
            dtype: Dtype::F32,
            bytes: values.iter().flat_map(|v| v.to_le_bytes()).collect(),
        }
    }

    /// A `U8` field.
    ///
    /// # Panics
    /// If `values.len()` is not the product of `shape`.
    pub fn from_u8(name: &str, shape: &[usize], values: &[u8]) -> Field {
        assert_eq!(
            checked_len(shape),
            Some(values.len()),
            "tensor field `{name}`: {} values for shape {shape:?}",
            values.len()
        );
        Field {
            name: name.to_string(),
            shape: shape.to_vec(),
            dtype: Dtype::U8,
            bytes: values.to_vec(),
        }
    }

    /// A field of any dtype from its raw little-endian bytes, or an error if their length is
    /// not the product of `shape` times the element size.
    pub fn from_raw(name: &str, shape: &[usize], dtype: Dtype, bytes: Vec<u8>) -> Result<Field> {
        let expected = checked_len(shape).and_then(|n| n.checked_mul(dtype.size()));
        if expected != Some(bytes.len()) {
            bail!(
                "tensor field `{name}`: {} bytes of data for shape {shape:?} of {dtype:?}",
                bytes.len()
            );
        }
        Ok(Field {
            name: name.to_string(),
            shape: shape.to_vec(),
            dtype,
            bytes,
        })
    }
}

/// Bounds-checked little-endian reading from a byte slice.
struct Reader<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Reader<'a> {
    fn slice(&mut self, n: usize) -> Option<&'a [u8]> {
        let end = self.pos.checked_add(n)?;
        let s = self.bytes.get(self.pos..end)?;
        self.pos = end;
        Some(s)
    }

    fn array<const N: usize>(&mut self) -> Option<[u8; N]> {
        let mut a = [0u8; N];
        a.copy_from_slice(self.slice(N)?);
        Some(a)
    }

    fn u8(&mut self) -> Option<u8> {
        self.array::<1>().map(|a| a[0])
    }

    fn u16(&mut self) -> Option<u16> {
        self.array().map(u16::from_le_bytes)
    }

    fn u64(&mut self) -> Option<u64> {
        self.array().map(u64::from_le_bytes)
    }
}

/// The contents of a tensor file: its fields in file order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TensorFile {
    pub fields: Vec<Field>,
}

impl TensorFile {
    /// Parses a whole tensor file; `what` names the file in error messages.
    pub fn parse(bytes: &[u8], what: &str) -> Result<TensorFile> {
        let len = bytes.len();
        let prefix = &bytes[..len.min(MAGIC.len())];
        if prefix != &MAGIC[..prefix.len()] {
            bail!(
                "{what}: not a tensor file (starts with {:?}, expected {:?})",
                String::from_utf8_lossy(prefix),
                String::from_utf8_lossy(MAGIC)
            );
        }
        if len < HEADER_LEN {
            bail!(
                "{what}: file of {len} bytes is shorter than the {HEADER_LEN}-byte tensor \
                 file header"
            );
        }
        let (major, minor) = (bytes[12], bytes[13]);
        if (major, minor) != (1, 0) {
            bail!("{what}: unsupported tensor file version {major}.{minor} (expected 1.0)");
        }
        let mut count = [0u8; 4];
        count.copy_from_slice(&bytes[14..18]);
        let count = u32::from_le_bytes(count);
        let room = (len - HEADER_LEN) as u64;
        if u64::from(count) * MIN_FIELD_HEADER_LEN as u64 > room {
            bail!(
                "{what}: field count {count} is implausibly large for a file of {len} bytes \
                 (each field header needs at least {MIN_FIELD_HEADER_LEN} bytes)"
            );
        }
        let mut r = Reader {
            bytes,
            pos: HEADER_LEN,
        };
        let mut fields = Vec::with_capacity(count as usize);
        for index in 0..count as usize {
            fields.push(parse_field(&mut r, index, what)?);
        }
        Ok(TensorFile { fields })
    }

    /// Reads and parses the tensor file at `path`; errors name the path.
    pub fn read(path: &Path) -> Result<TensorFile> {
        let bytes = std::fs::read(path)
            .with_context(|| format!("reading tensor file {}", path.display()))?;
        TensorFile::parse(&bytes, &path.display().to_string())
    }

    /// The first field called `name`.
    pub fn field(&self, name: &str) -> Option<&Field> {
        self.fields.iter().find(|f| f.name == name)
    }

    /// The field `name` as f32 values with exactly the given shape, or an error naming the
    /// file, the field and the shape expected and found.
    pub fn f32_field(&self, name: &str, shape: &[usize], what: &str) -> Result<Vec<f32>> {
        let field = self
            .field(name)
            .ok_or_else(|| anyhow!("{what}: no field `{name}` (expected shape {shape:?})"))?;
        if field.shape != shape {
            bail!(
                "{what}: field `{name}` has shape {:?}, expected {shape:?}",
                field.shape
            );
        }
        Ok(field.to_f32())
    }

    /// The file's bytes: the header, then each field's data in order at an 8-byte aligned
    /// offset, zero padded.
    ///
    /// # Panics
    /// If there are more than `u32::MAX` fields, or a field's name is longer than 65535
    /// bytes or its shape has more than 65535 dimensions.
    pub fn to_bytes(&self) -> Vec<u8> {
        assert!(
            u32::try_from(self.fields.len()).is_ok(),
            "too many tensor fields"
        );
        let header_len = HEADER_LEN
            + self
                .fields
                .iter()
                .map(|f| MIN_FIELD_HEADER_LEN + f.name.len() + 8 * f.shape.len())
                .sum::<usize>();
        let mut offsets = Vec::with_capacity(self.fields.len());
        let mut end = header_len;
        for f in &self.fields {
            let offset = end.next_multiple_of(8);
            offsets.push(offset);
            end = offset + f.bytes.len();
        }
        let mut out = Vec::with_capacity(end);
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&[1, 0]);
        out.extend_from_slice(&(self.fields.len() as u32).to_le_bytes());
        for (f, &offset) in self.fields.iter().zip(&offsets) {
            assert!(
                f.name.len() <= usize::from(u16::MAX),
                "tensor field name of {} bytes is too long",
                f.name.len()
            );
            assert!(
                f.shape.len() <= usize::from(u16::MAX),
                "tensor field `{}` has too many dimensions",
                f.name
            );
            out.extend_from_slice(&(f.name.len() as u16).to_le_bytes());
            out.extend_from_slice(f.name.as_bytes());
            out.extend_from_slice(&(f.shape.len() as u16).to_le_bytes());
            out.push(f.dtype.code());
            out.extend_from_slice(&(offset as u64).to_le_bytes());
            for &d in &f.shape {
                out.extend_from_slice(&(d as u64).to_le_bytes());
            }
        }
        for (f, &offset) in self.fields.iter().zip(&offsets) {
            out.resize(offset, 0);
            out.extend_from_slice(&f.bytes);
        }
        out
    }
}

/// Parses the header of field number `index` at the reader's position, and copies its data.
fn parse_field(r: &mut Reader<'_>, index: usize, what: &str) -> Result<Field> {
    let len = r.bytes.len();
    let start = r.pos;
    let truncated = || {
        anyhow!(
            "{what}: the header of field #{index} (from byte {start}) extends beyond the end \
             of the file ({len} bytes)"
        )
    };
    let name_len = r.u16().ok_or_else(truncated)?;
    let name = r.slice(usize::from(name_len)).ok_or_else(truncated)?;
    let name = std::str::from_utf8(name)
        .map_err(|e| anyhow!("{what}: the name of field #{index} is not UTF-8 ({e})"))?
        .to_string();
    let ndim = r.u16().ok_or_else(truncated)?;
    let code = r.u8().ok_or_else(truncated)?;
    let dtype = Dtype::from_code(code).ok_or_else(|| {
        anyhow!("{what}: field #{index} `{name}` has unknown dtype code {code} (expected 1 to 11)")
    })?;
    let offset = r.u64().ok_or_else(truncated)?;
    let mut shape = Vec::with_capacity(usize::from(ndim));
    let mut dims = Vec::with_capacity(usize::from(ndim));
    for _ in 0..ndim {
        let d = r.u64().ok_or_else(truncated)?;
        dims.push(d);
        shape.push(usize::try_from(d).ok());
    }
    let size = shape
        .iter()
        .try_fold(1usize, |n, &d| n.checked_mul(d?))
        .and_then(|n| n.checked_mul(dtype.size()))
        .ok_or_else(|| {
            anyhow!(
                "{what}: field #{index} `{name}`: the size of shape {dims:?} of {dtype:?} overflows"
            )
        })?;
    let range = usize::try_from(offset)
        .ok()
        .and_then(|o| Some(o..o.checked_add(size)?))
        .filter(|range| range.end <= len);
    let Some(range) = range else {
        bail!(
            "{what}: data of field #{index} `{name}` (offset {offset}, {size} bytes) extends \
             beyond the end of the file ({len} bytes)"
        );
    };
    Ok(Field {
        name,
        shape: shape.into_iter().flatten().collect(),
        dtype,
        bytes: r.bytes[range].to_vec(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One f32 field `a` of shape [2]: header 40 bytes (name at 20, dtype code at 23, offset
    /// at 24..32, shape at 32..40), data at 40..48.
    fn one() -> Vec<u8> {
        let tf = TensorFile {
            fields: vec![Field::from_f32("a", &[2], &[1.0, 2.0])],
        };
        let bytes = tf.to_bytes();
        assert_eq!(bytes.len(), 48);
        bytes
    }

    fn sample() -> TensorFile {
        let values: Vec<f32> = (0..120).map(|i| i as f32 * 0.25 - 7.0).collect();
        let halves: Vec<u8> = [0x3c00u16, 0xc000, 0x0001]
            .iter()
            .flat_map(|h| h.to_le_bytes())
            .collect();
        TensorFile {
            fields: vec![
                Field::from_u8("description", &[7], b"hello\0\0"),
                Field::from_f32("data", &[2, 3, 4, 5], &values),
                Field::from_f32("scalar", &[], &[f32::NAN]),
                Field::from_u8("empty", &[3, 0], &[]),
                Field::from_raw("half", &[3], Dtype::F16, halves).unwrap(),
                Field::from_f32("tail", &[3], &[1.0, -0.0, f32::INFINITY]),
            ],
        }
    }

    /// The data offsets written in a file's header.
    fn offsets(bytes: &[u8]) -> Vec<u64> {
        let count = u32::from_le_bytes(bytes[14..18].try_into().unwrap());
        let mut pos = 18;
        let mut out = Vec::new();
        for _ in 0..count {
            let name_len = u16::from_le_bytes(bytes[pos..pos + 2].try_into().unwrap()) as usize;
            pos += 2 + name_len;
            let ndim = u16::from_le_bytes(bytes[pos..pos + 2].try_into().unwrap()) as usize;
            pos += 3;
            out.push(u64::from_le_bytes(bytes[pos..pos + 8].try_into().unwrap()));
            pos += 8 + 8 * ndim;
        }
        out
    }

    fn error(bytes: &[u8]) -> String {
        format!("{:#}", TensorFile::parse(bytes, "test.bsdf").unwrap_err())
    }

    #[test]
    fn round_trip() {
        let tf = sample();
        let bytes = tf.to_bytes();
        assert_eq!(&bytes[..12], b"tensor_file\0");
        assert!(offsets(&bytes).iter().all(|o| o % 8 == 0));
        let back = TensorFile::parse(&bytes, "test.bsdf").unwrap();
        assert_eq!(back.fields.len(), tf.fields.len());
        for (a, b) in tf.fields.iter().zip(&back.fields) {
            assert_eq!(a.name, b.name);
            assert_eq!(a.shape, b.shape);
            assert_eq!(a.dtype, b.dtype);
            assert_eq!(a.bytes(), b.bytes());
            let (fa, fb) = (a.to_f32(), b.to_f32());
            assert_eq!(fa.len(), fb.len());
            assert!(fa.iter().zip(&fb).all(|(x, y)| x.to_bits() == y.to_bits()));
        }
        assert_eq!(back.to_bytes(), bytes);

        let data = back.field("data").unwrap();
        assert_eq!(data.shape, vec![2, 3, 4, 5]);
        assert_eq!(data.len(), 120);
        assert_eq!(data.to_f32()[119], 119.0 * 0.25 - 7.0);
        assert!(data.to_u8().is_none() && data.text().is_none());
        let text = back.field("description").unwrap();
        assert_eq!(text.text().as_deref(), Some("hello"));
        assert_eq!(text.to_u8().unwrap(), b"hello\0\0");
        let scalar = back.field("scalar").unwrap();
        assert_eq!((scalar.len(), scalar.is_empty()), (1, false));
        let empty = back.field("empty").unwrap();
        assert_eq!((empty.len(), empty.is_empty()), (0, true));
        assert_eq!(
            back.field("half").unwrap().to_f32(),
            vec![1.0, -2.0, 2f32.powi(-24)]
        );
        assert!(back.field("missing").is_none());
    }

    #[test]
    fn unaligned_offset() {
        let field = Field::from_raw("b", &[3], Dtype::U16, vec![1, 0, 2, 0, 0xff, 0xff]);
        let mut bytes = TensorFile {
            fields: vec![field.unwrap()],
        }
        .to_bytes();
        assert_eq!(offsets(&bytes), vec![40]);
        bytes.insert(40, 0xaa);
        bytes[24..32].copy_from_slice(&41u64.to_le_bytes());
        let tf = TensorFile::parse(&bytes, "test.bsdf").unwrap();
        assert_eq!(tf.fields[0].to_f32(), vec![1.0, 2.0, 65535.0]);
    }

    #[test]
    fn f16_conversion() {
        assert_eq!(f16_to_f32(0x3c00), 1.0);
        assert_eq!(f16_to_f32(0xc000), -2.0);
        assert_eq!(f16_to_f32(0x7bff), 65504.0);
        assert_eq!(f16_to_f32(0x0001), 2f32.powi(-24));
        assert_eq!(f16_to_f32(0x03ff), 1023.0 * 2f32.powi(-24));
        assert_eq!(f16_to_f32(0x0400), 2f32.powi(-14));
        assert_eq!(f16_to_f32(0x3555), 1365.0 / 4096.0);
        assert_eq!(f16_to_f32(0x7c00), f32::INFINITY);
        assert_eq!(f16_to_f32(0xfc00), f32::NEG_INFINITY);
        assert!(f16_to_f32(0x7e00).is_nan());
        assert!(f16_to_f32(0xfc01).is_nan());
        assert_eq!(f16_to_f32(0x0000).to_bits(), 0);
        assert_eq!(f16_to_f32(0x8000).to_bits(), 0x8000_0000);
        // Every finite half against its definition.
        for h in 0..=u16::MAX {
            let exp = i32::from((h >> 10) & 0x1f);
            let mant = f64::from(h & 0x3ff);
            if exp == 0x1f {
                continue;
            }
            let magnitude = if exp == 0 {
                mant * 2f64.powi(-24)
            } else {
                (1.0 + mant / 1024.0) * 2f64.powi(exp - 15)
            };
            let expected = if h & 0x8000 != 0 {
                -magnitude
            } else {
                magnitude
            };
            assert_eq!(f64::from(f16_to_f32(h)), expected, "half {h:#06x}");
        }
        let bytes: Vec<u8> = [0x3c00u16, 0xc000, 0x7bff, 0x0001, 0x7c00, 0x7e00]
            .iter()
            .flat_map(|h| h.to_le_bytes())
            .collect();
        let v = Field::from_raw("h", &[2, 3], Dtype::F16, bytes)
            .unwrap()
            .to_f32();
        assert_eq!(
            &v[..5],
            &[1.0, -2.0, 65504.0, 2f32.powi(-24), f32::INFINITY]
        );
        assert!(v[5].is_nan());
    }

    #[test]
    fn integer_and_f64_conversion() {
        let cases: Vec<(Dtype, Vec<u8>, Vec<f32>)> = vec![
            (Dtype::U8, vec![0, 255], vec![0.0, 255.0]),
            (Dtype::I8, vec![0x80, 0x7f], vec![-128.0, 127.0]),
            (
                Dtype::U16,
                [65535u16].map(u16::to_le_bytes).concat(),
                vec![65535.0],
            ),
            (
                Dtype::I16,
                [-300i16].map(i16::to_le_bytes).concat(),
                vec![-300.0],
            ),
            (
                Dtype::U32,
                [1u32 << 31].map(u32::to_le_bytes).concat(),
                vec![2f32.powi(31)],
            ),
            (
                Dtype::I32,
                [-70000i32].map(i32::to_le_bytes).concat(),
                vec![-70000.0],
            ),
            (
                Dtype::U64,
                [u64::MAX].map(u64::to_le_bytes).concat(),
                vec![2f32.powi(64)],
            ),
            (
                Dtype::I64,
                [-5i64].map(i64::to_le_bytes).concat(),
                vec![-5.0],
            ),
            (
                Dtype::F32,
                [0.5f32].map(f32::to_le_bytes).concat(),
                vec![0.5],
            ),
            (
                Dtype::F64,
                [0.1f64].map(f64::to_le_bytes).concat(),
                vec![0.1f32],
            ),
        ];
        for (dtype, bytes, expected) in cases {
            assert_eq!(Dtype::from_code(dtype.code()), Some(dtype));
            let n = expected.len();
            let field = Field::from_raw("x", &[n], dtype, bytes).unwrap();
            assert_eq!(field.to_f32(), expected, "{dtype:?}");
        }
        assert!(Field::from_raw("x", &[2], Dtype::F32, vec![0; 4]).is_err());
        assert_eq!(Dtype::from_code(0), None);
        assert_eq!(Dtype::from_code(12), None);
    }

    #[test]
    fn errors() {
        assert!(TensorFile::parse(&one(), "test.bsdf").is_ok());

        let e = error(&one()[..10]);
        assert!(e.contains("test.bsdf") && e.contains("shorter than"), "{e}");

        let mut bytes = one();
        bytes[0] = b'x';
        let e = error(&bytes);
        assert!(
            e.contains("test.bsdf") && e.contains("not a tensor file"),
            "{e}"
        );
        assert!(error(b"PK\x03\x04").contains("not a tensor file"));

        let mut bytes = one();
        bytes[12] = 2;
        let e = error(&bytes);
        assert!(e.contains("version 2.0"), "{e}");
        let mut bytes = one();
        bytes[13] = 1;
        assert!(error(&bytes).contains("version 1.1"));

        for code in [0u8, 12, 255] {
            let mut bytes = one();
            bytes[23] = code;
            let e = error(&bytes);
            assert!(
                e.contains("dtype") && e.contains(&format!("code {code}")),
                "{e}"
            );
            assert!(e.contains("`a`"), "{e}");
        }

        let mut bytes = one();
        bytes[20] = 0xff;
        let e = error(&bytes);
        assert!(e.contains("not UTF-8") && e.contains("#0"), "{e}");

        let mut bytes = one();
        bytes[24..32].copy_from_slice(&44u64.to_le_bytes());
        let e = error(&bytes);
        assert!(e.contains("beyond the end") && e.contains("`a`"), "{e}");
        assert!(e.contains("offset 44") && e.contains("8 bytes") && e.contains("48 bytes"));
        let mut bytes = one();
        bytes[24..32].copy_from_slice(&u64::MAX.to_le_bytes());
        assert!(error(&bytes).contains("beyond the end"));

        let mut bytes = one();
        bytes[32..40].copy_from_slice(&u64::MAX.to_le_bytes());
        let e = error(&bytes);
        assert!(e.contains("overflow") && e.contains("`a`"), "{e}");
        let mut bytes = one();
        bytes[32..40].copy_from_slice(&(1u64 << 62).to_le_bytes());
        assert!(error(&bytes).contains("overflow"));

        let mut bytes = one();
        bytes[14..18].copy_from_slice(&u32::MAX.to_le_bytes());
        let e = error(&bytes);
        assert!(
            e.contains("implausibly large") && e.contains("4294967295"),
            "{e}"
        );
        let mut bytes = one();
        bytes[14..18].copy_from_slice(&2u32.to_le_bytes());
        assert!(error(&bytes).contains("field #1"));

        let mut bytes = one();
        bytes[21..23].copy_from_slice(&1000u16.to_le_bytes());
        assert!(error(&bytes).contains("beyond the end"));
    }

    #[test]
    fn truncation_never_panics() {
        let bytes = sample().to_bytes();
        for n in 0..bytes.len() {
            let e = TensorFile::parse(&bytes[..n], "test.bsdf");
            assert!(e.is_err(), "prefix of {n} bytes parsed");
            assert!(format!("{:#}", e.unwrap_err()).contains("test.bsdf"));
        }
        assert!(TensorFile::parse(&bytes, "test.bsdf").is_ok());
    }

    #[test]
    fn f32_field_shapes() {
        let tf = TensorFile {
            fields: vec![Field::from_f32(
                "a",
                &[2, 3],
                &[0.0, 1.0, 2.0, 3.0, 4.0, 5.0],
            )],
        };
        assert_eq!(tf.f32_field("a", &[2, 3], "x.bsdf").unwrap()[5], 5.0);
        let e = format!("{:#}", tf.f32_field("a", &[3, 2], "x.bsdf").unwrap_err());
        assert!(e.contains("x.bsdf") && e.contains("`a`"), "{e}");
        assert!(e.contains("[3, 2]") && e.contains("[2, 3]"), "{e}");
        let e = format!("{:#}", tf.f32_field("b", &[1], "x.bsdf").unwrap_err());
        assert!(e.contains("x.bsdf") && e.contains("`b`"), "{e}");
    }

    #[test]
    fn read_names_the_path() {
        let path =
            std::env::temp_dir().join(format!("lightpath-tensor-{}.bsdf", std::process::id()));
        std::fs::write(&path, sample().to_bytes()).unwrap();
        let tf = TensorFile::read(&path).unwrap();
        assert_eq!(tf, sample());
        std::fs::write(&path, b"not a tensor").unwrap();
        let e = format!("{:#}", TensorFile::read(&path).unwrap_err());
        assert!(e.contains(&path.display().to_string()), "{e}");
        std::fs::remove_file(&path).unwrap();
        let e = format!("{:#}", TensorFile::read(&path).unwrap_err());
        assert!(e.contains(&path.display().to_string()), "{e}");
    }
}

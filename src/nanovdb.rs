//! Reader for NanoVDB (`.nvdb`) Float grids as pbrt-v4's "nanovdb" medium uses them, and a
//! conversion to a sparse layout of 8³ bricks that a GPU kernel can index directly.
//!
//! Supported: the file container of NanoVDB major version 32 (segments made of a 16-byte header,
//! one 176-byte metadata record plus name per grid, then the grid payloads), codecs NONE and ZIP,
//! and the in-memory layout of Float grids (GridData, TreeData, root tile table, 32³ upper and
//! 16³ lower internal nodes, 8³ leaves). Value lookup and trilinear sampling reproduce pbrt-v4
//! (`SampleFromVoxels` order 1: no half-voxel offset, z interpolated first).
//!
//! Every offset in a loaded grid is checked once at load time, and all later reads are
//! bounds-checked as well, so corrupt input yields an error (or the background value), never a
//! panic.

use anyhow::{anyhow, bail, Context, Result};
use glam::{DVec3, I64Vec3, IVec3, UVec3, Vec3};
use std::collections::HashMap;
use std::io::Read;
use std::path::Path;

const FILE_MAGIC: u64 = 0x3042_4456_6f6e_614e; // "NanoVDB0"
const FILE_MAGIC_NEW: u64 = 0x3242_4456_6f6e_614e; // "NanoVDB2" (files from 32.9 writers)
const GRID_MAGIC_NEW: u64 = 0x3142_4456_6f6e_614e; // "NanoVDB1" (grids from 32.9 writers)
const META_SIZE: usize = 176;
const GRID_DATA_SIZE: usize = 672;
const TREE: usize = GRID_DATA_SIZE;
const ROOT_SIZE: usize = 64;
const TILE_SIZE: usize = 32;
/// Internal node layout: (child-mask offset, table offset, node size, log2 of the slot count).
type Layout = (usize, usize, usize, u32);
const UPPER: Layout = (4128, 8256, 270_400, 15);
const LOWER: Layout = (544, 1088, 33_856, 12);
const LEAF_VALUES: usize = 96;
const LEAF_SIZE: usize = 2144;
const MAX_TABLE: i64 = 1 << 28;
const CODECS: &str = "NONE ZIP BLOSC";
const GRID_TYPES: &str = "Unknown Float Double Int16 Int32 Int64 Vec3f Vec3d Mask Half UInt32 \
    Boolean RGBA8 Fp4 Fp8 Fp16 FpN Vec4f Vec4d";
const GRID_CLASSES: &str =
    "Unknown LevelSet FogVolume Staggered PointIndex PointData Topology VoxelVolume";

/// Entry `v` of a space-separated list of names.
fn label(names: &str, v: u32) -> String {
    let name = names.split_whitespace().nth(v as usize);
    name.map_or_else(|| format!("unknown ({v})"), str::to_string)
}

fn get<const N: usize>(b: &[u8], off: usize) -> Option<[u8; N]> {
    b.get(off..off.checked_add(N)?)?.try_into().ok()
}
macro_rules! readers {
    ($($f:ident: $t:ty),*) => {$(
        fn $f(b: &[u8], off: usize) -> Option<$t> { get(b, off).map(<$t>::from_le_bytes) }
    )*};
}
readers!(rd_u16: u16, rd_u32: u32, rd_i32: i32, rd_u64: u64, rd_i64: i64, rd_f32: f32, rd_f64: f64);

/// `N` consecutive little-endian values starting at `off` (default where out of range).
fn arr<T: Default, const N: usize>(
    rd: fn(&[u8], usize) -> Option<T>,
    b: &[u8],
    off: usize,
) -> [T; N] {
    std::array::from_fn(|i| rd(b, off + std::mem::size_of::<T>() * i).unwrap_or_default())
}
/// A NUL-terminated string stored in `b` (lossy UTF-8).
fn c_str(b: &[u8]) -> String {
    let end = b.iter().position(|&c| c == 0).unwrap_or(b.len());
    String::from_utf8_lossy(&b[..end]).into_owned()
}
/// `base + rel` as a buffer offset, `None` on overflow or a negative result.
fn offset(base: usize, rel: i64) -> Option<usize> {
    usize::try_from(i64::try_from(base).ok()?.checked_add(rel)?).ok()
}

/// NanoVDB's grid-name hash as stored in the file metadata (`nameKey`).
pub fn name_hash(name: &str) -> u64 {
    name.bytes().fold(0u64, |h, c| {
        (h.wrapping_mul(67)).wrapping_add(u64::from(c) + (h >> 56))
    })
}

/// Root tile key of the 4096³ region containing `ijk` (coordinates taken as u32, so negative
/// coordinates get large keys).
fn root_key(ijk: IVec3) -> u64 {
    let s = |v: i32| u64::from(v as u32 >> 12);
    s(ijk.z) | s(ijk.y) << 21 | s(ijk.x) << 42
}

/// pbrt-v4's trilinear filter: voxel values sit at integer index points; interpolate along z
/// first, then y, then x, with `lerp(a, b, w) = a + w·(b − a)`.
fn trilinear(p: Vec3, v: impl Fn(IVec3) -> f32) -> f32 {
    let f = p.floor();
    let (b, w) = (f.as_ivec3(), p - f);
    let at = |x, y, z| {
        v(IVec3::new(
            b.x.wrapping_add(x),
            b.y.wrapping_add(y),
            b.z.wrapping_add(z),
        ))
    };
    let lerp = |a: f32, b: f32, w: f32| a + w * (b - a);
    let yz = |x| {
        lerp(
            lerp(at(x, 0, 0), at(x, 0, 1), w.z),
            lerp(at(x, 1, 0), at(x, 1, 1), w.z),
            w.y,
        )
    };
    lerp(yz(0), yz(1), w.x)
}

/// Index↔world map of a grid (NanoVDB `Map`). Matrices are row-major, column-vector
/// convention: `world = mat · index + vec`, `index = inv_mat · (world − vec)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Map {
    pub mat_f: [f32; 9],
    pub inv_mat_f: [f32; 9],
    pub vec_f: [f32; 3],
    pub mat_d: [f64; 9],
    pub inv_mat_d: [f64; 9],
    pub vec_d: [f64; 3],
}

impl Map {
    fn read(b: &[u8], at: usize) -> Map {
        Map {
            mat_f: arr(rd_f32, b, at),
            inv_mat_f: arr(rd_f32, b, at + 36),
            vec_f: arr(rd_f32, b, at + 72),
            mat_d: arr(rd_f64, b, at + 88),
            inv_mat_d: arr(rd_f64, b, at + 160),
            vec_d: arr(rd_f64, b, at + 232),
        }
    }
}

/// The node that holds the values of an 8³ block: a constant tile value or a leaf offset.
enum Node {
    Const(f32),
    Leaf(usize),
}

/// One NanoVDB Float grid: its uncompressed buffer (uploadable as-is) plus parsed header fields.
#[derive(Clone, Debug)]
pub struct FloatGrid {
    source: String,
    buffer: Vec<u8>,
    name: String,
    grid_class: u32,
    map: Map,
    world_bbox: (DVec3, DVec3),
    index_bbox: (IVec3, IVec3),
    background: f32,
    /// Root tiles: (key, absolute offset of the upper node or `None` for a tile, tile value).
    tiles: Vec<(u64, Option<usize>, f32)>,
}

/// Nodes of one tree level: absolute start offset, count and stride.
struct Level {
    start: usize,
    count: usize,
    size: usize,
}

impl Level {
    fn index_of(&self, abs: usize) -> Option<usize> {
        let rel = abs.checked_sub(self.start)?;
        (rel % self.size == 0 && rel / self.size < self.count).then_some(rel / self.size)
    }
}

impl FloatGrid {
    /// Parses and validates an uncompressed grid buffer. `source` names the origin (normally the
    /// file path) in error messages.
    pub fn from_buffer(buffer: Vec<u8>, source: &str) -> Result<FloatGrid> {
        let b = &buffer[..];
        let min = GRID_DATA_SIZE + 64 + ROOT_SIZE;
        if b.len() < min {
            bail!(
                "{source}: truncated: grid buffer has {} bytes, a grid needs at least {min}",
                b.len()
            );
        }
        let name = c_str(&b[40..296]);
        let u32_ = |o: usize| rd_u32(b, o).unwrap_or(0);
        let u64_ = |o: usize| rd_u64(b, o).unwrap_or(0);
        let magic = u64_(0);
        if magic != FILE_MAGIC && magic != GRID_MAGIC_NEW {
            let m = magic.to_le_bytes().escape_ascii().to_string();
            bail!("{source}: grid \"{name}\": bad grid magic \"{m}\" (expected \"NanoVDB0\" or \"NanoVDB1\")");
        }
        let v = u32_(16);
        if v >> 21 != 32 {
            bail!(
                "{source}: grid \"{name}\": NanoVDB version {}.{}.{} is not supported (expected major version 32)",
                v >> 21, (v >> 10) & 0x7ff, v & 0x3ff
            );
        }
        check_kind(source, &name, u32_(636), u32_(632))?;
        if u64_(32) != b.len() as u64 {
            bail!(
                "{source}: grid \"{name}\": grid size field {} differs from the buffer length {}",
                u64_(32),
                b.len()
            );
        }
        let corrupt = |what: String| anyhow!("{source}: grid \"{name}\": corrupt tree: {what}");
        let level = |l: usize, size: usize| -> Result<Level> {
            let count = u32_(TREE + 32 + 4 * l) as usize;
            let start = offset(TREE, u64_(TREE + 8 * l) as i64).unwrap_or(usize::MAX);
            let end = count.checked_mul(size).and_then(|n| n.checked_add(start));
            if count > 0 && (start % 32 != 0 || end.is_none_or(|e| e > b.len())) {
                return Err(corrupt(format!(
                    "{count} nodes of {size} bytes at byte {start} do not fit the {}-byte buffer aligned to 32",
                    b.len()
                )));
            }
            Ok(Level { start, count, size })
        };
        let levels = [level(0, LEAF_SIZE)?, level(1, LOWER.2)?, level(2, UPPER.2)?];
        let root = offset(TREE, u64_(TREE + 24) as i64).unwrap_or(usize::MAX);
        let table_size = rd_u32(b, root.saturating_add(24)).unwrap_or(0) as usize;
        if root % 32 != 0 || root.saturating_add(ROOT_SIZE + TILE_SIZE * table_size) > b.len() {
            return Err(corrupt(format!(
                "root with {table_size} tiles at byte {root} lies outside the buffer"
            )));
        }
        let mut seen: Vec<Vec<bool>> = levels.iter().map(|l| vec![false; l.count]).collect();
        let mut claim = |l: usize, parent: &str, abs: Option<usize>| -> Result<()> {
            let (names, abs) = (["leaf", "lower", "upper"], abs.unwrap_or(usize::MAX));
            let k = levels[l].index_of(abs).ok_or_else(|| {
                let lv = &levels[l];
                corrupt(format!(
                    "{parent} points to byte {abs}, which is not a {} node (expected one of {} nodes of {} bytes from byte {})",
                    names[l], lv.count, lv.size, lv.start
                ))
            })?;
            if std::mem::replace(&mut seen[l][k], true) {
                return Err(corrupt(format!(
                    "{parent} points to {} node {k}, which is already used",
                    names[l]
                )));
            }
            Ok(())
        };
        let mut tiles = Vec::with_capacity(table_size);
        for t in 0..table_size {
            let tile = root + ROOT_SIZE + TILE_SIZE * t;
            let child = rd_i64(b, tile + 8).unwrap_or(0);
            let abs = (child != 0).then(|| offset(root, child).unwrap_or(usize::MAX));
            if abs.is_some() {
                claim(2, &format!("root tile {t}"), abs)?;
            }
            tiles.push((u64_(tile), abs, rd_f32(b, tile + 20).unwrap_or(0.0)));
        }
        for (l, (cmask, table, _, log2n)) in [(2, UPPER), (1, LOWER)] {
            for k in 0..levels[l].count {
                let node = levels[l].start + k * levels[l].size;
                for w in 0..(1usize << log2n) / 64 {
                    let mut word = u64_(node + cmask + 8 * w);
                    while word != 0 {
                        let n = 64 * w + word.trailing_zeros() as usize;
                        word &= word - 1;
                        let abs = offset(node, rd_i64(b, node + table + 8 * n).unwrap_or(0));
                        let parent = ["", "lower", "upper"][l];
                        claim(l - 1, &format!("{parent} node {k} slot {n}"), abs)?;
                    }
                }
            }
        }
        Ok(FloatGrid {
            source: source.to_string(),
            name,
            grid_class: u32_(632),
            map: Map::read(b, 296),
            world_bbox: (arr(rd_f64, b, 560).into(), arr(rd_f64, b, 584).into()),
            index_bbox: (
                arr(rd_i32, b, root).into(),
                arr(rd_i32, b, root + 12).into(),
            ),
            background: rd_f32(b, root + 28).unwrap_or(0.0),
            tiles,
            buffer,
        })
    }

    /// The uncompressed grid buffer, byte for byte as NanoVDB stores it.
    pub fn buffer(&self) -> &[u8] {
        &self.buffer
    }
    /// The grid name.
    pub fn name(&self) -> &str {
        &self.name
    }
    /// The grid class (0 Unknown, 2 FogVolume).
    pub fn grid_class(&self) -> u32 {
        self.grid_class
    }
    /// The index↔world map.
    pub fn map(&self) -> &Map {
        &self.map
    }
    /// The value returned outside all nodes and tiles.
    pub fn background(&self) -> f32 {
        self.background
    }
    /// Inclusive index bbox of the active values (the root's bbox).
    pub fn index_bbox(&self) -> (IVec3, IVec3) {
        self.index_bbox
    }
    /// World bbox stored in the grid: the map applied to index `min ..= max + 1`.
    pub fn world_bbox(&self) -> (DVec3, DVec3) {
        self.world_bbox
    }

    /// World → index in f32, `inv_mat_f · (p − vec_f)` with the fused multiply-adds NanoVDB uses
    /// (row r: `fma(x, m[3r], fma(y, m[3r+1], z·m[3r+2]))`).
    pub fn world_to_index(&self, p: Vec3) -> Vec3 {
        let (m, v) = (&self.map.inv_mat_f, self.map.vec_f);
        let (x, y, z) = (p.x - v[0], p.y - v[1], p.z - v[2]);
        let row = |r: usize| x.mul_add(m[3 * r], y.mul_add(m[3 * r + 1], z * m[3 * r + 2]));
        Vec3::new(row(0), row(1), row(2))
    }

    /// Index → world in f64, `mat_d · p + vec_d`.
    pub fn index_to_world(&self, p: DVec3) -> DVec3 {
        let (m, v) = (&self.map.mat_d, self.map.vec_d);
        let row = |r: usize| m[3 * r] * p.x + m[3 * r + 1] * p.y + m[3 * r + 2] * p.z + v[r];
        DVec3::new(row(0), row(1), row(2))
    }

    /// Table entry `n` of the internal node at `node`: `Ok(child offset)` or `Err(tile value)`.
    fn entry(
        &self,
        node: usize,
        (cmask, table, _, _): Layout,
        n: usize,
    ) -> Option<Result<usize, f32>> {
        let word = rd_u64(&self.buffer, node + cmask + 8 * (n >> 6))?;
        let e = node + table + 8 * n;
        if (word >> (n & 63)) & 1 == 0 {
            return Some(Err(rd_f32(&self.buffer, e)?));
        }
        offset(node, rd_i64(&self.buffer, e)?).map(Ok)
    }

    /// Walks root → upper → lower to the node covering `ijk`; `None` means background.
    fn descend(&self, ijk: IVec3) -> Option<Node> {
        let key = root_key(ijk);
        let &(_, child, value) = self.tiles.iter().find(|t| t.0 == key)?;
        let Some(upper) = child else {
            return Some(Node::Const(value));
        };
        let (i, j, k) = (ijk.x, ijk.y, ijk.z);
        let n = (((i & 4095) >> 7) << 10) | (((j & 4095) >> 7) << 5) | ((k & 4095) >> 7);
        let lower = match self.entry(upper, UPPER, n as usize)? {
            Ok(lower) => lower,
            Err(v) => return Some(Node::Const(v)),
        };
        let n = (((i & 127) >> 3) << 8) | (((j & 127) >> 3) << 4) | ((k & 127) >> 3);
        Some(match self.entry(lower, LOWER, n as usize)? {
            Ok(leaf) => Node::Leaf(leaf),
            Err(v) => Node::Const(v),
        })
    }

    /// The value at integer index `ijk` (active or not), or the background outside the tree.
    pub fn value(&self, ijk: IVec3) -> f32 {
        match self.descend(ijk) {
            Some(Node::Const(v)) => v,
            Some(Node::Leaf(leaf)) => {
                let n = ((ijk.x & 7) << 6) | ((ijk.y & 7) << 3) | (ijk.z & 7);
                rd_f32(&self.buffer, leaf + LEAF_VALUES + 4 * n as usize).unwrap_or(self.background)
            }
            None => self.background,
        }
    }

    /// Trilinear sample at index-space point `p_index`, exactly as pbrt-v4 samples a medium.
    pub fn sample(&self, p_index: Vec3) -> f32 {
        trilinear(p_index, |ijk| self.value(ijk))
    }

    /// Copies the grid into 8³ bricks covering the index bbox plus a one-voxel margin.
    /// Constant tiles and constant leaves share one brick per distinct value; zero regions get
    /// no brick. Errors if the background is not 0 or the brick table would exceed 2^28 entries.
    pub fn bricks(&self) -> Result<Bricks> {
        let (src, name) = (&self.source, &self.name);
        if self.background != 0.0 {
            bail!(
                "{src}: grid \"{name}\" has background {}: nanovdb media need a zero background",
                self.background
            );
        }
        let mut out = Bricks::default();
        let (lo, hi) = self.index_bbox;
        if lo.cmpgt(hi).any() {
            return Ok(out);
        }
        let origin = (lo.as_i64vec3() - 1) & !7;
        let dims = (((hi.as_i64vec3() + 1) & !7) - origin) / 8 + 1;
        let count = dims
            .x
            .checked_mul(dims.y)
            .and_then(|n| n.checked_mul(dims.z));
        let fits = |v: I64Vec3| {
            v.cmpge(I64Vec3::splat(i32::MIN.into())).all()
                && v.cmple(I64Vec3::splat(i32::MAX.into())).all()
        };
        if count.is_none_or(|n| n > MAX_TABLE) || !fits(origin) || !fits(origin + dims * 8 - 1) {
            bail!(
                "{src}: grid \"{name}\": index bbox {lo}..{hi} needs {dims} bricks, more than 2^28"
            );
        }
        (out.origin, out.dims) = (origin.as_ivec3(), dims.as_uvec3());
        out.table.reserve(count.unwrap_or(0) as usize);
        let mut consts = HashMap::new();
        for z in 0..out.dims.z as i32 {
            for y in 0..out.dims.y as i32 {
                for x in 0..out.dims.x as i32 {
                    let entry = match self.descend(out.origin + 8 * IVec3::new(x, y, z)) {
                        None => 0,
                        Some(Node::Const(v)) => out.constant(v, &mut consts),
                        Some(Node::Leaf(leaf)) => {
                            let mut vals = [0.0f32; 512];
                            for (n, v) in vals.iter_mut().enumerate() {
                                let slot = ((n & 7) << 6) | (((n >> 3) & 7) << 3) | (n >> 6);
                                *v = rd_f32(&self.buffer, leaf + LEAF_VALUES + 4 * slot)
                                    .unwrap_or(0.0);
                            }
                            if vals.iter().all(|&v| v == vals[0]) {
                                out.constant(vals[0], &mut consts)
                            } else {
                                out.push(&vals)
                            }
                        }
                    };
                    out.table.push(entry);
                }
            }
        }
        Ok(out)
    }
}

/// Rejects grids that a pbrt-v4 nanovdb medium cannot use.
fn check_kind(src: &str, name: &str, grid_type: u32, class: u32) -> Result<()> {
    if grid_type != 1 {
        bail!(
            "{src}: grid \"{name}\" is a {} grid; a nanovdb medium needs Float grids",
            label(GRID_TYPES, grid_type)
        );
    }
    if class != 0 && class != 2 {
        bail!(
            "{src}: grid \"{name}\" has class {}; a nanovdb medium needs FogVolume (or Unknown) grids",
            label(GRID_CLASSES, class)
        );
    }
    Ok(())
}

/// Sparse 8³-brick copy of a grid for GPU lookups.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Bricks {
    /// Index-space minimum corner of brick (0, 0, 0), a multiple of 8.
    pub origin: IVec3,
    /// Number of bricks per axis.
    pub dims: UVec3,
    /// `dims.x * dims.y * dims.z` entries, x fastest: 0 = all zero, k > 0 = brick k − 1.
    pub table: Vec<u32>,
    /// 512 values per brick, voxel `(i, j, k)` at `(i & 7) + 8 (j & 7) + 64 (k & 7)`.
    pub values: Vec<f32>,
    /// Largest value of each brick.
    pub brick_max: Vec<f32>,
}

impl Bricks {
    fn push(&mut self, vals: &[f32]) -> u32 {
        self.values.extend_from_slice(vals);
        self.brick_max
            .push(vals.iter().copied().fold(f32::NEG_INFINITY, f32::max));
        self.brick_max.len() as u32
    }

    fn constant(&mut self, v: f32, consts: &mut HashMap<u32, u32>) -> u32 {
        if v == 0.0 {
            return 0;
        }
        *consts
            .entry(v.to_bits())
            .or_insert_with(|| self.push(&[v; 512]))
    }

    /// Table entry of the brick at brick coordinates `b` (assumed inside `dims`).
    fn entry(&self, b: I64Vec3) -> u32 {
        let d = self.dims.as_i64vec3();
        self.table
            .get((b.x + d.x * (b.y + d.y * b.z)) as usize)
            .copied()
            .unwrap_or(0)
    }

    fn voxel(&self, t: u32, r: I64Vec3) -> f32 {
        let i = (t as usize - 1) * 512 + ((r.x & 7) + 8 * (r.y & 7) + 64 * (r.z & 7)) as usize;
        self.values.get(i).copied().unwrap_or(0.0)
    }

    /// The value at integer index `ijk`; 0 outside the covered bricks.
    pub fn value(&self, ijk: IVec3) -> f32 {
        let r = ijk.as_i64vec3() - self.origin.as_i64vec3();
        if r.cmplt(I64Vec3::ZERO).any() || r.cmpge(self.dims.as_i64vec3() * 8).any() {
            return 0.0;
        }
        match self.entry(r / 8) {
            0 => 0.0,
            t => self.voxel(t, r),
        }
    }

    /// Trilinear sample at index-space point `p_index`, identical to [`FloatGrid::sample`].
    pub fn sample(&self, p_index: Vec3) -> f32 {
        trilinear(p_index, |ijk| self.value(ijk))
    }

    /// Largest value over the inclusive voxel box `lo ..= hi`, at least 0. Whole bricks use
    /// `brick_max`; partially covered bricks are scanned.
    pub fn max_in(&self, lo: IVec3, hi: IVec3) -> f32 {
        let o = self.origin.as_i64vec3();
        let lo = (lo.as_i64vec3() - o).max(I64Vec3::ZERO);
        let hi = (hi.as_i64vec3() - o).min(self.dims.as_i64vec3() * 8 - 1);
        let mut m = 0.0f32;
        if lo.cmpgt(hi).any() {
            return m;
        }
        for bz in lo.z / 8..=hi.z / 8 {
            for by in lo.y / 8..=hi.y / 8 {
                for bx in lo.x / 8..=hi.x / 8 {
                    let b = I64Vec3::new(bx, by, bz) * 8;
                    let t = self.entry(b / 8);
                    let (a, c) = (b.max(lo), (b + 7).min(hi));
                    if t == 0 {
                        continue;
                    } else if a == b && c == b + 7 {
                        m = m.max(self.brick_max.get(t as usize - 1).copied().unwrap_or(0.0));
                        continue;
                    }
                    for z in a.z..=c.z {
                        for y in a.y..=c.y {
                            for x in a.x..=c.x {
                                m = m.max(self.voxel(t, I64Vec3::new(x, y, z)));
                            }
                        }
                    }
                }
            }
        }
        m
    }

    /// Bytes of the table, values and brick maxima.
    pub fn bytes(&self) -> u64 {
        4 * (self.table.len() + self.values.len() + self.brick_max.len()) as u64
    }
}

/// One grid record of a file: metadata and where its payload lies.
struct Entry {
    name: String,
    name_key: u64,
    grid_size: u64,
    grid_type: u32,
    grid_class: u32,
    codec: u16,
    payload: usize,
    file_size: usize,
}

/// Parses all segments of a file into grid records, checking that every payload is present.
fn entries(data: &[u8], src: &str) -> Result<Vec<Entry>> {
    let truncated = |what: String| {
        anyhow!(
            "{src}: truncated: {what} (the file has {} bytes)",
            data.len()
        )
    };
    let mut out: Vec<Entry> = Vec::new();
    let mut pos = 0;
    while pos < data.len() || pos == 0 {
        let Some(magic) = rd_u64(data, pos) else {
            bail!(
                "{src}: not a NanoVDB file (only {} bytes at byte {pos})",
                data.len() - pos
            );
        };
        if magic != FILE_MAGIC && magic != FILE_MAGIC_NEW {
            let m = magic.to_le_bytes().escape_ascii().to_string();
            let hint = match magic {
                GRID_MAGIC_NEW => {
                    "; this is a raw grid buffer without file header, which pbrt-v4 cannot read"
                }
                _ if [FILE_MAGIC, FILE_MAGIC_NEW].contains(&magic.swap_bytes()) => {
                    "; reversed endianness"
                }
                _ => "",
            };
            bail!("{src}: not a NanoVDB file (magic \"{m}\" at byte {pos}, expected \"NanoVDB0\" or \"NanoVDB2\"{hint})");
        }
        let (Some(v), Some(count), Some(codec)) = (
            rd_u32(data, pos + 8),
            rd_u16(data, pos + 12),
            rd_u16(data, pos + 14),
        ) else {
            return Err(truncated(format!(
                "segment header at byte {pos} needs 16 bytes"
            )));
        };
        if v >> 21 != 32 {
            bail!(
                "{src}: NanoVDB version {}.{}.{} is not supported (expected major version 32)",
                v >> 21,
                (v >> 10) & 0x7ff,
                v & 0x3ff
            );
        }
        if codec > 2 {
            bail!("{src}: unknown codec {codec} at byte {pos} (expected 0 NONE, 1 ZIP or 2 BLOSC)");
        }
        pos += 16;
        let first = out.len();
        for g in 0..count {
            let Some(m) = data.get(pos..pos + META_SIZE) else {
                return Err(truncated(format!(
                    "metadata record {g} at byte {pos} needs {META_SIZE} bytes"
                )));
            };
            let u32_ = |o| rd_u32(m, o).unwrap_or(0);
            let name_size = u32_(136) as usize;
            let Some(name) = data.get(pos + META_SIZE..).and_then(|r| r.get(..name_size)) else {
                return Err(truncated(format!(
                    "name of grid {g} at byte {pos} needs {name_size} bytes"
                )));
            };
            let file_size = rd_u64(m, 8).unwrap_or(0);
            out.push(Entry {
                name: c_str(name),
                name_key: rd_u64(m, 16).unwrap_or(0),
                grid_size: rd_u64(m, 0).unwrap_or(0),
                grid_type: u32_(32),
                grid_class: u32_(36),
                codec,
                payload: 0,
                file_size: usize::try_from(file_size).unwrap_or(usize::MAX),
            });
            pos += META_SIZE + name_size;
        }
        for e in &mut out[first..] {
            e.payload = pos;
            pos = pos
                .checked_add(e.file_size)
                .filter(|&end| end <= data.len())
                .ok_or_else(|| {
                    truncated(format!(
                        "grid \"{}\" needs {} bytes at byte {pos}",
                        e.name, e.file_size
                    ))
                })?;
        }
    }
    Ok(out)
}

/// Decodes the payload of one grid record into the uncompressed grid buffer.
fn decode(data: &[u8], e: &Entry, src: &str) -> Result<Vec<u8>> {
    let (name, size) = (&e.name, e.grid_size);
    let payload = &data[e.payload..e.payload + e.file_size];
    let short = || {
        anyhow!(
            "{src}: truncated: grid \"{name}\": payload of {} bytes is too short",
            payload.len()
        )
    };
    let out = match e.codec {
        0 => payload
            .get(..usize::try_from(size)?)
            .ok_or_else(short)?
            .to_vec(),
        1 => {
            let n = usize::try_from(rd_u64(payload, 0).ok_or_else(short)?)?;
            let z = payload
                .get(8..)
                .and_then(|p| p.get(..n))
                .ok_or_else(short)?;
            let mut out = Vec::with_capacity(size.min(1 << 26) as usize);
            flate2::read::ZlibDecoder::new(z)
                .take(size.saturating_add(1))
                .read_to_end(&mut out)
                .map_err(|err| anyhow!("{src}: grid \"{name}\": corrupt ZIP payload: {err}"))?;
            out
        }
        c => bail!(
            "{src}: codec {} is not supported (pbrt-v4 reads NONE and ZIP)",
            label(CODECS, c.into())
        ),
    };
    if out.len() as u64 != size {
        bail!("{src}: grid \"{name}\": decompressed size {} differs from the grid size {size} in the metadata", out.len());
    }
    Ok(out)
}

fn read_file(path: &Path) -> Result<Vec<u8>> {
    std::fs::read(path).with_context(|| format!("{}: cannot read NanoVDB file", path.display()))
}

/// Picks the first grid named `name` from the bytes of a `.nvdb` file and loads it.
fn float_grid_from_bytes(data: &[u8], src: &str, name: &str) -> Result<Option<FloatGrid>> {
    let list = entries(data, src)?;
    let Some(e) = list.iter().find(|e| e.name == name) else {
        return Ok(None);
    };
    if e.name_key != 0 && e.name_key != name_hash(name) {
        bail!(
            "{src}: grid \"{name}\": name hash {:#x} in the metadata does not match the name (expected {:#x} or 0)",
            e.name_key, name_hash(name)
        );
    }
    check_kind(src, name, e.grid_type, e.grid_class)?;
    let mut grid = FloatGrid::from_buffer(decode(data, e, src)?, src)?;
    grid.name = e.name.clone();
    Ok(Some(grid))
}

/// Reads the first grid named `name` from a `.nvdb` file. `Ok(None)` if no grid has that name;
/// an error if the file is malformed or the grid is not a Float FogVolume/Unknown grid.
pub fn read_float_grid(path: &Path, name: &str) -> Result<Option<FloatGrid>> {
    float_grid_from_bytes(&read_file(path)?, &path.display().to_string(), name)
}

/// Names of all grids in a `.nvdb` file, in file order.
pub fn grid_names(path: &Path) -> Result<Vec<String>> {
    let list = entries(&read_file(path)?, &path.display().to_string())?;
    Ok(list.into_iter().map(|e| e.name).collect())
}

/// A writer of NanoVDB 32.3.3 Float FogVolume grids and files, for the tests (lightpath's
/// own and its integration tests make their .nvdb files with it; pbrt-v4 reads them).
pub mod write {
    use super::*;
    use flate2::{write::ZlibEncoder, Compression};
    use std::collections::BTreeMap;
    use std::io::Write;

    const VERSION: u32 = 32 << 21 | 3 << 10 | 3;

    /// A grid to write: `f` inside the inclusive box `lo ..= hi`, zero outside; map `mat · i + vec`.
    pub struct GridSource<'a> {
        pub name: &'a str,
        pub lo: IVec3,
        pub hi: IVec3,
        pub f: &'a dyn Fn(IVec3) -> f32,
        pub mat: [f64; 9],
        pub vec: [f64; 3],
    }

    impl GridSource<'_> {
        /// The value at `p`: `f` inside the box, 0 outside.
        pub fn at(&self, p: IVec3) -> f32 {
            let inside = p.cmpge(self.lo).all() && p.cmple(self.hi).all();
            inside.then(|| (self.f)(p)).unwrap_or(0.0)
        }
        /// Index space to world space.
        pub fn apply(&self, p: DVec3) -> DVec3 {
            let (m, v) = (&self.mat, &self.vec);
            let r = |r: usize| m[3 * r] * p.x + m[3 * r + 1] * p.y + m[3 * r + 2] * p.z + v[r];
            DVec3::new(r(0), r(1), r(2))
        }
    }

    /// Little-endian encoding for the test writer.
    pub(super) trait Le {
        fn enc(&self) -> Vec<u8>;
    }
    macro_rules! le {
        ($($t:ty),*) => {$(
            impl Le for $t {
                fn enc(&self) -> Vec<u8> {
                    self.to_le_bytes().into()
                }
            }
        )*};
    }
    le!(u8, u16, u32, i32, u64, i64, f32, f64);
    impl<T: Le> Le for [T] {
        fn enc(&self) -> Vec<u8> {
            self.iter().flat_map(Le::enc).collect()
        }
    }
    impl<T: Le, const N: usize> Le for [T; N] {
        fn enc(&self) -> Vec<u8> {
            self[..].enc()
        }
    }

    pub(super) fn put(b: &mut [u8], off: usize, v: &(impl Le + ?Sized)) {
        let v = v.enc();
        b[off..off + v.len()].copy_from_slice(&v);
    }

    fn set_bit(b: &mut [u8], off: usize, n: usize) {
        b[off + n / 8] |= 1 << (n % 8);
    }

    fn inverse(m: &[f64; 9]) -> [f64; 9] {
        let c = |r: usize, k: usize| {
            let (r0, r1, c0, c1) = ((r + 1) % 3, (r + 2) % 3, (k + 1) % 3, (k + 2) % 3);
            m[3 * r0 + c0] * m[3 * r1 + c1] - m[3 * r0 + c1] * m[3 * r1 + c0]
        };
        let det = m[0] * c(0, 0) + m[1] * c(0, 1) + m[2] * c(0, 2);
        std::array::from_fn(|i| c(i % 3, i / 3) / det)
    }

    enum E {
        Tile(f32),
        Leaf(usize),
    }

    /// Voxel `n` of an 8³ block in NanoVDB leaf order (x slowest, z fastest).
    fn local(n: usize) -> IVec3 {
        IVec3::new((n >> 6) as i32, (n >> 3) as i32 & 7, n as i32 & 7)
    }

    /// Builds a NanoVDB 32.3.3 Float FogVolume grid buffer: one inactive zero root tile plus one
    /// root tile per upper node, constant 8³ blocks as lower-node tiles, all-zero blocks left
    /// out, everything else as leaves. Internal node bboxes are their full extent.
    pub fn grid_buffer(s: &GridSource) -> Vec<u8> {
        let mut leaves: Vec<(IVec3, [f32; 512])> = vec![];
        let mut lowers: BTreeMap<[i32; 3], BTreeMap<usize, E>> = BTreeMap::new();
        let (mut bmin, mut bmax, mut voxels) = (IVec3::MAX, IVec3::MIN, 0u64);
        let (blo, bhi) = (s.lo & !7, s.hi & !7);
        for oz in (blo.z..=bhi.z).step_by(8) {
            for oy in (blo.y..=bhi.y).step_by(8) {
                for ox in (blo.x..=bhi.x).step_by(8) {
                    let o = IVec3::new(ox, oy, oz);
                    let v: [f32; 512] = std::array::from_fn(|n| s.at(o + local(n)));
                    let e = if v.iter().all(|&a| a == v[0]) {
                        if v[0] == 0.0 {
                            continue;
                        }
                        (bmin, bmax, voxels) = (bmin.min(o), bmax.max(o + 7), voxels + 512);
                        E::Tile(v[0])
                    } else {
                        for n in (0..512).filter(|&n| v[n] != 0.0) {
                            let p = o + local(n);
                            (bmin, bmax, voxels) = (bmin.min(p), bmax.max(p), voxels + 1);
                        }
                        leaves.push((o, v));
                        E::Leaf(leaves.len() - 1)
                    };
                    let n = ((ox & 127) >> 3) << 8 | ((oy & 127) >> 3) << 4 | (oz & 127) >> 3;
                    let lower = lowers.entry((o & !127).to_array()).or_default();
                    lower.insert(n as usize, e);
                }
            }
        }
        let mut uppers: BTreeMap<[i32; 3], Vec<usize>> = BTreeMap::new();
        for (i, k) in lowers.keys().enumerate() {
            let key = (IVec3::from(*k) & !4095).to_array();
            uppers.entry(key).or_default().push(i);
        }
        let root = 736;
        let upper0 = root + 64 + 32 * (uppers.len() + 1);
        let lower0 = upper0 + uppers.len() * UPPER.2;
        let leaf0 = lower0 + lowers.len() * LOWER.2;
        let size = leaf0 + leaves.len() * LEAF_SIZE;
        let mut b = vec![0u8; size];
        put(&mut b, 0, b"NanoVDB0");
        put(&mut b, 16, &[VERSION, 2 | 32, 0, 1]);
        put(&mut b, 32, &(size as u64));
        put(&mut b, 40, s.name.as_bytes());
        let inv = inverse(&s.mat);
        put(
            &mut b,
            296,
            &[s.mat.map(|v| v as f32), inv.map(|v| v as f32)],
        );
        put(&mut b, 368, &s.vec.map(|v| v as f32));
        put(&mut b, 380, &1f32);
        put(&mut b, 384, &[s.mat, inv]);
        put(&mut b, 528, &[s.vec[0], s.vec[1], s.vec[2], 1.0]);
        let corner = |c: i32| {
            let pick = |bit: i32, lo: i32, hi: i32| if c >> bit & 1 == 0 { lo } else { hi + 1 };
            let x = pick(0, bmin.x, bmax.x);
            s.apply(IVec3::new(x, pick(1, bmin.y, bmax.y), pick(2, bmin.z, bmax.z)).as_dvec3())
        };
        let wmin = (0..8).map(corner).fold(DVec3::MAX, DVec3::min);
        let wmax = (0..8).map(corner).fold(DVec3::MIN, DVec3::max);
        put(&mut b, 560, &[wmin.to_array(), wmax.to_array()]);
        let m = &s.mat;
        let voxel_size = [0, 1, 2].map(|c| DVec3::new(m[c], m[3 + c], m[6 + c]).length());
        put(&mut b, 608, &voxel_size);
        put(&mut b, 632, &[2u32, 1]);
        let first_leaf = if leaves.is_empty() { 0 } else { leaf0 - 672 };
        let offsets = [first_leaf, lower0 - 672, upper0 - 672, 64];
        put(&mut b, 672, &offsets.map(|o| o as u64));
        put(
            &mut b,
            704,
            &[leaves.len(), lowers.len(), uppers.len()].map(|n| n as u32),
        );
        put(&mut b, 728, &voxels);
        put(&mut b, root, &[bmin.to_array(), bmax.to_array()]);
        put(&mut b, root + 24, &(uppers.len() as u32 + 1));
        let key = |o: IVec3| {
            let k = [o.z, o.y, o.x].map(|v| (v as u32 >> 12) as u64);
            k[0] | k[1] << 21 | k[2] << 42
        };
        // Tile 0: an inactive constant root tile far away, so the linear scan has to skip it.
        put(&mut b, root + 64, &key(IVec3::new(-8192, 8192, -4096)));
        for (u, (uorg, kids)) in uppers.iter().enumerate() {
            let (tile, node) = (root + 64 + 32 * (u + 1), upper0 + u * UPPER.2);
            put(&mut b, tile, &key(IVec3::from(*uorg)));
            put(&mut b, tile + 8, &((node - root) as i64));
            put(&mut b, node, &[*uorg, uorg.map(|v| v + 4095)]);
            for &l in kids {
                let o = IVec3::from(*lowers.keys().nth(l).unwrap()) & 4095;
                let n = ((o.x >> 7) << 10 | (o.y >> 7) << 5 | o.z >> 7) as usize;
                set_bit(&mut b, node + 4128, n);
                put(
                    &mut b,
                    node + 8256 + 8 * n,
                    &((lower0 + l * LOWER.2 - node) as i64),
                );
            }
        }
        for (l, (lorg, entries)) in lowers.iter().enumerate() {
            let node = lower0 + l * LOWER.2;
            put(&mut b, node, &[*lorg, lorg.map(|v| v + 127)]);
            for (&n, e) in entries {
                match *e {
                    E::Tile(v) => {
                        set_bit(&mut b, node + 32, n);
                        put(&mut b, node + 1088 + 8 * n, &v);
                    }
                    E::Leaf(i) => {
                        set_bit(&mut b, node + 544, n);
                        let off = (leaf0 + i * LEAF_SIZE - node) as i64;
                        put(&mut b, node + 1088 + 8 * n, &off);
                    }
                }
            }
        }
        for (i, (o, v)) in leaves.iter().enumerate() {
            let leaf = leaf0 + i * LEAF_SIZE;
            put(&mut b, leaf, &o.to_array());
            put(&mut b, leaf + 12, &[7u8, 7, 7]);
            (0..512)
                .filter(|&n| v[n] != 0.0)
                .for_each(|n| set_bit(&mut b, leaf + 16, n));
            put(&mut b, leaf + 96, v);
        }
        b
    }

    /// A .nvdb file's bytes: segments of (codec: 0 NONE, 1 ZIP; grid buffers of `grid_buffer`).
    pub fn file_image(segments: &[(u16, &[&[u8]])]) -> Vec<u8> {
        let mut out = vec![];
        for &(codec, grids) in segments {
            let mut head = vec![0u8; 16];
            put(&mut head, 0, b"NanoVDB0");
            put(&mut head, 8, &VERSION);
            put(&mut head, 12, &[grids.len() as u16, codec]);
            out.extend(head);
            let mut payloads = vec![];
            for g in grids {
                let p = if codec == 1 {
                    let mut z = ZlibEncoder::new(Vec::new(), Compression::fast());
                    z.write_all(g).unwrap();
                    let z = z.finish().unwrap();
                    [(z.len() as u64).enc(), z].concat()
                } else {
                    g.to_vec()
                };
                let name = c_str(&g[40..296]);
                let mut m = vec![0u8; META_SIZE];
                put(
                    &mut m,
                    0,
                    &[g.len() as u64, p.len() as u64, name_hash(&name)],
                );
                put(&mut m, 24, &g[728..736]);
                put(&mut m, 32, &g[636..640]);
                put(&mut m, 36, &g[632..636]);
                put(&mut m, 40, &g[560..608]);
                put(&mut m, 88, &g[736..760]);
                put(&mut m, 112, &g[608..632]);
                put(&mut m, 136, &(name.len() as u32 + 1));
                put(&mut m, 140, &g[704..716]);
                put(&mut m, 152, &1u32);
                put(&mut m, 156, &g[716..728]);
                put(&mut m, 168, &codec);
                put(&mut m, 172, &VERSION);
                out.extend(m);
                out.extend(name.as_bytes());
                out.push(0);
                payloads.push(p);
            }
            payloads.iter().for_each(|p| out.extend(p));
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::write::*;
    use super::*;

    /// Constant 8³ blocks (lower-node tiles), all-zero blocks (no leaf) and varying leaves.
    fn density(p: IVec3) -> f32 {
        let b = p >> 3i32;
        if (b.x + b.y + b.z).rem_euclid(5) == 0 {
            0.5
        } else if b.x == 1 && b.y.rem_euclid(2) == 0 {
            0.0
        } else {
            (p.x * 7 + p.y * 3 - p.z * 5).rem_euclid(11) as f32 * 0.1 + 0.05
        }
    }

    fn spec(name: &str) -> GridSource<'_> {
        let (lo, hi) = (IVec3::new(-21, -13, -30), IVec3::new(25, 18, 12));
        let (mat, vec) = (
            [0.5, 0.0, 0.0, 0.0, 0.25, 0.0, 0.0, 0.0, 2.0],
            [1.5, -2.0, 3.25],
        );
        GridSource {
            name,
            lo,
            hi,
            f: &density,
            mat,
            vec,
        }
    }

    /// A temporary file, removed on drop.
    struct Tmp(std::path::PathBuf);
    impl Drop for Tmp {
        fn drop(&mut self) {
            let _ = std::fs::remove_file(&self.0);
        }
    }

    fn tmp(file: &str, bytes: &[u8]) -> Tmp {
        let p = std::env::temp_dir().join(format!("nvdb-{}-{file}", std::process::id()));
        std::fs::write(&p, bytes).unwrap();
        Tmp(p)
    }

    fn load(file: &str, bytes: &[u8], name: &str) -> FloatGrid {
        read_float_grid(&tmp(file, bytes).0, name).unwrap().unwrap()
    }

    fn one_grid_file(s: &GridSource) -> Vec<u8> {
        file_image(&[(0, &[&grid_buffer(s)])])
    }

    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> u64 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            self.0
        }
        fn i(&mut self, lo: i32, hi: i32) -> i32 {
            lo + (self.next() % (hi - lo + 1) as u64) as i32
        }
        fn point(&mut self, lo: IVec3, hi: IVec3) -> Vec3 {
            let mut f = |lo: i32, hi: i32| {
                lo as f32 + (hi - lo) as f32 * (self.next() >> 40) as f32 / (1u64 << 24) as f32
            };
            Vec3::new(f(lo.x, hi.x), f(lo.y, hi.y), f(lo.z, hi.z))
        }
    }

    fn for_box(lo: IVec3, hi: IVec3, mut f: impl FnMut(IVec3)) {
        for z in lo.z..=hi.z {
            for y in lo.y..=hi.y {
                (lo.x..=hi.x).for_each(|x| f(IVec3::new(x, y, z)));
            }
        }
    }

    fn direct_trilinear(s: &GridSource, p: Vec3) -> f32 {
        let (i, t) = (p.floor().as_ivec3(), p - p.floor());
        let v = |x, y, z| s.at(i + IVec3::new(x, y, z));
        let l = |a: f32, b: f32, w: f32| a + w * (b - a);
        let x0 = l(
            l(v(0, 0, 0), v(0, 0, 1), t.z),
            l(v(0, 1, 0), v(0, 1, 1), t.z),
            t.y,
        );
        let x1 = l(
            l(v(1, 0, 0), v(1, 0, 1), t.z),
            l(v(1, 1, 0), v(1, 1, 1), t.z),
            t.y,
        );
        l(x0, x1, t.x)
    }

    #[test]
    fn name_hash_matches_nanovdb() {
        assert_eq!(name_hash("density"), 0x85a6c080218);
    }

    #[test]
    fn values_round_trip() {
        let s = spec("density");
        let g = load("rt.nvdb", &one_grid_file(&s), "density");
        for_box(s.lo - 3, s.hi + 3, |p| {
            assert_eq!(g.value(p), s.at(p), "at {p}")
        });
        for p in [
            IVec3::new(-8000, 8200, -4000),
            IVec3::new(5000, 0, 0),
            IVec3::MIN,
        ] {
            assert_eq!(g.value(p), 0.0);
        }
        let mut expect = (IVec3::MAX, IVec3::MIN);
        for_box(s.lo, s.hi, |p| {
            if s.at(p) != 0.0 {
                expect = (expect.0.min(p), expect.1.max(p));
            }
        });
        assert_eq!(g.index_bbox(), expect);
        assert_eq!(
            (g.name(), g.grid_class(), g.background()),
            ("density", 2, 0.0)
        );
        let w = g.world_bbox();
        assert_eq!(w.0, s.apply(expect.0.as_dvec3()));
        assert_eq!(w.1, s.apply((expect.1 + 1).as_dvec3()));
        // The source really exercises 8 upper nodes and constant tiles in lower nodes.
        let b = g.buffer();
        let lower = 672 + rd_u64(b, 680).unwrap() as usize;
        let masks = (0..rd_u32(b, 708).unwrap() as usize).map(|l| lower + l * LOWER.2 + 32);
        let tiles: u32 = masks
            .flat_map(|m| &b[m..m + 512])
            .map(|m| m.count_ones())
            .sum();
        assert!(rd_u32(b, 712).unwrap() == 8 && tiles > 10, "{tiles}");
    }

    #[test]
    fn sample_is_pbrt_trilinear() {
        let s = spec("density");
        let g = load("sample.nvdb", &one_grid_file(&s), "density");
        let mut rng = Rng(0x9e3779b97f4a7c15);
        for _ in 0..20000 {
            let p = rng.point(s.lo - 2, s.hi + 2);
            assert_eq!(g.sample(p), direct_trilinear(&s, p), "at {p}");
        }
        assert_eq!(
            g.sample(Vec3::new(3.0, -4.0, 5.0)),
            s.at(IVec3::new(3, -4, 5))
        );
    }

    #[test]
    fn world_to_index_inverts_map() {
        let (a, c) = (1.0f64, 0.3f64);
        let (sa, ca, sc, cc) = (a.sin(), a.cos(), c.sin(), c.cos());
        let rot = [ca, -sa, 0.0, sa * cc, ca * cc, -sc, sa * sc, ca * sc, cc];
        let scaled: [f64; 9] = std::array::from_fn(|i| rot[i] * [0.5, 0.25, 2.0][i % 3]);
        for mat in [spec("").mat, scaled] {
            let s = GridSource {
                mat,
                ..spec("density")
            };
            let g = load("map.nvdb", &one_grid_file(&s), "density");
            let mut rng = Rng(7);
            for _ in 0..1000 {
                let p = rng.point(s.lo - 4, s.hi + 4);
                let w = s.apply(p.as_dvec3());
                let err = (g.world_to_index(w.as_vec3()) - p).abs().max_element();
                assert!(err < 1e-4 * (1.0 + p.abs().max_element()), "{p}: {err}");
                assert!((g.index_to_world(p.as_dvec3()) - w).abs().max_element() < 1e-12);
            }
        }
    }

    #[test]
    fn bricks_match_tree() {
        let s = spec("density");
        let g = load("bricks.nvdb", &one_grid_file(&s), "density");
        let br = g.bricks().unwrap();
        let (lo, hi) = g.index_bbox();
        let end = br.origin + 8 * br.dims.as_ivec3();
        assert!(br.origin.cmple(lo - 1).all() && end.cmpgt(hi + 1).all());
        assert_eq!(br.origin & 7, IVec3::ZERO);
        assert_eq!(br.table.len() as u32, br.dims.x * br.dims.y * br.dims.z);
        // Every leaf of the test grid varies; all constant tiles share one 0.5 brick.
        assert_eq!(
            br.brick_max.len(),
            rd_u32(g.buffer(), 704).unwrap() as usize + 1
        );
        assert_eq!(br.values.len(), 512 * br.brick_max.len());
        let words = br.table.len() + br.values.len() + br.brick_max.len();
        assert_eq!(br.bytes(), 4 * words as u64);
        for_box(s.lo - 4, s.hi + 4, |p| {
            assert_eq!(br.value(p), g.value(p), "at {p}")
        });
        // The documented layout, independent of Bricks::value.
        for_box(lo, hi, |p| {
            let (b, r) = ((p - br.origin) / 8, (p - br.origin) % 8);
            let d = br.dims.as_ivec3();
            let t = br.table[(b.x + d.x * (b.y + d.y * b.z)) as usize] as usize;
            let v = if t == 0 {
                0.0
            } else {
                br.values[512 * (t - 1) + (r.x + 8 * r.y + 64 * r.z) as usize]
            };
            assert_eq!(v, s.at(p), "at {p}");
        });
        let mut rng = Rng(11);
        for _ in 0..20000 {
            let p = rng.point(s.lo - 3, s.hi + 3);
            assert_eq!(br.sample(p), g.sample(p), "at {p}");
        }
        for _ in 0..300 {
            let a = IVec3::new(rng.i(-40, 30), rng.i(-30, 25), rng.i(-45, 20));
            let b = a + IVec3::new(rng.i(-1, 20), rng.i(0, 20), rng.i(0, 20));
            let mut m = 0.0f32;
            for_box(a, b, |p| m = m.max(g.value(p)));
            assert_eq!(br.max_in(a, b), m, "box {a}..{b}");
        }
        assert_eq!(br.max_in(IVec3::MIN, IVec3::MAX), 1.05);
    }

    #[test]
    fn selection_segments_and_zip() {
        let temp = |p: IVec3| (p.x + p.y) as f32;
        let (lo, hi) = (IVec3::new(1, 2, 3), IVec3::splat(9));
        let t = GridSource {
            name: "temperature",
            lo,
            hi,
            f: &temp,
            ..spec("")
        };
        let (d, t) = (grid_buffer(&spec("density")), grid_buffer(&t));
        let one = file_image(&[(0, &[&d, &t])]);
        let two = file_image(&[(1, &[&t]), (0, &[&d, &t])]);
        for (file, bytes) in [("one.nvdb", &one), ("two.nvdb", &two)] {
            let p = tmp(file, bytes);
            assert_eq!(
                read_float_grid(&p.0, "density").unwrap().unwrap().buffer(),
                &d[..]
            );
            assert_eq!(
                read_float_grid(&p.0, "temperature")
                    .unwrap()
                    .unwrap()
                    .buffer(),
                &t[..]
            );
            assert!(read_float_grid(&p.0, "dens").unwrap().is_none());
        }
        let names = grid_names(&tmp("two.nvdb", &two).0).unwrap();
        assert_eq!(names, ["temperature", "density", "temperature"]);
        let g = load("two.nvdb", &two, "temperature");
        assert_eq!(
            (g.value(IVec3::new(4, 5, 6)), g.value(IVec3::new(4, 5, 10))),
            (9.0, 0.0)
        );
        let zip = load("zip.nvdb", &file_image(&[(1, &[&d])]), "density");
        assert_eq!(zip.buffer(), &d[..]);
        // The first grid of a name wins, as in pbrt-v4.
        let other = grid_buffer(&GridSource {
            f: &temp,
            ..spec("density")
        });
        let g = load("dup.nvdb", &file_image(&[(0, &[&other, &d])]), "density");
        assert_eq!(g.buffer(), &other[..]);
        // Newer writers store a zero name hash.
        let mut f = file_image(&[(0, &[&d])]);
        put(&mut f, 32, &0u64);
        load("nohash.nvdb", &f, "density");
    }

    fn expect_err(file: &str, bytes: &[u8], phrase: &str) {
        let e = read_float_grid(&tmp(file, bytes).0, "density").err();
        let msg = format!("{:#}", e.unwrap_or_else(|| panic!("{file}: no error")));
        assert!(msg.contains(file) && msg.contains(phrase), "{msg}");
    }

    #[test]
    fn errors() {
        let d = grid_buffer(&spec("density"));
        let file = file_image(&[(0, &[&d])]);
        let edit = |f: &[u8], off: usize, v: &dyn Fn(&mut Vec<u8>, usize)| {
            let mut f = f.to_vec();
            v(&mut f, off);
            f
        };
        let at = |f: &[u8], off: usize, v: &[u8]| edit(f, off, &|f, o| put(f, o, v));
        let grid = |off: usize, v: &[u8]| file_image(&[(0, &[&at(&d, off, v)])]);
        let v31 = (31u32 << 21 | 3 << 10 | 3).enc();
        expect_err(
            "magic.nvdb",
            &at(&file, 0, b"NotAVDB!"),
            "not a NanoVDB file",
        );
        expect_err(
            "swapped.nvdb",
            &at(&file, 0, b"0BDVonaN"),
            "reversed endianness",
        );
        expect_err("empty.nvdb", &[], "not a NanoVDB file");
        expect_err("v31.nvdb", &at(&file, 8, &v31), "31.3.3 is not supported");
        expect_err(
            "blosc.nvdb",
            &at(&file, 14, &2u16.enc()),
            "codec BLOSC is not supported",
        );
        expect_err(
            "codec9.nvdb",
            &at(&file, 14, &9u16.enc()),
            "unknown codec 9",
        );
        expect_err("double.nvdb", &grid(636, &2u32.enc()), "is a Double grid");
        expect_err("levelset.nvdb", &grid(632, &1u32.enc()), "class LevelSet");
        expect_err("gmagic.nvdb", &grid(0, b"NanoVDBX"), "bad grid magic");
        expect_err("gv31.nvdb", &grid(16, &v31), "expected major version 32");
        expect_err("trunc.nvdb", &file[..file.len() - 100], "truncated");
        expect_err("trunc2.nvdb", &file[..100], "truncated");
        expect_err("hash.nvdb", &at(&file, 32, &5u64.enc()), "name hash");
        let zip = file_image(&[(1, &[&d])]);
        let size = |n: u64| at(&zip, 16, &n.enc());
        expect_err("size.nvdb", &size(d.len() as u64 + 32), "decompressed size");
        expect_err(
            "size2.nvdb",
            &size(d.len() as u64 - 32),
            "decompressed size",
        );
        expect_err("zcorrupt.nvdb", &at(&zip, 220, &[0xff; 16]), "corrupt ZIP");
        let tile = 736 + 64 + 32 + 8;
        expect_err(
            "child.nvdb",
            &grid(tile, &(1i64 << 40).enc()),
            "corrupt tree",
        );
        expect_err("child2.nvdb", &grid(tile, &(-736i64).enc()), "corrupt tree");
        let lower = 672 + rd_u64(&d, 680).unwrap() as usize;
        let n = (0..4096)
            .find(|&n| d[lower + 544 + n / 8] >> (n % 8) & 1 == 1)
            .unwrap();
        let (e, off) = (
            lower + 1088 + 8 * n,
            rd_i64(&d, lower + 1088 + 8 * n).unwrap(),
        );
        expect_err("leafoff.nvdb", &grid(e, &(off + 7).enc()), "corrupt tree");
        expect_err("twice.nvdb", &grid(e, &(off + 2144).enc()), "already used");
        expect_err("count.nvdb", &grid(704, &u32::MAX.enc()), "corrupt tree");
        let bg = load("bg.nvdb", &grid(736 + 28, &1f32.enc()), "density");
        let msg = bg.bricks().unwrap_err().to_string();
        let phrase = "background 1: nanovdb media need a zero background";
        assert!(msg.contains("bg.nvdb") && msg.contains(phrase), "{msg}");
    }

    #[test]
    fn corrupt_bytes_never_panic() {
        let (lo, hi) = (IVec3::new(1, 2, 3), IVec3::new(20, 12, 17));
        let d = grid_buffer(&GridSource {
            lo,
            hi,
            ..spec("density")
        });
        for (codec, seed) in [(0u16, 1u64), (1, 2)] {
            let file = file_image(&[(codec, &[&d])]);
            let mut rng = Rng(seed);
            for round in 0..300 {
                let mut f = file.clone();
                for _ in 0..1 + rng.next() % 4 {
                    let limit = if round % 2 == 0 { 1600 } else { f.len() };
                    let at = rng.next() as usize % limit;
                    f[at] = rng.next() as u8;
                }
                let cut = if round % 7 == 0 {
                    rng.next() as usize % f.len()
                } else {
                    f.len()
                };
                match float_grid_from_bytes(&f[..cut], "fuzz.nvdb", "density") {
                    Ok(Some(g)) => {
                        for _ in 0..50 {
                            g.sample(rng.point(IVec3::splat(-30), IVec3::splat(40)));
                        }
                        if g.index_bbox() == (lo, hi) {
                            let _ = g.bricks().map(|b| b.max_in(IVec3::ZERO, IVec3::splat(30)));
                        }
                    }
                    Ok(None) => {}
                    Err(e) => assert!(e.to_string().starts_with("fuzz.nvdb: "), "{e}"),
                }
            }
        }
    }
}

//! The scene's large arrays on the device, in chunks read by address
//! (glsl/lib/scene_data.glsl): triangles, their attribute records, the BVH's nodes and
//! primitive references, texels and medium grids (abi.h `DATA_*`). Each kind is cut into
//! chunks of 2^shift records, each chunk a buffer of its own below the device's largest
//! allocation and buffer, so that no kind meets a binding's range (lavapipe: 128 MiB) or
//! one allocation's size (lavapipe: 2 GiB); the kernels find a record's chunk by its index
//! (`index >> shift`) in the table at `BINDING_SCENE_DATA`.
use super::buffer::Buffer;
use super::{Device, GpuResult};
use crate::abi::{DATA_IN_BINDING, DATA_KINDS};
use ash::vk;
use std::sync::Arc;

/// One kind's data as the host has it: its bytes (a slice, or made record by record as
/// they are uploaded), the size of one record (a record never straddles two chunks) and
/// the usage its buffers need beyond storage and addressing.
pub struct DataArray<'a> {
    pub name: &'static str,
    pub bytes: DataBytes<'a>,
    pub record: u64,
    pub usage: vk::BufferUsageFlags,
    /// The largest chunk for this kind, where it is not the scene's.
    pub chunk_bytes: Option<u64>,
    /// Whether its one chunk, where it fits a binding, is bound there too
    /// (`DATA_IN_BINDING`: the triangles, the BVH's nodes and references).
    pub bindable: bool,
}

/// A kind's bytes: a slice the host holds, or `len` bytes that `fill(at, out)` makes
/// from byte `at` on, whole records at a time, straight into the device's memory or the
/// upload's staging memory, in pieces in any order and on every core (the triangles,
/// their attributes and the texels: no host array of the whole kind, whose fresh pages
/// cost more than making the records; docs/performance.md).
pub enum DataBytes<'a> {
    Slice(&'a [u8]),
    Made { len: u64, fill: Fill<'a> },
}

/// What makes a kind's records: `fill(at, out)` writes the bytes from `at` on into `out`.
pub type Fill<'a> = Box<dyn Fn(u64, &mut [u8]) + Send + Sync + 'a>;

impl DataBytes<'_> {
    pub fn len(&self) -> u64 {
        match self {
            DataBytes::Slice(s) => s.len() as u64,
            DataBytes::Made { len, .. } => *len,
        }
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Writes the `out.len()` bytes (a whole number of records) from byte `at` on.
    fn write(&self, at: u64, out: &mut [u8]) {
        match self {
            DataBytes::Slice(s) => out.copy_from_slice(&s[at as usize..at as usize + out.len()]),
            DataBytes::Made { fill, .. } => fill(at, out),
        }
    }
}

impl<'a> DataArray<'a> {
    pub fn new(name: &'static str, bytes: &'a [u8], record: u64) -> DataArray<'a> {
        DataArray {
            name,
            bytes: DataBytes::Slice(bytes),
            record,
            usage: vk::BufferUsageFlags::empty(),
            chunk_bytes: None,
            bindable: false,
        }
    }

    /// `count` records of `record` bytes that `fill` makes (`DataBytes::Made`).
    pub fn made(
        name: &'static str,
        count: u64,
        record: u64,
        fill: impl Fn(u64, &mut [u8]) + Send + Sync + 'a,
    ) -> DataArray<'a> {
        DataArray {
            bytes: DataBytes::Made {
                len: count * record,
                fill: Box::new(fill),
            },
            ..DataArray::new(name, &[], record)
        }
    }

    /// An empty kind (a kernel that reads none of it).
    pub fn none(name: &'static str) -> DataArray<'static> {
        DataArray::new(name, &[], 4)
    }
}

/// The bytes of one piece of an in-place upload (rounded down to whole records).
const UPLOAD_PIECE: u64 = 16 << 20;

/// The largest power of two of records of `record` bytes that fits in `max_chunk_bytes`
/// (at least one record, at most 2^31): a chunk's size as its shift.
pub fn chunk_shift(record: u64, max_chunk_bytes: u64) -> u32 {
    let records = (max_chunk_bytes / record.max(1)).max(1);
    (63 - records.leading_zeros()).min(31)
}

/// The chunks of each kind and the table the kernels find them by.
pub struct SceneData {
    /// Per kind (abi.h `DATA_*`), its chunks in order.
    pub chunks: Vec<Vec<Buffer>>,
    /// Per kind, the shift of its chunks' record count.
    pub shifts: Vec<u32>,
    /// The table at `BINDING_SCENE_DATA`.
    pub table: Buffer,
    /// Per kind, its name.
    pub names: Vec<&'static str>,
}

impl SceneData {
    /// Uploads `arrays` (one per kind, in `DATA_*` order) in chunks of at most
    /// `max_chunk_bytes` each.
    pub fn new(
        device: &Arc<Device>,
        arrays: [DataArray; DATA_KINDS as usize],
        max_chunk_bytes: u64,
    ) -> GpuResult<SceneData> {
        let binding_range = device.info.max_storage_buffer_range;
        let mut chunks = Vec::new();
        let mut shifts = Vec::new();
        let mut lens = Vec::new();
        let names = arrays.iter().map(|a| a.name).collect();
        for a in &arrays {
            let limit = a.chunk_bytes.unwrap_or(max_chunk_bytes);
            // One chunk: shift 31 (every index in it; the kernels read no table), or
            // DATA_IN_BINDING where it is bound too.
            let bytes = a.bytes.len();
            let shift = if a.bindable && bytes <= limit && bytes <= binding_range {
                DATA_IN_BINDING
            } else if bytes <= limit {
                31
            } else {
                chunk_shift(a.record, limit)
            };
            let chunk_bytes = (a.record << shift).max(1);
            let usage = vk::BufferUsageFlags::STORAGE_BUFFER
                | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS
                | a.usage;
            let mut list = Vec::new();
            if a.bytes.is_empty() {
                list.push(Buffer::with_data(device, a.name, &[], usage)?);
            }
            let count = bytes.div_ceil(chunk_bytes);
            let chunk_lens: Vec<u64> = (0..count)
                .map(|k| chunk_bytes.min(bytes - k * chunk_bytes))
                .collect();
            for (k, &len) in chunk_lens.iter().enumerate() {
                let name = if count == 1 {
                    a.name.to_string()
                } else {
                    format!("{} (chunk {k} of {count})", a.name)
                };
                list.push(Buffer::device_local(device, &name, len.max(16), usage)?);
            }
            chunks.push(list);
            shifts.push(shift);
            lens.push(chunk_lens);
        }
        // Each kind's bytes into its chunks. Where the host writes the device's memory in
        // place (lavapipe, integrated GPUs), in pieces of about UPLOAD_PIECE bytes shared
        // out to every core (no command is submitted, so no queue is shared; each piece's
        // bytes depend on its place alone); else chunk by chunk through staging memory.
        let in_place = chunks
            .iter_mut()
            .flatten()
            .all(|b| b.host_writable().is_some());
        if in_place {
            let mut pieces = Vec::new();
            for ((a, list), lens) in arrays.iter().zip(chunks.iter_mut()).zip(&lens) {
                let piece = ((UPLOAD_PIECE / a.record).max(1) * a.record) as usize;
                let mut at = 0;
                // (An empty kind has one placeholder buffer and no chunk lengths.)
                for (buffer, &len) in list.iter_mut().zip(lens) {
                    let memory = buffer.host_writable().expect("host-writable chunks");
                    for out in memory[..len as usize].chunks_mut(piece) {
                        let n = out.len() as u64;
                        pieces.push((&a.bytes, at, out));
                        at += n;
                    }
                }
            }
            crate::accel::map_in_parallel(&mut pieces, crate::accel::threads(), |(b, at, out)| {
                b.write(*at, out)
            });
        } else {
            for ((a, list), lens) in arrays.iter().zip(chunks.iter_mut()).zip(&lens) {
                let mut at = 0;
                for (buffer, &len) in list.iter_mut().zip(lens) {
                    buffer.upload_with(len, a.record, &mut |offset, out| {
                        a.bytes.write(at + offset, out)
                    })?;
                    at += len;
                }
            }
        }
        let mut headers: Vec<[u32; 4]> = Vec::new();
        let mut addresses: Vec<[u32; 2]> = Vec::new();
        for (list, &shift) in chunks.iter().zip(&shifts) {
            let first = list[0].device_address();
            headers.push([
                first as u32,
                (first >> 32) as u32,
                shift,
                addresses.len() as u32,
            ]);
            addresses.extend(
                list.iter()
                    .map(|b| b.device_address())
                    .map(|a| [a as u32, (a >> 32) as u32]),
            );
        }
        let mut table: Vec<u8> = bytemuck::cast_slice(&headers).to_vec();
        table.extend_from_slice(bytemuck::cast_slice(&addresses));
        let table = Buffer::with_data(
            device,
            "scene data table",
            &table,
            vk::BufferUsageFlags::STORAGE_BUFFER,
        )?;
        Ok(SceneData {
            chunks,
            shifts,
            table,
            names,
        })
    }

    /// What the binding of `kind` holds: its one chunk where the kernels read it there
    /// (`DATA_IN_BINDING`), else the table (a placeholder they never read).
    pub fn bound(&self, kind: u32) -> &Buffer {
        if self.shifts[kind as usize] == DATA_IN_BINDING {
            &self.chunks[kind as usize][0]
        } else {
            &self.table
        }
    }

    /// Per kind: its name, bytes and chunks (for the trace).
    pub fn kinds(&self) -> Vec<(&'static str, u64, usize)> {
        self.names
            .iter()
            .zip(&self.chunks)
            .map(|(&n, c)| (n, c.iter().map(|b| b.size).sum(), c.len()))
            .collect()
    }

    /// The bytes of device memory the chunks and the table hold.
    pub fn device_bytes(&self) -> u64 {
        self.chunks.iter().flatten().map(|b| b.size).sum::<u64>() + self.table.size
    }
}

#[cfg(test)]
mod tests {
    use super::chunk_shift;

    #[test]
    fn a_chunk_is_the_largest_power_of_two_of_records_that_fits() {
        assert_eq!(chunk_shift(48, 2 << 30), 25); // 2^25 triangles: 1.5 GiB
        assert_eq!(chunk_shift(4, 2 << 30), 29);
        assert_eq!(chunk_shift(4, u64::MAX), 31);
        assert_eq!(chunk_shift(80, 100), 0); // one record at least
        assert_eq!(chunk_shift(16, 64), 2);
        assert_eq!(chunk_shift(16, 63), 1);
    }
}

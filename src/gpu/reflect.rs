//! What a kernel's SPIR-V says about its interface: the descriptor bindings it uses
//! (each kernel's descriptor-set layout is built from these, so the GLSL declaration is
//! the one source) and the member offsets of its structs (tests/abi.rs compares them with
//! the Rust mirrors in `crate::abi`).
use ash::vk;
use std::collections::{BTreeMap, HashMap, HashSet};

const OP_NAME: u32 = 5;
const OP_MEMBER_NAME: u32 = 6;
const OP_TYPE_STRUCT: u32 = 30;
const OP_TYPE_POINTER: u32 = 32;
const OP_TYPE_RUNTIME_ARRAY: u32 = 29;
const OP_TYPE_ARRAY: u32 = 28;
const OP_FUNCTION: u32 = 54;
const OP_VARIABLE: u32 = 59;
const OP_LOAD: u32 = 61;
const OP_STORE: u32 = 62;
const OP_ACCESS_CHAIN: u32 = 65;
const OP_IN_BOUNDS_ACCESS_CHAIN: u32 = 66;
const OP_PTR_ACCESS_CHAIN: u32 = 67;
const OP_ARRAY_LENGTH: u32 = 68;
const OP_DECORATE: u32 = 71;
const OP_MEMBER_DECORATE: u32 = 72;
const OP_TYPE_ACCELERATION_STRUCTURE: u32 = 5341;

const DECORATION_BLOCK: u32 = 2;
const DECORATION_BUFFER_BLOCK: u32 = 3;
const DECORATION_BINDING: u32 = 33;
const DECORATION_DESCRIPTOR_SET: u32 = 34;
const DECORATION_OFFSET: u32 = 35;

const STORAGE_UNIFORM_CONSTANT: u32 = 0;
const STORAGE_UNIFORM: u32 = 2;
const STORAGE_STORAGE_BUFFER: u32 = 12;

/// One descriptor a kernel uses: its binding (set 0), type and the GLSL name of its
/// block or variable (for messages).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct KernelBinding {
    pub binding: u32,
    pub ty: vk::DescriptorType,
    pub name: String,
}

fn words(code: &[u8]) -> Vec<u32> {
    code.chunks_exact(4)
        .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect()
}

/// The module's instructions as word slices (opcode in the low 16 bits of the first).
fn instructions(words: &[u32]) -> Vec<&[u32]> {
    let mut out = Vec::new();
    let mut i = 5;
    while i < words.len() {
        let count = (words[i] >> 16) as usize;
        if count == 0 || i + count > words.len() {
            break;
        }
        out.push(&words[i..i + count]);
        i += count;
    }
    out
}

fn string_at(w: &[u32]) -> String {
    let bytes: Vec<u8> = w
        .iter()
        .flat_map(|x| x.to_le_bytes())
        .take_while(|&b| b != 0)
        .collect();
    String::from_utf8_lossy(&bytes).to_string()
}

/// The descriptor bindings of set 0 that the kernel's code reads or writes, by binding
/// number. Declared but unused resources are left out, so a kernel's layout holds
/// exactly what it touches.
pub fn kernel_bindings(code: &[u8]) -> Result<Vec<KernelBinding>, String> {
    let words = words(code);
    let insts = instructions(&words);
    let mut names: HashMap<u32, String> = HashMap::new();
    let mut binding: HashMap<u32, u32> = HashMap::new();
    let mut set: HashMap<u32, u32> = HashMap::new();
    let mut block: HashSet<u32> = HashSet::new();
    let mut buffer_block: HashSet<u32> = HashSet::new();
    let mut pointer_to: HashMap<u32, u32> = HashMap::new();
    let mut element_of: HashMap<u32, u32> = HashMap::new();
    let mut acceleration_structures: HashSet<u32> = HashSet::new();
    let mut structs: HashSet<u32> = HashSet::new();
    let mut variables: Vec<(u32, u32, u32)> = Vec::new(); // (id, pointer type, storage class)
    let mut used: HashSet<u32> = HashSet::new();
    let mut in_functions = false;
    for inst in &insts {
        let op = inst[0] & 0xffff;
        match op {
            OP_NAME if inst.len() > 2 => {
                names.insert(inst[1], string_at(&inst[2..]));
            }
            OP_DECORATE if inst.len() > 2 => match inst[2] {
                DECORATION_BINDING if inst.len() > 3 => {
                    binding.insert(inst[1], inst[3]);
                }
                DECORATION_DESCRIPTOR_SET if inst.len() > 3 => {
                    set.insert(inst[1], inst[3]);
                }
                DECORATION_BLOCK => {
                    block.insert(inst[1]);
                }
                DECORATION_BUFFER_BLOCK => {
                    buffer_block.insert(inst[1]);
                }
                _ => {}
            },
            OP_TYPE_STRUCT => {
                structs.insert(inst[1]);
            }
            OP_TYPE_POINTER if inst.len() > 3 => {
                pointer_to.insert(inst[1], inst[3]);
            }
            OP_TYPE_ARRAY | OP_TYPE_RUNTIME_ARRAY if inst.len() > 2 => {
                element_of.insert(inst[1], inst[2]);
            }
            OP_TYPE_ACCELERATION_STRUCTURE => {
                acceleration_structures.insert(inst[1]);
            }
            OP_FUNCTION => in_functions = true,
            OP_VARIABLE if !in_functions && inst.len() > 3 => {
                variables.push((inst[2], inst[1], inst[3]));
            }
            OP_LOAD
            | OP_ACCESS_CHAIN
            | OP_IN_BOUNDS_ACCESS_CHAIN
            | OP_PTR_ACCESS_CHAIN
            | OP_ARRAY_LENGTH
                if in_functions && inst.len() > 3 =>
            {
                used.insert(inst[3]);
            }
            OP_STORE if in_functions && inst.len() > 1 => {
                used.insert(inst[1]);
            }
            _ => {}
        }
    }
    let mut out: BTreeMap<u32, KernelBinding> = BTreeMap::new();
    for (id, pointer, storage) in variables {
        let Some(&b) = binding.get(&id) else { continue };
        if !used.contains(&id) {
            continue;
        }
        if set.get(&id).copied().unwrap_or(0) != 0 {
            return Err(format!("variable {id} uses a descriptor set other than 0"));
        }
        let mut ty = pointer_to.get(&pointer).copied().unwrap_or(0);
        while let Some(&e) = element_of.get(&ty) {
            ty = e;
        }
        let kind = match storage {
            STORAGE_STORAGE_BUFFER => vk::DescriptorType::STORAGE_BUFFER,
            STORAGE_UNIFORM if buffer_block.contains(&ty) => vk::DescriptorType::STORAGE_BUFFER,
            STORAGE_UNIFORM if block.contains(&ty) => vk::DescriptorType::UNIFORM_BUFFER,
            STORAGE_UNIFORM_CONSTANT if acceleration_structures.contains(&ty) => {
                vk::DescriptorType::ACCELERATION_STRUCTURE_KHR
            }
            _ => return Err(format!("binding {b}: a descriptor of a kind lightpath does not bind (storage class {storage})")),
        };
        let name = if structs.contains(&ty) {
            names.get(&ty).cloned()
        } else {
            None
        }
        .or_else(|| names.get(&id).cloned())
        .unwrap_or_else(|| format!("binding {b}"));
        if let Some(prev) = out.get(&b) {
            return Err(format!(
                "binding {b} is declared twice ({} and {name})",
                prev.name
            ));
        }
        out.insert(
            b,
            KernelBinding {
                binding: b,
                ty: kind,
                name,
            },
        );
    }
    Ok(out.into_values().collect())
}

/// Member offsets of named structs in a SPIR-V module: (struct name, member name, offset).
pub fn struct_member_offsets(code: &[u8]) -> Vec<(String, String, u32)> {
    let words = words(code);
    let mut names: HashMap<u32, String> = HashMap::new();
    let mut member_names: HashMap<(u32, u32), String> = HashMap::new();
    let mut offsets: Vec<(u32, u32, u32)> = Vec::new();
    for inst in instructions(&words) {
        match inst[0] & 0xffff {
            OP_NAME if inst.len() > 2 => {
                names.insert(inst[1], string_at(&inst[2..]));
            }
            OP_MEMBER_NAME if inst.len() > 3 => {
                member_names.insert((inst[1], inst[2]), string_at(&inst[3..]));
            }
            OP_MEMBER_DECORATE if inst.len() > 4 && inst[3] == DECORATION_OFFSET => {
                offsets.push((inst[1], inst[2], inst[4]))
            }
            _ => {}
        }
    }
    offsets
        .into_iter()
        .filter_map(|(ty, member, offset)| {
            Some((
                names.get(&ty)?.clone(),
                member_names.get(&(ty, member))?.clone(),
                offset,
            ))
        })
        .collect()
}

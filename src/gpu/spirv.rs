//! What a lane of a pipeline carries, read statically from its SPIR-V
//! (issue 47), for every law (each law's `footprint.rs` names its
//! pipelines): the bytes of function variables naga declares (what
//! the driver receives), and after `spirv-opt -O` with unlimited scalar
//! replacement the private arrays that remain because an access chain
//! indexes them at run time. A thread on an NVIDIA GPU holds at most 255
//! 32-bit registers; a private array indexed at run time lives in local
//! memory, off-chip, on every access, whatever its size. `pidm info
//! --shader DIR` prints these figures per variant, and a test holds the
//! hardware variants to their budgets.
//!
//! The SPIR-V is read with a few opcodes of the specification (types,
//! constants, variables, access chains, names), not a library: nothing
//! here runs in a pipeline.

use crate::gpu::GpuError;
use std::collections::HashMap;
use std::process::Command;

/// The SPIR-V naga writes for a validated module with the options pidm's
/// pipelines use (`context::compile_trusted`: no bounds checks, no loop
/// counters).
pub fn module_spirv(
    module: &naga::Module,
    info: &naga::valid::ModuleInfo,
    precision: crate::laws::Precision,
) -> Result<Vec<u32>, GpuError> {
    let options = naga::back::spv::Options {
        bounds_check_policies: naga::proc::BoundsCheckPolicies {
            index: naga::proc::BoundsCheckPolicy::Unchecked,
            buffer: naga::proc::BoundsCheckPolicy::Unchecked,
            image_load: naga::proc::BoundsCheckPolicy::Unchecked,
            binding_array: naga::proc::BoundsCheckPolicy::Unchecked,
        },
        force_loop_bounding: false,
        ..Default::default()
    };
    naga::back::spv::write_vec(module, info, &options, None).map_err(|e| GpuError::ShaderCompile {
        precision,
        message: e.to_string(),
    })
}

/// One private array a lane indexes at run time.
#[derive(Clone, Debug, PartialEq)]
pub struct IndexedArray {
    /// The variable's name in the SPIR-V (naga's, where the optimiser kept
    /// it), else its id.
    pub name: String,
    pub bytes: usize,
}

/// The static footprint of one variant.
#[derive(Clone, Debug, PartialEq)]
pub struct Footprint {
    /// Bytes of every function variable of naga's SPIR-V, all functions
    /// together (what the driver receives, before it inlines and splits).
    pub declared_bytes: usize,
    /// The private arrays indexed at run time after `spirv-opt`, or `None`
    /// where `spirv-opt` (Debian's spirv-tools) is not on the PATH.
    pub indexed: Option<Vec<IndexedArray>>,
    /// Instructions after `spirv-opt`, which inlines every function as
    /// Mesa's NIR does: the code a driver compiles (`None` as above).
    pub instructions: Option<usize>,
    /// Instructions of naga's SPIR-V with every call inlined before any
    /// folding (a branch on a constant inlines both sides): what a driver
    /// that inlines first works through (lavapipe's pipeline creation
    /// scales with it).
    pub inlined: usize,
}

impl Footprint {
    /// Bytes of private arrays indexed at run time (`None`: not measured).
    pub fn indexed_bytes(&self) -> Option<usize> {
        self.indexed
            .as_ref()
            .map(|a| a.iter().map(|x| x.bytes).sum())
    }
}

/// The footprint of a module's SPIR-V (`spirv-opt` run as a child, in a
/// temporary folder): each law's `footprint.rs` reads its pipelines' so.
pub fn measure_spirv(words: &[u32]) -> Footprint {
    let naga_module = Module::parse(words);
    let declared_bytes = naga_module.function_variable_bytes();
    let inlined = naga_module.inlined_size();
    let opt = optimized(words);
    let indexed = opt.as_ref().map(|opt| Module::parse(opt).indexed_arrays());
    let instructions = opt.as_ref().map(|opt| instruction_count(opt));
    Footprint {
        declared_bytes,
        indexed,
        instructions,
        inlined,
    }
}

/// The optimiser's arguments: `-O` with scalar replacement of aggregates of
/// any size (the default stops at 100 elements).
pub const SPIRV_OPT_ARGS: [&str; 3] = ["-O", "--scalar-replacement=0", "-O"];

/// `spirv-opt`'s output for a module, or `None` where it is not installed
/// or fails.
fn optimized(words: &[u32]) -> Option<Vec<u32>> {
    let dir = tempfile_dir()?;
    let input = dir.join("in.spv");
    let output = dir.join("out.spv");
    let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
    std::fs::write(&input, bytes).ok()?;
    let status = Command::new("spirv-opt")
        .args(SPIRV_OPT_ARGS)
        .arg(&input)
        .arg("-o")
        .arg(&output)
        .status()
        .ok()?;
    let out = status
        .success()
        .then(|| std::fs::read(&output).ok())
        .flatten()
        .map(|b| {
            b.chunks_exact(4)
                .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                .collect()
        });
    let _ = std::fs::remove_dir_all(&dir);
    out
}

/// A fresh folder under the system's temporary directory (also the RADV
/// probe's, `gpu::isa`).
pub(crate) fn tempfile_dir() -> Option<std::path::PathBuf> {
    use std::sync::atomic::{AtomicU64, Ordering};
    static NEXT: AtomicU64 = AtomicU64::new(0);
    let dir = std::env::temp_dir().join(format!(
        "pidm-footprint-{}-{}",
        std::process::id(),
        NEXT.fetch_add(1, Ordering::Relaxed)
    ));
    std::fs::create_dir_all(&dir).ok()?;
    Some(dir)
}

/// Whether `spirv-opt` can be run (for tests that say why they need it).
pub fn spirv_opt_available() -> bool {
    Command::new("spirv-opt")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success())
}

/// Instructions of a module (its header left out).
fn instruction_count(words: &[u32]) -> usize {
    let mut at = 5;
    let mut count = 0;
    while at < words.len() {
        let n = (words[at] >> 16) as usize;
        if n == 0 {
            break;
        }
        count += 1;
        at += n;
    }
    count
}

// SPIR-V opcodes (the specification's numbers).
const OP_NAME: u16 = 5;
const OP_TYPE_BOOL: u16 = 20;
const OP_TYPE_INT: u16 = 21;
const OP_TYPE_FLOAT: u16 = 22;
const OP_TYPE_VECTOR: u16 = 23;
const OP_TYPE_MATRIX: u16 = 24;
const OP_TYPE_ARRAY: u16 = 28;
const OP_TYPE_STRUCT: u16 = 30;
const OP_TYPE_POINTER: u16 = 32;
const OP_CONSTANT_TRUE: u16 = 41;
const OP_CONSTANT_FALSE: u16 = 42;
const OP_CONSTANT: u16 = 43;
const OP_CONSTANT_NULL: u16 = 46;
const OP_VARIABLE: u16 = 59;
const OP_ACCESS_CHAIN: u16 = 65;
const OP_IN_BOUNDS_ACCESS_CHAIN: u16 = 66;
const STORAGE_FUNCTION: u32 = 7;

/// A type, as far as sizes and indexing need it.
#[derive(Clone, Debug)]
enum Type {
    Scalar(usize),
    Vector(u32, u32),
    Array(u32, u32),
    Struct(Vec<u32>),
    /// The pointee.
    Pointer(u32),
    Other,
}

/// The parts of a module this file reads.
#[derive(Default)]
pub(crate) struct Module {
    types: HashMap<u32, Type>,
    /// Integer constants by id (array lengths), and every constant's id.
    constants: HashMap<u32, u64>,
    /// Function variables: id and pointer type.
    variables: Vec<(u32, u32)>,
    /// Access chains: result, base, indices.
    chains: Vec<(u32, u32, Vec<u32>)>,
    names: HashMap<u32, String>,
    /// Per function: its instructions and the functions it calls (once per
    /// call); the entry point's function.
    functions: HashMap<u32, (usize, Vec<u32>)>,
    current: Option<u32>,
    entry: Option<u32>,
}

impl Module {
    pub(crate) fn parse(words: &[u32]) -> Module {
        let mut m = Module::default();
        let mut at = 5;
        while at < words.len() {
            let count = (words[at] >> 16) as usize;
            let op = (words[at] & 0xffff) as u16;
            if count == 0 || at + count > words.len() {
                break;
            }
            let operands = &words[at + 1..at + count];
            m.read(op, operands);
            m.read_function(op, operands);
            at += count;
        }
        m
    }

    fn read(&mut self, op: u16, w: &[u32]) {
        match op {
            OP_NAME => {
                let bytes: Vec<u8> = w[1..].iter().flat_map(|x| x.to_le_bytes()).collect();
                let end = bytes.iter().position(|&b| b == 0).unwrap_or(bytes.len());
                let name = String::from_utf8_lossy(&bytes[..end]).into_owned();
                self.names.insert(w[0], name);
            }
            OP_TYPE_BOOL => {
                self.types.insert(w[0], Type::Scalar(4));
            }
            OP_TYPE_INT | OP_TYPE_FLOAT => {
                self.types.insert(w[0], Type::Scalar(w[1] as usize / 8));
            }
            OP_TYPE_VECTOR | OP_TYPE_MATRIX => {
                self.types.insert(w[0], Type::Vector(w[1], w[2]));
            }
            OP_TYPE_ARRAY => {
                self.types.insert(w[0], Type::Array(w[1], w[2]));
            }
            OP_TYPE_STRUCT => {
                self.types.insert(w[0], Type::Struct(w[1..].to_vec()));
            }
            OP_TYPE_POINTER => {
                self.types.insert(w[0], Type::Pointer(w[2]));
            }
            OP_CONSTANT => {
                self.constants.insert(w[1], w[2] as u64);
            }
            OP_CONSTANT_TRUE | OP_CONSTANT_FALSE | OP_CONSTANT_NULL | 44 | 48..=52 => {
                self.constants.insert(w[1], 0);
            }
            OP_VARIABLE if w[2] == STORAGE_FUNCTION => self.variables.push((w[1], w[0])),
            OP_VARIABLE => {}
            OP_ACCESS_CHAIN | OP_IN_BOUNDS_ACCESS_CHAIN => {
                self.chains.push((w[1], w[2], w[3..].to_vec()));
            }
            _ => {
                if (19..=39).contains(&op) {
                    self.types.entry(w[0]).or_insert(Type::Other);
                }
            }
        }
    }

    /// Functions, their sizes and calls (OpFunction 54, OpFunctionEnd 56,
    /// OpFunctionCall 57, OpEntryPoint 15).
    fn read_function(&mut self, op: u16, w: &[u32]) {
        match op {
            15 => self.entry = w.get(1).copied(),
            54 => {
                self.current = Some(w[1]);
                self.functions.insert(w[1], (0, Vec::new()));
            }
            56 => self.current = None,
            _ => {
                if let Some(f) = self.current {
                    let entry = self.functions.get_mut(&f).expect("opened");
                    entry.0 += 1;
                    if op == 57 {
                        entry.1.push(w[2]);
                    }
                }
            }
        }
    }

    /// Instructions of the entry point with every call inlined, before any
    /// folding: what a driver that inlines first (Mesa's NIR does) starts
    /// from.
    pub(crate) fn inlined_size(&self) -> usize {
        fn size(m: &Module, f: u32, memo: &mut HashMap<u32, usize>) -> usize {
            if let Some(&n) = memo.get(&f) {
                return n;
            }
            let Some((own, calls)) = m.functions.get(&f) else {
                return 0;
            };
            let n = own + calls.iter().map(|&g| size(m, g, memo)).sum::<usize>();
            memo.insert(f, n);
            n
        }
        self.entry.map_or(0, |e| size(self, e, &mut HashMap::new()))
    }

    /// Bytes of a type (booleans as 4, no padding).
    fn size(&self, ty: u32) -> usize {
        match self.types.get(&ty) {
            Some(Type::Scalar(b)) => *b,
            Some(Type::Vector(of, n)) => self.size(*of) * *n as usize,
            Some(Type::Array(of, len)) => {
                self.size(*of) * self.constants.get(len).copied().unwrap_or(0) as usize
            }
            Some(Type::Struct(members)) => members.iter().map(|m| self.size(*m)).sum(),
            _ => 0,
        }
    }

    fn pointee(&self, pointer: u32) -> u32 {
        match self.types.get(&pointer) {
            Some(Type::Pointer(of)) => *of,
            _ => 0,
        }
    }

    fn function_variable_bytes(&self) -> usize {
        self.variables
            .iter()
            .map(|&(_, ty)| self.size(self.pointee(ty)))
            .sum()
    }

    /// Function variables with an access chain (direct, or through another
    /// chain) that indexes an array by a value that is not a constant.
    fn indexed_arrays(&self) -> Vec<IndexedArray> {
        // Each chain's root variable and the type its base points to.
        let mut root: HashMap<u32, (u32, u32)> = self
            .variables
            .iter()
            .map(|&(id, ty)| (id, (id, self.pointee(ty))))
            .collect();
        let mut dynamic = std::collections::BTreeSet::new();
        for (result, base, indices) in &self.chains {
            let Some(&(var, mut ty)) = root.get(base) else {
                continue;
            };
            for index in indices {
                match self.types.get(&ty) {
                    Some(Type::Array(of, _)) => {
                        if !self.constants.contains_key(index) {
                            dynamic.insert(var);
                        }
                        ty = *of;
                    }
                    Some(Type::Vector(of, _)) => ty = *of,
                    Some(Type::Struct(members)) => {
                        let k = self.constants.get(index).copied().unwrap_or(0) as usize;
                        ty = members.get(k).copied().unwrap_or(0);
                    }
                    _ => break,
                }
            }
            root.insert(*result, (var, ty));
        }
        let types: HashMap<u32, u32> = self.variables.iter().copied().collect();
        dynamic
            .into_iter()
            .map(|var| IndexedArray {
                name: self
                    .names
                    .get(&var)
                    .cloned()
                    .unwrap_or_else(|| format!("%{var}")),
                bytes: self.size(self.pointee(types[&var])),
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The reader sees what it is meant to: a private array indexed by a
    /// loop's counter stays indexed after the optimiser, one indexed only
    /// by constants does not, and the declared bytes count both.
    #[test]
    fn the_reader_finds_an_array_indexed_at_run_time() {
        let src = "
@group(0) @binding(0) var<storage, read_write> out: array<f32>;
@compute @workgroup_size(1)
fn main(@builtin(global_invocation_id) g: vec3<u32>) {
    var a = array<f32, 8>(1., 2., 3., 4., 5., 6., 7., 8.);
    var b = array<f32, 4>(1., 2., 3., 4.);
    out[0] = a[g.x % 8u] + b[1] + b[3];
}
";
        let module = naga::front::wgsl::parse_str(src).unwrap();
        let info = naga::valid::Validator::new(
            naga::valid::ValidationFlags::all(),
            naga::valid::Capabilities::empty(),
        )
        .validate(&module)
        .unwrap();
        let options = naga::back::spv::Options {
            force_loop_bounding: false,
            ..Default::default()
        };
        let words = naga::back::spv::write_vec(&module, &info, &options, None).unwrap();
        assert_eq!(Module::parse(&words).function_variable_bytes(), 48);
        if let Some(opt) = optimized(&words) {
            let indexed = Module::parse(&opt).indexed_arrays();
            assert_eq!(indexed.iter().map(|a| a.bytes).collect::<Vec<_>>(), [32]);
        }
    }
}

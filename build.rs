//! Compiles every compute kernel in glsl/ to SPIR-V, once per traversal backend, and
//! turns the `#define`s of glsl/lib/abi.h into Rust constants (one source for both).
use std::fs;
use std::path::{Path, PathBuf};

/// The traversal backends: (suffix, define).
const BACKENDS: [(&str, &str); 3] = [
    ("rayquery", "ACCEL_RAYQUERY"),
    ("cwbvh", "ACCEL_CWBVH"),
    ("bvh2", "ACCEL_BVH2"),
];

fn main() {
    let out = PathBuf::from(std::env::var("OUT_DIR").expect("OUT_DIR"));
    let root = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").expect("CARGO_MANIFEST_DIR"));
    let glsl = root.join("glsl");
    println!("cargo:rerun-if-changed=glsl");

    let abi = glsl.join("lib/abi.h");
    println!("cargo:rerun-if-changed={}", abi.display());
    write_abi_constants(&abi, &out.join("abi_constants.rs"));

    let mut kernels: Vec<PathBuf> = fs::read_dir(&glsl)
        .expect("read glsl/")
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "comp"))
        .collect();
    kernels.sort();

    // Every (kernel, variant, backend) is one job; jobs run on all cores (optimizing the
    // largest kernels takes minutes each), and the table lists them in a fixed order.
    let mut jobs = Vec::new();
    for kernel in &kernels {
        println!("cargo:rerun-if-changed={}", kernel.display());
        let base = kernel.file_stem().unwrap().to_string_lossy().to_string();
        let source = fs::read_to_string(kernel).expect("read kernel");
        for (variant, variant_define) in variants(&base) {
            let name = if variant.is_empty() {
                base.clone()
            } else {
                format!("{base}+{variant}")
            };
            for (suffix, define) in BACKENDS {
                jobs.push(Job {
                    kernel: kernel.clone(),
                    source: source.clone(),
                    name: name.clone(),
                    variant_define,
                    suffix,
                    define,
                });
            }
        }
    }
    let threads = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .min(jobs.len().max(1));
    let next = std::sync::atomic::AtomicUsize::new(0);
    // Each thread takes the next job and keeps (job index, result); they are put back in
    // the jobs' order below.
    let mut results: Vec<(usize, Result<Vec<u8>, String>)> = std::thread::scope(|scope| {
        let workers: Vec<_> = (0..threads)
            .map(|_| {
                scope.spawn(|| {
                    let compiler = shaderc::Compiler::new().expect("shaderc compiler");
                    let mut done = Vec::new();
                    loop {
                        let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                        let Some(job) = jobs.get(i) else {
                            return done;
                        };
                        done.push((i, compile(&compiler, &root, &glsl, job)));
                    }
                })
            })
            .collect();
        workers
            .into_iter()
            .flat_map(|w| w.join().expect("a compile thread panicked"))
            .collect()
    });
    results.sort_by_key(|(i, _)| *i);
    let mut table = String::from("/// (kernel name, backend, SPIR-V words) for every compiled kernel.\npub const KERNELS: &[(&str, &str, &[u8])] = &[\n");
    let mut failed = false;
    for (job, (_, result)) in jobs.iter().zip(results) {
        let Job {
            kernel,
            name,
            suffix,
            ..
        } = job;
        match result {
            Ok(spirv) => {
                let spv = out.join(format!("{name}.{suffix}.spv"));
                fs::write(&spv, spirv).expect("write spv");
                table.push_str(&format!(
                    "    ({name:?}, {suffix:?}, include_bytes!(concat!(env!(\"OUT_DIR\"), \"/{name}.{suffix}.spv\"))),\n"
                ));
            }
            Err(e) => {
                // shaderc's messages already read "file:line: error: ...".
                eprintln!(
                    "GLSL error in {} ({suffix} backend):\n{e}",
                    kernel.display()
                );
                for line in e.lines() {
                    println!("cargo:warning={line}");
                }
                failed = true;
            }
        }
    }
    table.push_str("];\n");
    if failed {
        panic!("GLSL compilation failed; see the errors above (file:line)");
    }
    fs::write(out.join("kernels.rs"), table).expect("write kernels.rs");
}

/// One kernel in one variant for one backend.
struct Job {
    kernel: PathBuf,
    source: String,
    /// The table's name: the kernel's, with `+variant` for a profiling variant.
    name: String,
    variant_define: Option<&'static str>,
    suffix: &'static str,
    define: &'static str,
}

/// Compiles one kernel for one backend and variant: its SPIR-V, or shaderc's message.
/// Warnings are passed on to cargo.
fn compile(
    compiler: &shaderc::Compiler,
    root: &Path,
    glsl: &Path,
    job: &Job,
) -> Result<Vec<u8>, String> {
    let Job {
        kernel,
        source,
        variant_define,
        define,
        ..
    } = job;
    let mut options = shaderc::CompileOptions::new().expect("shaderc options");
    options.set_target_env(
        shaderc::TargetEnv::Vulkan,
        shaderc::EnvVersion::Vulkan1_2 as u32,
    );
    options.set_target_spirv(shaderc::SpirvVersion::V1_5);
    options.set_optimization_level(shaderc::OptimizationLevel::Performance);
    options.set_generate_debug_info();
    options.add_macro_definition(define, Some("1"));
    if let Some(d) = variant_define {
        options.add_macro_definition(d, Some("1"));
    }
    let lib = glsl.join("lib");
    let root_for_names = root.to_path_buf();
    options.set_include_callback(move |requested, _kind, requester, _depth| {
        let requester_dir = root_for_names.join(
            Path::new(requester)
                .parent()
                .map(Path::to_path_buf)
                .unwrap_or_default(),
        );
        let candidates = [lib.join(requested), requester_dir.join(requested)];
        for path in candidates {
            if let Ok(content) = fs::read_to_string(&path) {
                println!("cargo:rerun-if-changed={}", path.display());
                // Names relative to the repository keep the SPIR-V (its debug info) the
                // same in every clone, so drivers' shader caches hold.
                let resolved_name = path
                    .strip_prefix(&root_for_names)
                    .unwrap_or(&path)
                    .display()
                    .to_string();
                return Ok(shaderc::ResolvedInclude {
                    resolved_name,
                    content,
                });
            }
        }
        Err(format!(
            "cannot find include '{requested}' (looked in glsl/lib and beside {requester})"
        ))
    });
    let artifact = compiler
        .compile_into_spirv(
            source,
            shaderc::ShaderKind::Compute,
            &kernel
                .strip_prefix(root)
                .unwrap_or(kernel)
                .display()
                .to_string(),
            "main",
            Some(&options),
        )
        .map_err(|e| e.to_string())?;
    if artifact.get_num_warnings() > 0 {
        for line in artifact.get_warning_messages().lines() {
            println!("cargo:warning={line}");
        }
    }
    Ok(artifact.as_binary_u8().to_vec())
}

/// The variants each kernel is compiled in: the kernel itself, and the profiling variants
/// of `lightpath profile`, each of which does one stage twice (the `PROFILE_X2_*` blocks of
/// glsl/lib/trace.glsl, trace_bvh_common.glsl, rng.glsl, bsdf.glsl and lights.glsl), for
/// the kernels that hold that stage: (name suffix, define).
fn variants(kernel: &str) -> Vec<(&'static str, Option<&'static str>)> {
    const TRACE: (&str, Option<&str>) = ("x2trace", Some("PROFILE_X2_TRACE"));
    const PRIM: (&str, Option<&str>) = ("x2prim", Some("PROFILE_X2_PRIM"));
    const RNG: (&str, Option<&str>) = ("x2rng", Some("PROFILE_X2_RNG"));
    const BSDF: (&str, Option<&str>) = ("x2bsdf", Some("PROFILE_X2_BSDF"));
    const LIGHT: (&str, Option<&str>) = ("x2light", Some("PROFILE_X2_LIGHT"));
    let mut v = vec![("", None)];
    match kernel {
        "bdpt_trace" => v.extend([TRACE, PRIM]),
        "bdpt_start" | "bdpt_hit" => v.extend([RNG, LIGHT]),
        k if k.starts_with("bdpt_shade_") => v.extend([RNG, BSDF]),
        "pt_trace" | "pt_shadow" => v.extend([TRACE, PRIM]),
        "pt_camera" => v.push(RNG),
        "pt_hit" => v.extend([RNG, LIGHT]),
        k if k.starts_with("pt_shade_") => v.extend([RNG, BSDF]),
        _ => {}
    }
    v
}

/// `#define NAME 123` / `#define NAME 123u` lines of abi.h become `pub const NAME: u32`;
/// `#define NAME 0.5` (a decimal point), `pub const NAME: f32`.
fn write_abi_constants(abi: &Path, dest: &Path) {
    let text = fs::read_to_string(abi).expect("read glsl/lib/abi.h");
    let mut rust = String::from("// Generated by build.rs from glsl/lib/abi.h. Do not edit.\n");
    for line in text.lines() {
        let mut words = line.split_whitespace();
        if words.next() != Some("#define") {
            continue;
        }
        let (Some(name), Some(value), None) = (words.next(), words.next(), words.next()) else {
            continue;
        };
        let value = value.trim_end_matches('u');
        if let Ok(v) = value.parse::<u32>() {
            rust.push_str(&format!("pub const {name}: u32 = {v};\n"));
        } else if let (true, Ok(v)) = (value.contains('.'), value.parse::<f32>()) {
            rust.push_str(&format!("pub const {name}: f32 = {v:?};\n"));
        }
    }
    fs::write(dest, rust).expect("write abi constants");
}

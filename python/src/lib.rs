//! lightpath's Python bindings (the `lightpath._lightpath` extension): thin wrappers over
//! the renderer's Rust API (scene loading, `Renderer::render`, the EXR metadata, compare
//! and merge), so that a notebook renders exactly what the command line renders.
//! The Python package (pysrc/lightpath) re-exports these; its `__init__.pyi` documents
//! them for editors.
use lightpath::cli::{apply_overrides, RenderArgs};
use lightpath::io::{self, Image, RenderInfo};
use lightpath::render::{AccelChoice, BdptDetails, MmltReport, RenderRequest, Renderer};
use lightpath::scene::{self, IntegratorKind};
use lightpath::trace::{Span, Trace};
use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::create_exception;
use pyo3::exceptions::{PyKeyboardInterrupt, PyRuntimeError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyTuple};
use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, OnceLock, Weak};
use std::time::{Duration, Instant};

// Large allocations on huge pages, as the command line's (src/memory.rs).
#[global_allocator]
static ALLOCATOR: lightpath::memory::LargePages = lightpath::memory::LargePages;

create_exception!(
    _lightpath,
    SceneError,
    PyValueError,
    "A scene file that cannot be read: the message names the file and line, as the command line's does."
);
create_exception!(
    _lightpath,
    RenderError,
    PyRuntimeError,
    "A render that failed on the device (the message names the stage), or no device at all."
);

/// SIGINT's number: what an interrupted render reports, as the command line's.
const SIGINT: usize = 2;

fn render_error(e: anyhow::Error) -> PyErr {
    RenderError::new_err(format!("{e:#}"))
}

/// Renderers opened so far, one per (device, accel): a device and its compiled pipelines
/// are opened once per process and reused.
type RendererCache = Mutex<HashMap<(Option<String>, String), Arc<Mutex<Renderer>>>>;

fn renderers() -> &'static RendererCache {
    static CACHE: OnceLock<RendererCache> = OnceLock::new();
    CACHE.get_or_init(Default::default)
}

/// The interrupt flags of the renders under way (see `interrupt`).
fn running() -> &'static Mutex<Vec<Weak<AtomicUsize>>> {
    static RUNNING: OnceLock<Mutex<Vec<Weak<AtomicUsize>>>> = OnceLock::new();
    RUNNING.get_or_init(Default::default)
}

fn renderer_for(device: Option<&str>, accel: &str) -> PyResult<Arc<Mutex<Renderer>>> {
    let choice = AccelChoice::from_name(accel).ok_or_else(|| {
        PyValueError::new_err(format!(
            "accel {accel:?}: expected auto, rayquery, bvh, cwbvh or bvh2"
        ))
    })?;
    let key = (device.map(str::to_owned), accel.to_owned());
    let mut cache = renderers().lock().unwrap_or_else(|e| e.into_inner());
    if let Some(r) = cache.get(&key) {
        return Ok(r.clone());
    }
    let r = Arc::new(Mutex::new(
        Renderer::new(device, choice).map_err(render_error)?,
    ));
    cache.insert(key, r.clone());
    Ok(r)
}

fn image_to_numpy<'py>(py: Python<'py>, image: &Image) -> PyResult<Bound<'py, PyAny>> {
    let flat: Vec<f32> = image.pixels.iter().flatten().copied().collect();
    let array =
        PyArray1::from_vec(py, flat).reshape([image.height as usize, image.width as usize, 3])?;
    Ok(array.into_any())
}

fn numpy_to_image(array: PyReadonlyArray3<'_, f32>) -> PyResult<Image> {
    let shape = array.shape();
    if shape[2] != 3 {
        return Err(PyValueError::new_err(format!(
            "an image is an H x W x 3 array, got {shape:?}"
        )));
    }
    let data = array.as_array();
    let mut pixels = Vec::with_capacity(shape[0] * shape[1]);
    for y in 0..shape[0] {
        for x in 0..shape[1] {
            pixels.push([data[[y, x, 0]], data[[y, x, 1]], data[[y, x, 2]]]);
        }
    }
    Ok(Image {
        width: shape[1] as u32,
        height: shape[0] as u32,
        pixels,
    })
}

/// A scene read from a `.test` or `.pbrt` file, with the settings the command line can
/// override.
#[pyclass(module = "lightpath")]
#[derive(Clone)]
struct Scene {
    scene: scene::Scene,
    path: PathBuf,
    bytes: Arc<Vec<u8>>,
}

#[pymethods]
impl Scene {
    /// The image size, (width, height).
    #[getter]
    fn size(&self) -> (u32, u32) {
        (self.scene.width, self.scene.height)
    }

    #[setter]
    fn set_size(&mut self, size: (i64, i64)) -> PyResult<()> {
        let (w, h) = size;
        if !(1..=65536).contains(&w) || !(1..=65536).contains(&h) {
            return Err(PyValueError::new_err(format!(
                "size must be two sides of 1 to 65536 pixels, got ({w}, {h})"
            )));
        }
        self.scene.width = w as u32;
        self.scene.height = h as u32;
        Ok(())
    }

    /// Scattering vertices per path at most (-1: unbounded, with Russian roulette).
    #[getter]
    fn max_depth(&self) -> i32 {
        self.scene.settings.max_depth
    }

    #[setter]
    fn set_max_depth(&mut self, d: i64) -> PyResult<()> {
        if !(-1..=i32::MAX as i64).contains(&d) {
            return Err(PyValueError::new_err(format!(
                "max_depth must be -1 (unbounded) or at least 0, got {d}"
            )));
        }
        self.scene.settings.max_depth = d as i32;
        Ok(())
    }

    /// Samples per pixel (MMLT: mutations per pixel).
    #[getter]
    fn spp(&self) -> u32 {
        self.scene.settings.spp
    }

    #[setter]
    fn set_spp(&mut self, spp: i64) -> PyResult<()> {
        self.scene.settings.spp = check_spp(spp)?;
        Ok(())
    }

    /// The integrator the file asks for: pathtracer, direct, analyticdirect, bdpt or mmlt.
    #[getter]
    fn integrator(&self) -> &'static str {
        self.scene.settings.integrator.name()
    }

    #[setter]
    fn set_integrator(&mut self, name: &str) -> PyResult<()> {
        self.scene.settings.integrator = integrator_kind(name)?;
        Ok(())
    }

    /// The file the scene was read from.
    #[getter]
    fn path(&self) -> String {
        self.path.display().to_string()
    }

    fn __repr__(&self) -> String {
        format!(
            "lightpath.Scene({:?}, size=({}, {}), integrator={:?}, spp={}, max_depth={})",
            self.path.display().to_string(),
            self.scene.width,
            self.scene.height,
            self.scene.settings.integrator.name(),
            self.scene.settings.spp,
            self.scene.settings.max_depth
        )
    }
}

fn check_spp(spp: i64) -> PyResult<u32> {
    if !(1..=u32::MAX as i64).contains(&spp) {
        return Err(PyValueError::new_err(format!(
            "spp must be at least 1 (and below 2^32), got {spp}"
        )));
    }
    Ok(spp as u32)
}

fn integrator_kind(name: &str) -> PyResult<IntegratorKind> {
    IntegratorKind::from_name(name).ok_or_else(|| {
        PyValueError::new_err(format!(
            "integrator {name:?}: expected {}",
            lightpath::integrators::names()
        ))
    })
}

/// Reads a scene file (`.test`, or `.pbrt` by its extension). Raises SceneError with the
/// file and line of what is wrong.
#[pyfunction]
fn load(path: PathBuf) -> PyResult<Scene> {
    let scene = scene::load(&path).map_err(|e| SceneError::new_err(e.to_string()))?;
    let bytes = std::fs::read(&path)
        .map_err(|e| SceneError::new_err(format!("cannot read {}: {e}", path.display())))?;
    Ok(Scene {
        scene,
        path,
        bytes: Arc::new(bytes),
    })
}

/// A render: its image, how it was made, and what its integrator measured.
#[pyclass(module = "lightpath")]
struct RenderResult {
    image: Image,
    info: RenderInfo,
    gamma: f32,
    interrupted: bool,
    strategies: Option<Vec<lightpath::render::StrategyImages>>,
    mmlt: Option<MmltReport>,
    spans: Vec<Span>,
    /// A gbuffer film's channels (lightpath::integrators::gbuffer).
    aux: Vec<lightpath::integrators::gbuffer::AuxChannel>,
}

#[pymethods]
impl RenderResult {
    /// A `gbuffer` film's channels beside the image (pbrt-v4's names: `Albedo.R`, `P.X`,
    /// `N.X`, `Ns.X`, `u`, `v`, …), each a float32 array of shape (height, width); None
    /// for other films.
    #[getter]
    fn gbuffer<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        if self.aux.is_empty() {
            return Ok(None);
        }
        let d = PyDict::new(py);
        for c in &self.aux {
            let array = PyArray1::from_vec(py, c.values.clone())
                .reshape([self.image.height as usize, self.image.width as usize])?;
            d.set_item(&c.name, array)?;
        }
        Ok(Some(d))
    }

    /// The image: a float32 array of shape (height, width, 3), linear RGB.
    #[getter]
    fn image<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        image_to_numpy(py, &self.image)
    }

    /// What the EXR header records: integrator, samples_per_pixel, seeds, max_depth,
    /// backend, device, render_seconds, version, scene_file, scene_sha256; and
    /// interrupted.
    #[getter]
    fn metadata<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        let i = &self.info;
        d.set_item("integrator", &i.integrator)?;
        d.set_item("samples_per_pixel", i.samples_per_pixel)?;
        d.set_item("seeds", i.seeds.clone())?;
        d.set_item("max_depth", i.max_depth)?;
        d.set_item("backend", &i.backend)?;
        d.set_item("device", &i.device)?;
        d.set_item("render_seconds", i.render_seconds)?;
        d.set_item("version", &i.version)?;
        d.set_item("scene_file", &i.scene_file)?;
        d.set_item("scene_sha256", &i.scene_hash)?;
        d.set_item("interrupted", self.interrupted)?;
        Ok(d)
    }

    /// Whether the render was stopped early (Ctrl-C or `interrupt()`); the image is the
    /// mean of the samples done.
    #[getter]
    fn interrupted(&self) -> bool {
        self.interrupted
    }

    /// BDPT with strategies=True: {(s, t): (weighted, unweighted)} images; the weighted
    /// ones sum to the image. None otherwise.
    #[getter]
    fn strategies<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let Some(list) = &self.strategies else {
            return Ok(None);
        };
        let d = PyDict::new(py);
        for st in list {
            let pair = PyTuple::new(
                py,
                [
                    image_to_numpy(py, &st.weighted)?,
                    image_to_numpy(py, &st.unweighted)?,
                ],
            )?;
            d.set_item((st.s, st.t), pair)?;
        }
        Ok(Some(d))
    }

    /// MMLT with depths=True: {scattering vertices: image}; they sum to the image (less
    /// the bdpt tail of max_depth -1). None otherwise.
    #[getter]
    fn depths<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let Some(m) = &self.mmlt else {
            return Ok(None);
        };
        if m.depth_images.is_empty() {
            return Ok(None);
        }
        let d = PyDict::new(py);
        for (depth, image) in m.depth_images.iter().enumerate() {
            d.set_item(depth, image_to_numpy(py, image)?)?;
        }
        Ok(Some(d))
    }

    /// MMLT's statistics: b (the image's normalization) and its standard error, chains,
    /// mutations, bootstrap samples, seconds, and per depth its b and acceptance.
    #[getter]
    fn mmlt<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let Some(m) = &self.mmlt else {
            return Ok(None);
        };
        let d = PyDict::new(py);
        d.set_item("b", m.b)?;
        d.set_item("b_stderr", m.b_stderr)?;
        d.set_item("chains", m.chains)?;
        d.set_item("mutations", m.mutations)?;
        d.set_item("bootstrap_samples", m.bootstrap_samples)?;
        d.set_item("bootstrap_seconds", m.bootstrap_seconds)?;
        d.set_item("chain_seconds", m.chain_seconds)?;
        d.set_item("mutations_per_second", m.mutations_per_second())?;
        let depths = PyList::empty(py);
        for s in &m.depths {
            let e = PyDict::new(py);
            let rate = |a: u64, p: u64| if p > 0 { a as f64 / p as f64 } else { 0.0 };
            e.set_item("depth", s.depth)?;
            e.set_item("b", s.b)?;
            e.set_item("chains", s.chains)?;
            e.set_item("large_acceptance", rate(s.large_accepted, s.large_proposed))?;
            e.set_item("small_acceptance", rate(s.small_accepted, s.small_proposed))?;
            depths.append(e)?;
        }
        d.set_item("depths", depths)?;
        Ok(Some(d))
    }

    /// The per-stage trace: a list of {name, gpu, start_us, dur_us} (CPU stages and GPU
    /// dispatches), as `--trace` writes it; host stages add host_bytes and
    /// host_peak_bytes (at their end), the scene upload device_bytes and data (per kind of
    /// scene data read by address: {name: {bytes, chunks}}).
    #[getter]
    fn trace<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let list = PyList::empty(py);
        for s in &self.spans {
            let e = PyDict::new(py);
            e.set_item("name", &s.name)?;
            e.set_item("gpu", s.gpu)?;
            e.set_item("start_us", s.start_us)?;
            e.set_item("dur_us", s.dur_us)?;
            if let Some((rss, peak)) = s.host_bytes {
                e.set_item("host_bytes", rss)?;
                e.set_item("host_peak_bytes", peak)?;
            }
            if let Some(d) = s.device_bytes {
                e.set_item("device_bytes", d)?;
            }
            if !s.data.is_empty() {
                let data = PyDict::new(py);
                for (name, bytes, chunks) in &s.data {
                    let kind = PyDict::new(py);
                    kind.set_item("bytes", bytes)?;
                    kind.set_item("chunks", chunks)?;
                    data.set_item(name, kind)?;
                }
                e.set_item("data", data)?;
            }
            list.append(e)?;
        }
        Ok(list)
    }

    /// Writes the image: EXR (linear float, with the metadata and a gbuffer film's
    /// channels) or PNG (8-bit, with the scene's gamma; an error for a gbuffer render), by
    /// the extension; through a temporary file and a rename.
    fn save(&self, path: PathBuf) -> PyResult<()> {
        io::check_writable(&path).map_err(|e| PyValueError::new_err(format!("{e:#}")))?;
        io::write_image_with_aux(&path, &self.image, self.gamma, Some(&self.info), &self.aux)
            .map_err(|e| PyRuntimeError::new_err(format!("{e:#}")))
    }

    fn __repr__(&self) -> String {
        format!(
            "lightpath.RenderResult({}x{}, {}, {} spp{})",
            self.image.width,
            self.image.height,
            self.info.integrator,
            self.info.samples_per_pixel,
            if self.interrupted {
                ", interrupted"
            } else {
                ""
            }
        )
    }
}

/// Everything `render` needs, checked before anything runs.
struct Job {
    request: RenderRequest,
    renderer: Arc<Mutex<Renderer>>,
}

/// Renders `scene` (a copy: the Scene is not changed). Keyword arguments override the
/// scene's settings as the command line's options do. The GIL is released while the
/// device works; Ctrl-C stops the render after the dispatch in flight and returns the
/// image of the samples done (`interrupted` True), a second Ctrl-C raises
/// KeyboardInterrupt at once.
#[pyfunction]
#[pyo3(signature = (scene, integrator=None, spp=None, seed=0, accel="auto", time_limit=None,
    device=None, progress=false, max_depth=None, size=None, strategies=false, depths=false,
    mmlt_bootstrap=None, mmlt_chains=None, mmlt_sigma=None, mmlt_large_step=None))]
#[allow(clippy::too_many_arguments)]
fn render(
    py: Python<'_>,
    scene: &Scene,
    integrator: Option<&str>,
    spp: Option<i64>,
    seed: i64,
    accel: &str,
    time_limit: Option<f64>,
    device: Option<String>,
    progress: bool,
    max_depth: Option<i64>,
    size: Option<(i64, i64)>,
    strategies: bool,
    depths: bool,
    mmlt_bootstrap: Option<u32>,
    mmlt_chains: Option<u32>,
    mmlt_sigma: Option<f32>,
    mmlt_large_step: Option<f32>,
) -> PyResult<RenderResult> {
    // The arguments, checked before anything renders.
    let mut s = scene.clone();
    if let Some(name) = integrator {
        s.set_integrator(name)?;
    }
    if let Some(n) = spp {
        s.set_spp(n)?;
    }
    if let Some(d) = max_depth {
        s.set_max_depth(d)?;
    }
    if let Some(size) = size {
        s.set_size(size)?;
    }
    if !(0..=u32::MAX as i64).contains(&seed) {
        return Err(PyValueError::new_err(format!(
            "seed must be in [0, 2^32), got {seed}"
        )));
    }
    let args = RenderArgs {
        scene: scene.path.clone(),
        output: None,
        spp: None,
        max_depth: None,
        seed: seed as u32,
        size: None,
        integrator: None,
        accel: accel.to_owned(),
        device: device.clone(),
        trace: None,
        bdpt_strategies: None,
        mmlt_depths: None,
        mmlt_bootstrap,
        mmlt_chains,
        mmlt_sigma,
        mmlt_large_step,
        write_partial_images: None,
        time_limit,
        validate: false,
        quiet: !progress,
    };
    apply_overrides(&mut s.scene, &args).map_err(|e| PyValueError::new_err(format!("{e:#}")))?;
    let request = RenderRequest {
        scene: s.scene,
        seed: seed as u32,
        record_strategies: strategies,
        record_depths: depths,
        time_limit,
        show_progress: progress,
    };
    request
        .check("strategies=True", "depths=True", "time_limit")
        .map_err(|e| PyValueError::new_err(format!("{e:#}")))?;
    let renderer = py.allow_threads(|| renderer_for(device.as_deref(), accel))?;
    {
        let r = renderer.lock().unwrap_or_else(|e| e.into_inner());
        r.engine
            .film_bytes(request.scene.width, request.scene.height)
            .map_err(|e| PyValueError::new_err(format!("{e:#}")))?;
    }
    let info = renderer
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .render_info(&request.scene, &s.path, &s.bytes, seed as u32);
    let gamma = request.scene.settings.gamma;
    let job = Job { request, renderer };
    run(py, job, info, gamma)
}

/// Runs the job on its own thread while this one (holding the GIL only between waits)
/// watches for Ctrl-C.
fn run(py: Python<'_>, job: Job, mut info: RenderInfo, gamma: f32) -> PyResult<RenderResult> {
    let flag = Arc::new(AtomicUsize::new(0));
    {
        let mut list = running().lock().unwrap_or_else(|e| e.into_inner());
        list.retain(|w| w.strong_count() > 0);
        list.push(Arc::downgrade(&flag));
    }
    let started = Instant::now();
    let thread_flag = flag.clone();
    let handle = std::thread::spawn(move || {
        let mut trace = Trace::new();
        let mut r = job.renderer.lock().unwrap_or_else(|e| e.into_inner());
        r.engine.control.snapshots = None;
        r.engine.control.interrupt = Some(thread_flag);
        let out = r.render_request(&job.request, &mut trace);
        r.engine.control.interrupt = None;
        (out, trace)
    });
    loop {
        if handle.is_finished() {
            break;
        }
        py.allow_threads(|| std::thread::sleep(Duration::from_millis(10)));
        if let Err(e) = py.check_signals() {
            if !e.is_instance_of::<PyKeyboardInterrupt>(py) || flag.load(Ordering::SeqCst) != 0 {
                // A second Ctrl-C (or another signal's exception): return at once; the
                // render, already told to stop, ends on its own thread.
                flag.store(SIGINT, Ordering::SeqCst);
                return Err(e);
            }
            flag.store(SIGINT, Ordering::SeqCst);
        }
    }
    let (out, trace) = handle
        .join()
        .map_err(|_| RenderError::new_err("the render thread panicked"))?;
    let mut out = out.map_err(render_error)?;
    info.samples_per_pixel = out.samples_per_pixel as u64;
    info.backend = out.backend.name().to_string();
    info.render_seconds = started.elapsed().as_secs_f64();
    let details = out.details.take();
    let (strategies, mmlt) = match details {
        Some(d) => match d.downcast::<BdptDetails>() {
            Ok(b) => (Some(b.strategies), None),
            Err(d) => (None, d.downcast::<MmltReport>().ok().map(|m| *m)),
        },
        None => (None, None),
    };
    Ok(RenderResult {
        image: out.image,
        info,
        gamma,
        interrupted: out.interrupted.is_some(),
        strategies: strategies.filter(|s| !s.is_empty()),
        mmlt,
        spans: trace.spans,
        aux: out.aux,
    })
}

/// Stops every render under way after its dispatch in flight, as Ctrl-C does (from any
/// thread); each returns the image of the samples it has done, marked interrupted.
#[pyfunction]
fn interrupt() {
    for w in running().lock().unwrap_or_else(|e| e.into_inner()).iter() {
        if let Some(flag) = w.upgrade() {
            flag.store(SIGINT, Ordering::SeqCst);
        }
    }
}

/// The Vulkan devices: a list of dicts with index, name, kind, driver, api_version, ray
/// query and float-atomic support, limits, and which one `render` picks by default.
#[pyfunction]
fn devices(py: Python<'_>) -> PyResult<Bound<'_, PyList>> {
    let list_err = |e: lightpath::gpu::GpuError| RenderError::new_err(e.to_string());
    let instance = lightpath::gpu::Instance::new().map_err(list_err)?;
    let found = instance.devices().map_err(list_err)?;
    let best = if found.is_empty() {
        None
    } else {
        Some(lightpath::gpu::choose_device(&found, None).map_err(list_err)?)
    };
    let list = PyList::empty(py);
    for (i, (_, d)) in found.iter().enumerate() {
        let e = PyDict::new(py);
        e.set_item("index", i)?;
        e.set_item("name", &d.name)?;
        e.set_item("kind", d.kind_name())?;
        e.set_item("driver", &d.driver)?;
        e.set_item(
            "api_version",
            format!(
                "{}.{}.{}",
                ash_major(d.api_version),
                ash_minor(d.api_version),
                d.api_version & 0xfff
            ),
        )?;
        e.set_item("ray_query", d.ray_query)?;
        e.set_item("float_atomics", d.atomic_float)?;
        e.set_item("max_storage_buffer_range", d.max_storage_buffer_range)?;
        e.set_item("max_workgroup_invocations", d.max_workgroup_invocations)?;
        e.set_item("timestamps", d.timestamps)?;
        e.set_item("default", Some(i) == best)?;
        list.append(e)?;
    }
    Ok(list)
}

// (VK_API_VERSION_MAJOR/MINOR, without a dependency on ash here.)
fn ash_major(v: u32) -> u32 {
    (v >> 22) & 0x7f
}
fn ash_minor(v: u32) -> u32 {
    (v >> 12) & 0x3ff
}

/// An image argument: a RenderResult, an H x W x 3 float32 array, or an EXR's path.
fn image_arg(obj: &Bound<'_, PyAny>) -> PyResult<(Image, Option<RenderInfo>)> {
    if let Ok(r) = obj.downcast::<RenderResult>() {
        let r = r.borrow();
        return Ok((r.image.clone(), Some(r.info.clone())));
    }
    if let Ok(a) = obj.extract::<PyReadonlyArray3<'_, f32>>() {
        return Ok((numpy_to_image(a)?, None));
    }
    if let Ok(p) = obj.extract::<PathBuf>() {
        return io::read_exr_with_info(&p).map_err(|e| PyValueError::new_err(format!("{e:#}")));
    }
    Err(PyTypeError::new_err(
        "expected a RenderResult, a float32 array of shape (H, W, 3) or an EXR path",
    ))
}

/// Compares image a against reference b, as `lightpath compare`: a dict with mean_a,
/// mean_b (per channel), rmse and relmse (ε = 0.01). a and b: RenderResults, float32
/// arrays of shape (H, W, 3) or EXR paths.
#[pyfunction]
fn compare<'py>(
    py: Python<'py>,
    a: &Bound<'py, PyAny>,
    b: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyDict>> {
    let (ia, _) = image_arg(a)?;
    let (ib, _) = image_arg(b)?;
    let c = io::compare(&ia, &ib).map_err(|e| PyValueError::new_err(format!("{e:#}")))?;
    let d = PyDict::new(py);
    d.set_item("mean_a", c.mean_a.to_vec())?;
    d.set_item("mean_b", c.mean_b.to_vec())?;
    d.set_item("rmse", c.rmse)?;
    d.set_item("relmse", c.relmse)?;
    Ok(d)
}

/// Averages renders of the same scene and settings made with different seeds, weighted
/// by their samples per pixel, as `lightpath merge` (and refuses what it refuses).
/// Takes RenderResults or EXR paths; returns a RenderResult.
#[pyfunction]
fn merge(renders: &Bound<'_, PyList>) -> PyResult<RenderResult> {
    let mut inputs = Vec::new();
    for (i, r) in renders.iter().enumerate() {
        let (image, info) = image_arg(&r)?;
        let name = match r.extract::<PathBuf>() {
            Ok(p) => p,
            Err(_) => PathBuf::from(format!("render {}", i + 1)),
        };
        inputs.push((name, image, info));
    }
    if inputs.len() < 2 {
        return Err(PyValueError::new_err("merge needs at least two renders"));
    }
    let (image, info) = io::merge(&inputs).map_err(|e| PyValueError::new_err(format!("{e:#}")))?;
    Ok(RenderResult {
        image,
        info,
        gamma: 1.0,
        interrupted: false,
        strategies: None,
        mmlt: None,
        spans: Vec::new(),
        aux: Vec::new(),
    })
}

/// Reads an EXR (with its lightpath metadata, when it has some) as a RenderResult.
#[pyfunction]
fn read(path: PathBuf) -> PyResult<RenderResult> {
    let (image, info) =
        io::read_exr_with_info(&path).map_err(|e| PyValueError::new_err(format!("{e:#}")))?;
    Ok(RenderResult {
        image,
        info: info.unwrap_or_default(),
        gamma: 1.0,
        interrupted: false,
        strategies: None,
        mmlt: None,
        spans: Vec::new(),
        aux: Vec::new(),
    })
}

#[pymodule]
fn _lightpath(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Scene>()?;
    m.add_class::<RenderResult>()?;
    m.add("SceneError", m.py().get_type::<SceneError>())?;
    m.add("RenderError", m.py().get_type::<RenderError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_function(wrap_pyfunction!(load, m)?)?;
    m.add_function(wrap_pyfunction!(render, m)?)?;
    m.add_function(wrap_pyfunction!(interrupt, m)?)?;
    m.add_function(wrap_pyfunction!(devices, m)?)?;
    m.add_function(wrap_pyfunction!(compare, m)?)?;
    m.add_function(wrap_pyfunction!(merge, m)?)?;
    m.add_function(wrap_pyfunction!(read, m)?)?;
    Ok(())
}

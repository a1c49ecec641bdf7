//! tessera from Python: the `tessera._native` extension module, a thin layer over the tessera
//! library. It loads a scene (a file, TOML text or a dict given as JSON), renders it with the
//! interpreter's lock released, calls back after each progressive pass, stops on Ctrl-C, and
//! turns every error into a Python exception. The package's Python half (`tessera/`) gives
//! the arrays and the documented signatures; nothing here decides what an image is.

use pyo3::exceptions::{PyException, PyFileNotFoundError, PyKeyboardInterrupt, PyOSError};
use pyo3::exceptions::{PyMemoryError, PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyBytes, PyDict};
use std::panic::AssertUnwindSafe;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, RecvTimeoutError};
use std::time::Duration;
use tessera::film::Film;
use tessera::image_file::Format;
use tessera::job::{Job, JobState};
use tessera::recipe::{self, Recipe, Source};
use tessera::record::workload::Workload;
use tessera::record::{db, measure};
use tessera::render::{
    Control, DEFAULT_TILE, Progress, RenderOptions, RenderStats, Watch, render_job,
};
use tessera::scene::{Overrides, Scene, TextureSource};
use tessera::verify;

mod sigint;

pyo3::create_exception!(
    _native,
    TesseraError,
    PyException,
    "An error of tessera's: a file it cannot use, parts that do not merge, a database it cannot open."
);
pyo3::create_exception!(
    _native,
    SceneError,
    TesseraError,
    "A scene that tessera cannot render: its `file`, `line`, `column` and `field` (None where the \
     error is not at one value) say where, as the command line's message does."
);

/// A message as the command line prints it: what a stranger wrote that it quotes (a scene's
/// key, a recipe, a database's path) with its control, bidirectional and other unsafe
/// characters, line ends too, as `\u{…}` escapes, since Python prints an exception's text
/// to the terminal as it is; and of at most `text::MAX_MESSAGE_CHARS` characters, its start
/// and end kept, whatever the length of what it quotes.
fn safe(message: &str) -> String {
    tessera::text::message_safe(message)
}

/// A tessera error as the Python exception a user expects, with the command line's message.
fn to_py(py: Python<'_>, e: tessera::Error) -> PyErr {
    use tessera::Error;
    let message = safe(&e.to_string());
    match e {
        Error::SceneSyntax { path, at, .. } => scene_error(py, message, &path, at, None),
        Error::SceneValue {
            path, at, field, ..
        } => scene_error(py, message, &path, at, Some(field)),
        Error::Setting { .. } => PyValueError::new_err(message),
        Error::Io { cause, .. } if cause.kind() == std::io::ErrorKind::NotFound => {
            PyFileNotFoundError::new_err(message)
        }
        Error::Io { .. } => PyOSError::new_err(message),
        Error::Image { .. } | Error::Merge(_) | Error::Partial { .. } => {
            TesseraError::new_err(message)
        }
    }
}

/// A `SceneError` carrying where it is as attributes.
fn scene_error(
    py: Python<'_>,
    message: String,
    path: &Path,
    at: tessera::error::Location,
    field: Option<String>,
) -> PyErr {
    let err = SceneError::new_err(message);
    let value = err.value(py);
    let _ = value.setattr("file", path.display().to_string());
    let _ = value.setattr("line", at.line);
    let _ = value.setattr("column", at.column);
    let _ = value.setattr("field", field);
    err
}

/// The scene to render, as the Python side hands it over.
enum SceneInput {
    /// A scene file's path.
    File(PathBuf),
    /// A scene file's text.
    Toml(String),
    /// A dict with the scene file's keys, as JSON.
    Json(String),
}

/// The name a scene given as text goes by, in errors and in the recipe.
const TEXT_ORIGIN: &str = "<string>";
const DICT_ORIGIN: &str = "<dict>";

impl SceneInput {
    /// The scene parsed with `overrides`, and the source its recipe records.
    fn load(&self, overrides: Overrides) -> tessera::Result<(Scene, Source)> {
        let (origin, text) = match self {
            SceneInput::File(path) => {
                let text = Scene::read_text(path)?;
                let scene = Scene::parse(&text, path, &overrides)?;
                return Ok((scene, Source::new(path, &text, overrides)));
            }
            SceneInput::Toml(text) => (Path::new(TEXT_ORIGIN), text.clone()),
            SceneInput::Json(json) => (Path::new(DICT_ORIGIN), toml_of_json(json)?),
        };
        // Image textures of a scene without a file: beside the working directory, then in
        // its `scenes/`, as `reproduce` looks for them.
        let dirs = recipe::texture_dirs(None, Path::new("here"));
        let scene = Scene::parse_with(&text, origin, &overrides, &TextureSource::Dirs(dirs))?;
        Ok((scene, Source::new(origin, &text, overrides)))
    }
}

/// The most bytes the TOML of a dict may take: a scene file's (`MAX_SCENE_BYTES`).
const MAX_TOML_BYTES: u64 = tessera::scene::MAX_SCENE_BYTES;

/// The TOML of a dict's keys, bounded: written out, a table's header (`[a.b]`, `[[a.b]]` for
/// each table of an array) repeats every key above it, so a dict of a few MB whose long key
/// holds an array of 10,000 empty tables once wrote 10 GB of TOML (9.7 GB of memory,
/// 86 s) before any bound looked at it, and a float is written without an exponent (a
/// million of 5e-324 took 330 MB). What it would take is summed first, generously (a key
/// or string each character escaped as TOML may), and a dict over a scene file's 64 MiB is
/// refused unwritten.
fn toml_size(value: &toml::Value, path: u64) -> u64 {
    use toml::Value;
    match value {
        Value::String(s) => quoted_size(s),
        // A float is written out in full, without an exponent: 5e-324 takes 326 bytes.
        Value::Float(f) => f.to_string().len() as u64 + 2,
        Value::Integer(_) | Value::Boolean(_) => 24,
        Value::Datetime(_) => 40,
        Value::Array(items) => items.iter().fold(2u64, |n, item| {
            n.saturating_add(toml_size(item, path)).saturating_add(2)
        }),
        Value::Table(table) => table.iter().fold(path.saturating_add(6), |n, (key, item)| {
            let key = quoted_size(key);
            let below = path.saturating_add(key).saturating_add(1);
            n.saturating_add(key.saturating_add(4))
                .saturating_add(toml_size(item, below))
        }),
    }
}

/// The most bytes `s` takes as a TOML key or string: quoted, each character escaped as it
/// may be.
fn quoted_size(s: &str) -> u64 {
    let escaped = s.chars().map(|c| match c {
        '"' | '\\' => 2,
        c if c.is_control() => 6,
        c => c.len_utf8() as u64,
    });
    2 + escaped.sum::<u64>()
}

/// The TOML text of a scene given as a dict (already JSON): the same dict, the same text.
fn toml_of_json(json: &str) -> tessera::Result<String> {
    let setting = |message: String| tessera::Error::Setting {
        field: "scene".into(),
        message,
    };
    let value: toml::Value = serde_json::from_str(json)
        .map_err(|e| setting(format!("a dict of the scene file's keys is expected ({e})")))?;
    if !value.is_table() {
        return Err(setting(
            "a dict of the scene file's keys is expected".into(),
        ));
    }
    let size = toml_size(&value, 0);
    if size > MAX_TOML_BYTES {
        return Err(setting(format!(
            "written as TOML (each table's header repeats every key above it, each float is \
             written in full) it would take up to {size} bytes, more than the {} MiB a scene \
             file may",
            MAX_TOML_BYTES >> 20
        )));
    }
    toml::to_string(&value).map_err(|e| setting(format!("cannot be written as TOML ({e})")))
}

/// A rendered image: its exact sums, how it is shown, and the recipe it is saved with.
#[pyclass(frozen, module = "tessera._native")]
struct NativeImage {
    film: Film,
    gamma: f32,
    recipe: Recipe,
    stats: Option<RenderStats>,
    simd: &'static str,
}

impl NativeImage {
    fn encode(&self, format: Format, recipe: Option<&Recipe>) -> std::io::Result<Vec<u8>> {
        let mut bytes = Vec::new();
        self.film.write(format, self.gamma, recipe, &mut bytes)?;
        Ok(bytes)
    }

    /// The recipe a file of `format` carries: none in a PPM, and none, with a warning, where
    /// it is too long for any reader to take (a scene file over about 1 MiB), as `tessera
    /// render` leaves it out.
    fn carried(&self, py: Python<'_>, format: Format) -> PyResult<Option<&Recipe>> {
        if format == Format::Ppm {
            return Ok(None);
        }
        let Some(why) = py.detach(|| self.recipe.why_not_carried()) else {
            return Ok(Some(&self.recipe));
        };
        let message = std::ffi::CString::new(format!("{why}, so the image carries none"))
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        let category = py.get_type::<pyo3::exceptions::PyUserWarning>();
        // 2: the warning names the caller's line, not the package's `save`.
        PyErr::warn(py, category.as_any(), &message, 2)?;
        Ok(None)
    }
}

#[pymethods]
impl NativeImage {
    #[getter]
    fn width(&self) -> u32 {
        self.film.width
    }
    #[getter]
    fn height(&self) -> u32 {
        self.film.height
    }
    #[getter]
    fn samples_per_pixel(&self) -> u32 {
        self.film.samples_per_pixel
    }
    #[getter]
    fn max_depth(&self) -> u32 {
        self.recipe.image.max_depth
    }
    #[getter]
    fn seed(&self) -> u64 {
        self.recipe.image.seed
    }
    #[getter]
    fn gamma(&self) -> f32 {
        self.gamma
    }
    /// XXH3-128 of the exact sums, as recipes and benchmark results write it.
    #[getter]
    fn sums(&self, py: Python<'_>) -> String {
        py.detach(|| recipe::sums_hash(&self.film))
    }
    #[getter]
    fn mean_radiance(&self, py: Python<'_>) -> f64 {
        py.detach(|| self.film.mean_radiance())
    }
    /// The recipe the image is saved with, as JSON, written with the interpreter's lock
    /// released: it holds the scene's text, up to a scene file's 64 MiB, and of a 60 MB one
    /// once held up every other thread for 0.5 s.
    #[getter]
    fn recipe(&self, py: Python<'_>) -> String {
        py.detach(|| self.recipe.to_json())
    }

    /// The means of the exact sums, linear, as native-endian float32, row by row. Worked out
    /// and written with the interpreter's lock released, as the sRGB pixels and the sums'
    /// hash are: of a 6000x4000 image, each once held up every other thread for 0.2 to 0.8 s.
    fn linear_bytes<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyBytes>> {
        let linear = py.detach(|| self.film.linear());
        bytes_written(py, linear.len() * 4, |buf| {
            for (out, v) in buf.chunks_exact_mut(4).zip(&linear) {
                out.copy_from_slice(&v.to_ne_bytes());
            }
        })
    }

    /// The 8-bit sRGB pixels a PNG of the image holds, row by row.
    fn srgb8_bytes<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyBytes>> {
        let rgb8 = py.detach(|| self.film.to_rgb8(self.gamma));
        bytes_written(py, rgb8.len(), |buf| buf.copy_from_slice(&rgb8))
    }

    /// The image file of `format` ("png", "exr" or "ppm"), recipe included where the format
    /// has metadata: the bytes `save` writes.
    fn encode_as<'py>(&self, py: Python<'py>, format: &str) -> PyResult<Bound<'py, PyBytes>> {
        let format = match format {
            "png" => Format::Png,
            "exr" => Format::Exr,
            "ppm" => Format::Ppm,
            other => {
                return Err(PyValueError::new_err(safe(&format!(
                    "format must be png, exr or ppm, not {other:?}"
                ))));
            }
        };
        let recipe = self.carried(py, format)?;
        let bytes = py
            .detach(|| self.encode(format, recipe))
            .map_err(|e| TesseraError::new_err(format!("could not encode the image: {e}")))?;
        Ok(PyBytes::new(py, &bytes))
    }

    /// Writes the image to `path` (its format from the extension), whole or not at all: the
    /// file `tessera render` writes for the same scene and settings.
    fn save(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        let format = Format::from_path(&path).map_err(|e| to_py(py, e))?;
        let recipe = self.carried(py, format)?;
        // Held open until the image is written, so that the reader it waited for is there
        // when the save opens the pipe again.
        let _reader_there = reader_of_pipe(py, &path)?;
        py.detach(|| self.film.save(&path, self.gamma, recipe))
            .map_err(|e| to_py(py, e))
    }

    /// Counts and timing of the render, or None for a pass's image.
    fn stats<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let Some(s) = self.stats else {
            return Ok(None);
        };
        let d = PyDict::new(py);
        d.set_item("samples", s.samples)?;
        d.set_item("rays", s.rays)?;
        d.set_item("seconds", s.wall.as_secs_f64())?;
        d.set_item("threads", s.threads)?;
        d.set_item("simd", self.simd)?;
        d.set_item("samples_per_second", s.samples_per_sec())?;
        d.set_item("rays_per_sample", s.rays_per_sample())?;
        Ok(Some(d))
    }
}

/// Where `path` is a pipe (FIFO) of this user's (or root's), which a save writes in place:
/// waits for a reader, running Python's signal handlers every `SIGNAL_LOOK`, and returns a
/// write end of it, open. A save's own open of a pipe with no reader waits in the kernel,
/// where no Ctrl-C reaches: `Image.save` of one hung until killed. Another user's pipe is
/// left alone (the save refuses it), as is anything else.
fn reader_of_pipe(py: Python<'_>, path: &Path) -> PyResult<Option<std::fs::File>> {
    use std::os::unix::fs::{FileTypeExt, MetadataExt, OpenOptionsExt};
    let Ok(meta) = std::fs::metadata(path) else {
        return Ok(None);
    };
    if !meta.file_type().is_fifo() || tessera::owner::is_another_users(meta.uid(), &[]) {
        return Ok(None);
    }
    loop {
        let opened = std::fs::OpenOptions::new()
            .write(true)
            .custom_flags(libc::O_NONBLOCK)
            .open(path);
        match opened {
            Ok(file) => return Ok(Some(file)),
            // No reader yet.
            Err(e) if e.raw_os_error() == Some(libc::ENXIO) => {
                py.detach(|| std::thread::sleep(SIGNAL_LOOK));
                py.check_signals()?;
            }
            // The save says what is wrong, in its words.
            Err(_) => return Ok(None),
        }
    }
}

/// Python bytes of `len` bytes, written by `fill` with the interpreter's lock released: they
/// are no one else's until returned. (`PyBytes::new_with` zeroes them with the lock held,
/// which touches every page: 0.46 s of a 6000x4000 image's linear pixels.)
fn bytes_written<'py>(
    py: Python<'py>,
    len: usize,
    fill: impl FnOnce(&mut [u8]) + Send,
) -> PyResult<Bound<'py, PyBytes>> {
    let size = pyo3::ffi::Py_ssize_t::try_from(len)
        .map_err(|_| PyMemoryError::new_err(format!("{len} bytes are more than Python holds")))?;
    // SAFETY: as in `PyBytes::new_with`: a new bytes object of `len` bytes, which only this
    // function holds until it returns, its buffer zeroed before `fill` sees it.
    unsafe {
        let ptr = pyo3::ffi::PyBytes_FromStringAndSize(std::ptr::null(), size);
        let bytes = Bound::from_owned_ptr_or_err(py, ptr)?.cast_into_unchecked::<PyBytes>();
        // As a number, to cross to the thread without the lock.
        let buffer = pyo3::ffi::PyBytes_AsString(ptr).cast::<u8>() as usize;
        py.detach(move || {
            let buffer = buffer as *mut u8;
            std::ptr::write_bytes(buffer, 0, len);
            fill(std::slice::from_raw_parts_mut(buffer, len));
        });
        Ok(bytes)
    }
}

/// Hands the image of each progressive pass to `show` (which sends it to the caller's
/// thread, where `on_pass` is called), from the thread that folds finished tiles. A pass is
/// over when its last tile is folded: passes run one after another and a batch of tiles
/// never spans two, so the state then holds exactly the pass's samples in every pixel.
struct PassWatcher<'a> {
    show: &'a dyn Fn(NativeImage),
    scene: &'a Scene,
    source: &'a Source,
    simd: &'static str,
    passes_seen: usize,
    /// Set where a pass's image could not be had, which stops the render.
    stop: &'a AtomicBool,
    /// Why a pass's image could not be had: the memory for its copy of the sums.
    failed: Option<String>,
}

impl Watch for PassWatcher<'_> {
    fn started(&mut self, _: &JobState, _: &Progress) {}

    fn folded(&mut self, state: &JobState, _: &[usize], progress: &Progress) {
        if progress.pass <= self.passes_seen {
            return;
        }
        self.passes_seen = progress.pass;
        let spp = progress.passes[progress.pass - 1];
        let region = state.job.region;
        // Reserved, not assumed: the copy is as large as the render's own sums (6 GiB of a
        // 16384x16384 image), and a failed allocation ended the interpreter (abort).
        let mut sums = Vec::new();
        if let Err(e) = sums.try_reserve_exact(state.sums.len()) {
            self.failed = Some(format!(
                "the image of pass {} ({}x{} pixels) needs {} bytes for its copy of the \
                 sums, which this process could not have ({e})",
                progress.pass,
                region.width,
                region.height,
                std::mem::size_of_val(state.sums.as_slice())
            ));
            self.stop.store(true, Ordering::Relaxed);
            return;
        }
        sums.extend_from_slice(&state.sums);
        let film = Film {
            width: region.width,
            height: region.height,
            samples_per_pixel: spp,
            sums,
        };
        (self.show)(pass_image(film, self.scene, self.source, self.simd));
    }
}

/// The image of a pass of `spp` samples: its recipe says `spp`, so that `reproduce` makes
/// it again (a render of `spp` samples gives these very sums).
fn pass_image(film: Film, scene: &Scene, source: &Source, simd: &'static str) -> NativeImage {
    let mut source = source.clone();
    source.overrides.samples_per_pixel = Some(film.samples_per_pixel);
    let mut recipe = Recipe::new(&source, scene, &film);
    recipe.image.samples_per_pixel = film.samples_per_pixel;
    NativeImage {
        film,
        gamma: scene.settings.gamma,
        recipe,
        stats: None,
        simd,
    }
}

/// What went wrong on the rendering side, sorted out once the lock is taken again.
enum Failed {
    Tessera(tessera::Error),
    Pool(String),
    Interrupted,
    Panicked(String),
    /// What else stops the work, in words: a refusal of its cost.
    Other(String),
    /// Memory the work needs and could not have, in words: a `MemoryError`.
    Memory(String),
    /// The process was forked while the work ran, and this is the child, without its thread.
    Forked,
    /// The work was told to stop and had not ended `LOOKS_TO_STOP` looks later: it ends on
    /// its own thread, unwaited for, and what stopped it is raised.
    Unwaited,
}

/// Loads `scene` and renders it. `kind` says what `scene` is: "file" (a path), "toml" (a
/// scene file's text) or "json" (a dict of its keys, as JSON). The arguments are checked by
/// the Python side; `simd` is a path's name or "auto".
#[pyfunction]
#[pyo3(signature = (kind, scene, *, width=None, spp=None, depth=None, seed=None, threads=None,
    simd=None, on_pass=None))]
#[allow(clippy::too_many_arguments)]
fn render(
    py: Python<'_>,
    kind: &str,
    scene: &Bound<'_, PyAny>,
    width: Option<u32>,
    spp: Option<u32>,
    depth: Option<u32>,
    seed: Option<u64>,
    threads: Option<usize>,
    simd: Option<String>,
    on_pass: Option<Py<PyAny>>,
) -> PyResult<NativeImage> {
    let input = match kind {
        // A path's `str` as Python's file functions take it: a name that is not UTF-8 holds
        // surrogates for its bytes, which only a path (not a `String`) takes back.
        "file" => SceneInput::File(scene.extract()?),
        "toml" => SceneInput::Toml(scene.extract()?),
        "json" => SceneInput::Json(scene.extract()?),
        other => {
            return Err(PyValueError::new_err(safe(&format!(
                "unknown scene kind {other:?}"
            ))));
        }
    };
    let path = simd_path(simd.as_deref())?;
    let options = RenderOptions {
        threads: Some(threads_or_cpus(threads)),
        tile: DEFAULT_TILE,
        simd: path,
    };
    let overrides = Overrides {
        width,
        samples_per_pixel: spp,
        max_depth: depth,
        seed,
    };
    let watching = on_pass.is_some();
    interruptible(py, on_pass.as_ref(), move |stop, show| {
        let (scene, source) = input.load(overrides).map_err(Failed::Tessera)?;
        // Stopped while the scene was built (its raise not waited for): no pool is started.
        if stop.load(Ordering::Relaxed) {
            return Err(Failed::Interrupted);
        }
        let mut watcher = watching.then(|| PassWatcher {
            show,
            scene: &scene,
            source: &source,
            simd: path.name(),
            passes_seen: 0,
            stop,
            failed: None,
        });
        let watch = watcher.as_mut().map(|w| w as &mut dyn Watch);
        let rendered = render_whole(&scene, &options, stop, watch);
        if let Some(failed) = watcher.and_then(|w| w.failed) {
            return Err(Failed::Memory(failed));
        }
        let (film, stats) = rendered?;
        let recipe = Recipe::new(&source, &scene, &film);
        Ok(NativeImage {
            film,
            gamma: scene.settings.gamma,
            recipe,
            stats: Some(stats),
            simd: path.name(),
        })
    })
}

/// The worker threads of a render: `threads`, else one per CPU. A render always has a pool
/// of its own, never rayon's global one: a process forked after a render (`multiprocessing`'s
/// default on Linux) holds that pool's state without its threads, and a render there waited
/// for them forever.
fn threads_or_cpus(threads: Option<usize>) -> usize {
    threads.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()))
}

/// The SIMD path named `simd` (None: `auto`).
fn simd_path(simd: Option<&str>) -> PyResult<tessera::simd::Path> {
    tessera::simd::Path::choose(simd.unwrap_or("auto"))
        .map_err(|e| PyValueError::new_err(safe(&format!("simd: {e}"))))
}

/// Renders the whole of `scene` until it is complete or `stop` is set (then `Interrupted`),
/// in progressive passes when `watch` sees them.
fn render_whole<'a>(
    scene: &Scene,
    options: &RenderOptions,
    stop: &'a AtomicBool,
    watch: Option<&'a mut dyn Watch>,
) -> Result<(Film, RenderStats), Failed> {
    let job = Job::whole(scene);
    // Reserved, not assumed: a scene of 16384x16384 pixels claims 6 GiB of sums, and a
    // failed allocation ended the interpreter (abort, under a memory limit).
    let mut state = JobState::try_new(job, options.tile).map_err(Failed::Memory)?;
    let control = Control {
        stop,
        on_samples: &|_| {},
        on_progress: None,
        progressive: watch.is_some(),
        watch,
    };
    let stats =
        render_job(scene, options, &mut state, control).map_err(|e| Failed::Pool(e.to_string()))?;
    if !state.is_complete() {
        return Err(Failed::Interrupted);
    }
    Ok((state.into_film(), stats))
}

/// How often the caller's thread runs Python's signal handlers while `work` runs.
const SIGNAL_LOOK: Duration = Duration::from_millis(20);
/// The looks the caller's thread waits for `work` to end once it is told to stop, before it
/// raises without it: what no stop reaches (a scene's parsing and building, seconds of a
/// cloud of 2^20 spheres; a results database's reading; rays among a million spheres in
/// one place) goes on to its end on its own thread, and Ctrl-C was raised only then (9 s
/// after it, of such a cloud on a 2-core machine).
const LOOKS_TO_STOP: u32 = 4;
/// The stack of the thread `work` runs on.
const WORK_STACK: usize = 8 << 20;

/// What the thread running `work` tells the caller's.
enum Event<T> {
    /// A progressive pass's image, for `on_pass`.
    Pass(Box<NativeImage>),
    /// What `work` returned.
    Done(Result<T, Failed>),
}

/// Runs `work` on a thread of its own, and raises what it failed with. Meanwhile the
/// caller's thread, the interpreter's lock released but for a moment every 20 ms, runs
/// Python's signal handlers and calls `on_pass` with each image `work` hands to `show`;
/// what a handler raises (Ctrl-C's KeyboardInterrupt) or `on_pass` raises sets the flag
/// `work` is given, and is raised once `work` ends. So Ctrl-C does what Python's handler of
/// it says now: ignored (`SIG_IGN`), it stops nothing, and one installed after an earlier
/// render (as `asyncio.run` installs and restores one) still stops it; a flag set from
/// tessera's own handler, installed once and then replaced by such a handler, once left
/// every later render deaf to Ctrl-C. Off the main thread, where Python runs no handler, a
/// Ctrl-C that `sigint` counts sets the flag, unless Python's handler of it is not a
/// function; `sigint`'s handler is put in place at each look where it is, in the place of
/// one installed during the render (or of `SIG_IGN`, the render begun while it was Python's).
fn interruptible<T: Send + 'static>(
    py: Python<'_>,
    on_pass: Option<&Py<PyAny>>,
    work: impl FnOnce(&Arc<AtomicBool>, &dyn Fn(NativeImage)) -> Result<T, Failed> + Send + 'static,
) -> PyResult<T> {
    let stop = Arc::new(AtomicBool::new(false));
    let interrupts = if off_the_main_thread(py)? {
        Some(watch_sigint(py)?)
    } else {
        None
    };
    // Handed over, not queued: a pass's image (a copy of the sums, 120 MB at 3000x1688)
    // waits for the last to be taken, so that a slow `on_pass` holds up the render's next
    // image, not the memory of every pass.
    let (events, received) = mpsc::sync_channel::<Event<T>>(0);
    let flag = Arc::clone(&stop);
    // The stack of a main thread, as the command line parses a scene and builds its tree
    // on: a spawned thread's 2 MiB default is no bound a scene file is checked for. Not a
    // scoped thread: a process forked by `on_pass` or a signal handler holds none of it, and
    // the end of a scope waited for it there forever.
    let worker = std::thread::Builder::new()
        .name("tessera-render".into())
        .stack_size(WORK_STACK)
        .spawn(move || {
            let passes = events.clone();
            let show = move |image| drop(passes.send(Event::Pass(Box::new(image))));
            // A panic (a bug of tessera's) becomes an exception, caught as any other
            // TesseraError: it never ends the interpreter.
            let done = std::panic::catch_unwind(AssertUnwindSafe(|| work(&flag, &show)))
                .unwrap_or_else(|panic| Err(Failed::Panicked(panic_message(&panic))));
            drop(events.send(Event::Done(done)));
        });
    let (done, raised) = match worker {
        Ok(worker) => {
            let (done, raised) = watch_work(py, on_pass, &stop, interrupts, received);
            if matches!(done, Err(Failed::Forked | Failed::Unwaited)) {
                // The thread is the parent's: this process has nothing of it to wait for. Or
                // it is still at what no stop reaches: it ends there on its own, its result
                // dropped (its `Done` finds no one to take it), and holds nothing of Python's.
                std::mem::forget(worker);
            } else {
                // It has sent `Done` as its last word.
                py.detach(|| drop(worker.join()));
            }
            (done, raised)
        }
        Err(e) => (
            Err(Failed::Pool(format!("a thread to render on: {e}"))),
            None,
        ),
    };
    match raised {
        Some(e) => Err(e),
        None => done.map_err(|failed| failed.into_py(py)),
    }
}

/// The caller's side of `interruptible`: runs Python's signal handlers every `SIGNAL_LOOK`
/// and calls `on_pass` with each pass's image until the work is done; what is raised meanwhile
/// sets `stop` and is given back with what the work returned. In a process forked meanwhile
/// (by `on_pass` or a signal handler), where the work's thread is not, it ends at once with
/// `Forked`: it once waited there forever for an image or an end that never came.
fn watch_work<T>(
    py: Python<'_>,
    on_pass: Option<&Py<PyAny>>,
    stop: &AtomicBool,
    interrupts: Option<u64>,
    mut received: mpsc::Receiver<Event<T>>,
) -> (Result<T, Failed>, Option<PyErr>)
where
    T: Send,
{
    let pid = std::process::id();
    let mut raised: Option<PyErr> = None;
    // The looks since `stop` was set.
    let mut since_stop = 0u32;
    loop {
        let (event, back) = py.detach(move || (received.recv_timeout(SIGNAL_LOOK), received));
        received = back;
        let failed = match event {
            Ok(Event::Done(done)) => return (done, raised),
            Ok(Event::Pass(image)) => match on_pass.filter(|_| raised.is_none()) {
                Some(on_pass) => (Py::new(py, *image))
                    .and_then(|image| on_pass.call1(py, (image,)))
                    .err(),
                None => None,
            },
            Err(RecvTimeoutError::Timeout) => (py.check_signals())
                .and_then(|()| match interrupts {
                    Some(_) => watch_sigint(py).map(drop),
                    None => Ok(()),
                })
                .err(),
            // The thread sends `Done` whatever happens, as its last word.
            Err(RecvTimeoutError::Disconnected) => {
                let unheard = "the render's thread ended unheard".into();
                return (Err(Failed::Panicked(unheard)), raised);
            }
        };
        if let Some(e) = failed
            && raised.is_none()
        {
            raised = Some(e);
            stop.store(true, Ordering::Relaxed);
        }
        // Ctrl-C off the main thread: the render ends `Interrupted`.
        if interrupts.is_some_and(|before| sigint::seen() != before) {
            stop.store(true, Ordering::Relaxed);
        }
        if std::process::id() != pid {
            return (Err(Failed::Forked), None);
        }
        if stop.load(Ordering::Relaxed) {
            since_stop += 1;
            if since_stop > LOOKS_TO_STOP {
                return (Err(Failed::Unwaited), raised);
            }
        }
    }
}

/// Whether the caller is off the main thread, where Python runs no signal handler: there a
/// Ctrl-C that `sigint` counts sets a render's flag itself, while Python's handler of it is
/// a function (not `SIG_IGN` or `SIG_DFL`).
fn off_the_main_thread(py: Python<'_>) -> PyResult<bool> {
    let threading = py.import("threading")?;
    let current = threading.call_method0("current_thread")?;
    Ok(!current.is(&threading.call_method0("main_thread")?))
}

/// Whether Python's handler of Ctrl-C is a function. Asked at every look of a render off
/// the main thread: `signal.getsignal` is kept from the first, so a look imports nothing.
fn python_handles_sigint(py: Python<'_>) -> PyResult<bool> {
    static GETSIGNAL: PyOnceLock<Py<PyAny>> = PyOnceLock::new();
    let handler = GETSIGNAL
        .import(py, "signal", "getsignal")?
        .call1((libc::SIGINT,))?;
    Ok(handler.is_callable())
}

/// Puts `sigint`'s handler in place, where Python's handler of Ctrl-C is a function, and
/// says how many Ctrl-Cs it has seen. Called as a render off the main thread begins and at
/// each look: `signal.signal` on the main thread (which `asyncio.run` calls) puts Python's
/// own in its place, and a render on a thread then went on to its end after Ctrl-C (still
/// running 60 s later); so did one begun while Python ignored Ctrl-C, once a handler was
/// installed during it.
fn watch_sigint(py: Python<'_>) -> PyResult<u64> {
    if !python_handles_sigint(py)? {
        return Ok(sigint::seen());
    }
    sigint::watch().map_err(|e| PyRuntimeError::new_err(format!("could not watch for Ctrl-C: {e}")))
}

/// What a caught panic said.
fn panic_message(panic: &Box<dyn std::any::Any + Send>) -> String {
    (panic.downcast_ref::<&str>().map(|s| s.to_string()))
        .or_else(|| panic.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "a panic".into())
}

impl Failed {
    fn into_py(self, py: Python<'_>) -> PyErr {
        match self {
            Failed::Tessera(e) => to_py(py, e),
            Failed::Pool(e) => {
                TesseraError::new_err(format!("could not start the thread pool: {e}"))
            }
            Failed::Other(message) => TesseraError::new_err(safe(&message)),
            Failed::Memory(message) => PyMemoryError::new_err(safe(&message)),
            Failed::Forked => TesseraError::new_err(
                "this process was forked during the render (by on_pass or a signal handler): \
                 the render goes on in the parent, and the child holds none of its threads; \
                 render again in the child",
            ),
            Failed::Panicked(message) => TesseraError::new_err(safe(&format!(
                "internal error (a bug of tessera's; please report it): {message}"
            ))),
            // Ctrl-C off the main thread (the main thread's handler raises there too); or
            // the work, so stopped, unwaited for.
            Failed::Interrupted | Failed::Unwaited => py
                .check_signals()
                .err()
                .unwrap_or_else(|| PyKeyboardInterrupt::new_err("the render was interrupted")),
        }
    }
}

/// The SIMD paths this CPU runs, slowest first, and the one `auto` takes.
#[pyfunction]
fn simd_paths() -> (Vec<&'static str>, &'static str) {
    let supported = tessera::simd::Path::supported();
    (
        supported.iter().map(|p| p.name()).collect(),
        tessera::simd::Path::best().name(),
    )
}

/// The build of tessera inside this module (version, commit, rustc, target, profile, SIMD
/// paths), as JSON of a benchmark result's `build`.
#[pyfunction]
fn build() -> String {
    let build = tessera::record::host::Build::this(tessera::simd::Path::best(), false);
    serde_json::to_string(&build).unwrap_or_default()
}

/// Reads the recipe of the image at `image`, renders it again and says whether the image is
/// bit for bit what it makes: a dict of the verdict ("identical" or "differs"), its summary
/// and details, the recipe's sums and the work it asked for. A recipe asking for more than
/// four book covers' work (as it claims, and again at what its paths cost, a few traced),
/// or more than 8192x4096 pixels, is refused unless `any_cost`.
#[pyfunction]
#[pyo3(signature = (image, *, threads=None, simd=None, textures=None, any_cost=false))]
fn reproduce<'py>(
    py: Python<'py>,
    image: PathBuf,
    threads: Option<usize>,
    simd: Option<String>,
    textures: Option<PathBuf>,
    any_cost: bool,
) -> PyResult<Bound<'py, PyDict>> {
    let path = simd_path(simd.as_deref())?;
    let options = RenderOptions {
        threads: Some(threads_or_cpus(threads)),
        tile: DEFAULT_TILE,
        simd: path,
    };
    let (header, recipe) = py
        .detach(|| verify::read_recipe(&image))
        .map_err(|e| to_py(py, e))?;
    let work = verify::Work::of(&recipe);
    if let Some(refusal) = work.refusal(&image, "any_cost=True")
        && !any_cost
    {
        return Err(TesseraError::new_err(safe(&refusal)));
    }
    let d = PyDict::new(py);
    d.set_item("image", image.display().to_string())?;
    d.set_item("sums", &recipe.sums)?;
    let dirs = recipe::texture_dirs(textures.as_deref(), &image);
    let worker_image = image.clone();
    // On the worker's stack, as a scene is parsed: the recipe's scene and settings, then the
    // image against the recipe, in the order and by the function the command line's
    // `reproduce` and `info` take.
    let (differs, work) = interruptible(py, None, move |stop, _| {
        let image = worker_image;
        let checked = match verify::unrendered(&image, &header, &recipe).map_err(Failed::Tessera)? {
            verify::Unrendered::Differs(differs) => return Ok((Some(differs), work)),
            verify::Unrendered::Render(checked) => checked,
        };
        let mut scene = checked.scene(&dirs).map_err(Failed::Tessera)?;
        let yardstick = Workload::named("quick").map_err(|e| Failed::Other(format!("{e:#}")))?;
        let judged = verify::render_judged(
            work,
            &mut scene,
            &yardstick.scene,
            &image,
            "any_cost=True",
            any_cost,
            options.threads,
            stop,
            |_| {},
            |scene| render_whole(scene, &options, stop, None),
        )
        .map_err(|not| match not {
            verify::NotStarted::Refused(refusal) => Failed::Other(refusal),
            verify::NotStarted::Setting(e) => Failed::Tessera(e),
        })?;
        let (film, _) = judged.done.map_err(|failed| match failed {
            Failed::Interrupted if judged.over_budget.is_some() => {
                Failed::Other(judged.over_budget.clone().unwrap_or_default())
            }
            failed => failed,
        })?;
        let work = judged.work;
        let g = scene.settings.gamma;
        let differs = verify::differs_rendered(&image, &header, &recipe, &film, g)
            .map_err(Failed::Tessera)?;
        Ok((differs, work))
    })?;
    d.set_item("work", work.to_string())?;
    match differs {
        None => {
            d.set_item("verdict", "identical")?;
            d.set_item(
                "summary",
                format!(
                    "{} is bit for bit what its recipe makes",
                    tessera::text::path_safe(&image)
                ),
            )?;
            d.set_item("details", Vec::<String>::new())?;
        }
        Some(differs) => {
            d.set_item("verdict", "differs")?;
            d.set_item("summary", differs.summary)?;
            d.set_item("details", differs.details)?;
        }
    }
    Ok(d)
}

/// Measures `workload` ("quick", "cover", "cornell", "next-week") as `tessera bench` does,
/// without recording it, and returns the result as JSON of the `tessera-bench` schema;
/// Ctrl-C stops it (KeyboardInterrupt).
#[pyfunction(name = "bench")]
#[pyo3(signature = (workload, *, threads=None, scaling=false, repeat=3, warmup=1, simd=None))]
fn bench_workload(
    py: Python<'_>,
    workload: &str,
    threads: Option<usize>,
    scaling: bool,
    repeat: u32,
    warmup: u32,
    simd: Option<String>,
) -> PyResult<String> {
    let chosen = simd.as_deref().is_some_and(|s| s != "auto");
    let path = simd_path(simd.as_deref())?;
    let workload = Workload::named(workload)
        .map_err(|e| PyValueError::new_err(safe(&format!("workload: {e:#}"))))?;
    let cpus = threads_or_cpus(None);
    let plan = measure::Plan {
        workload,
        threads: threads_or_cpus(threads),
        scaling: if scaling {
            measure::scaling_counts(cpus)
        } else {
            Vec::new()
        },
        repeat,
        warmup,
        simd: path,
        simd_chosen: chosen,
    };
    // Ctrl-C stops it as it stops any render: each of its renders looks between rays.
    let result = interruptible(py, None, move |stop, _| {
        match measure::measure_unless(&plan, stop) {
            Ok(Some(result)) => Ok(result),
            Ok(None) => Err(Failed::Interrupted),
            Err(e) => Err(Failed::Pool(e.to_string())),
        }
    })?;
    serde_json::to_string(&result)
        .map_err(|e| TesseraError::new_err(format!("could not write the result: {e}")))
}

/// The runs the results database at `db` (None: the default one) holds, newest first, as
/// `tessera results list` shows them, each with its whole result as JSON under "result".
#[pyfunction]
#[pyo3(signature = (db=None, *, workload=None, machine=None, commit=None, limit=None))]
fn results<'py>(
    py: Python<'py>,
    db: Option<PathBuf>,
    workload: Option<String>,
    machine: Option<String>,
    commit: Option<String>,
    limit: Option<u32>,
) -> PyResult<Vec<Bound<'py, PyDict>>> {
    let filter = db::Filter {
        workload,
        machine,
        commit,
        limit,
    };
    // Read on a thread of its own, as a render is, so that Ctrl-C stops it: a wait for
    // another process's lock (a colleague's database held locked, 30 s for each of two
    // statements) ends at the next look, and the reading of a large one between runs.
    let runs = interruptible(py, None, move |stop, _| {
        let read = || -> anyhow::Result<Option<Vec<_>>> {
            let path = db::resolve(db)?;
            let db = db::ResultsDb::open_to_read(&path)?;
            // The results in the read that checked their runs' columns against them: read
            // after it, a result another process wrote meanwhile could go with a run
            // checked against another.
            db.as_one_read(|db| {
                let mut with_results = Vec::new();
                for run in db.runs(&filter)? {
                    if stop.load(Ordering::Relaxed) {
                        return Ok(None);
                    }
                    let json = db.result_json(run.id)?;
                    with_results.push((run, json));
                }
                Ok(Some(with_results))
            })
        };
        match db::stopped_by(Arc::clone(stop), read) {
            Ok(Some(runs)) => Ok(runs),
            // What a stop cut short (a wait given up as busy, say) is the stop's.
            Ok(None) => Err(Failed::Interrupted),
            Err(_) if stop.load(Ordering::Relaxed) => Err(Failed::Interrupted),
            Err(e) => Err(Failed::Other(format!("{e:#}"))),
        }
    })?;
    let mut out = Vec::with_capacity(runs.len());
    for (run, json) in runs {
        let d = PyDict::new(py);
        d.set_item("id", run.id)?;
        d.set_item("started_unix_s", run.started_unix_s)?;
        d.set_item("machine_id", run.machine_id)?;
        d.set_item("cpu_model", run.cpu_model)?;
        d.set_item("logical_cpus", run.logical_cpus)?;
        d.set_item("version", run.version)?;
        d.set_item("commit", run.commit)?;
        d.set_item("simd", run.simd)?;
        d.set_item("workload", run.workload)?;
        d.set_item("workload_id", run.workload_id)?;
        d.set_item("threads", run.threads)?;
        d.set_item("samples_per_second", run.sps[0])?;
        d.set_item("samples_per_second_min", run.sps[1])?;
        d.set_item("samples_per_second_max", run.sps[2])?;
        d.set_item("validation", run.validation)?;
        d.set_item("busy", run.busy)?;
        d.set_item("result", json)?;
        out.push(d);
    }
    Ok(out)
}

/// Panics in Rust where a render would, for the tests that check a panic becomes an
/// exception.
#[pyfunction]
fn _panic_for_tests(py: Python<'_>) -> PyResult<()> {
    interruptible(py, None, |_, _| -> Result<(), Failed> {
        panic!("a panic on purpose, from tessera._native._panic_for_tests")
    })
}

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("TesseraError", m.py().get_type::<TesseraError>())?;
    m.add("SceneError", m.py().get_type::<SceneError>())?;
    m.add_class::<NativeImage>()?;
    m.add_function(wrap_pyfunction!(render, m)?)?;
    m.add_function(wrap_pyfunction!(simd_paths, m)?)?;
    m.add_function(wrap_pyfunction!(build, m)?)?;
    m.add_function(wrap_pyfunction!(reproduce, m)?)?;
    m.add_function(wrap_pyfunction!(bench_workload, m)?)?;
    m.add_function(wrap_pyfunction!(results, m)?)?;
    m.add_function(wrap_pyfunction!(_panic_for_tests, m)?)?;
    Ok(())
}

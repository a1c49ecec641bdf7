//! Hostile input in bulk: thousands of generated and mutated scene files, partial files and
//! command lines. Nothing may panic, abort or hang, nothing may allocate what an input merely
//! claims, and every refusal names where it comes from (the binary's exit 2 with a message).
//!
//! Every case is generated from its own fixed seed, so a run is reproducible; a failing case
//! is printed with its name and input, and `TESSERA_FUZZ_CASE=scene:123` (or `part:…`,
//! `cli:…`) replays that one case alone. `TESSERA_FUZZ_SCALE=10` runs ten times as many.

mod common;

use common::*;
use rand_core::Rng as _;
use rand_pcg::Pcg32;
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::io::Write;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};
use tessera::partial::Part;
use tessera::render::{self, Job, Progress, RenderOptions, SampleRange};
use tessera::scene::{Overrides, Scene};
use tessera::shard::{self, Shard};

// ---------------------------------------------------------------------------------------
// An allocation ceiling, per thread, while a case runs.

/// The system allocator, refusing on the threads that armed it any single allocation above
/// their ceiling. A refusal aborts the test binary (Rust's answer to a failed allocation),
/// after naming the case: an input made tessera believe a size it had not checked.
struct Ceiling;

thread_local! {
    static CEILING: Cell<usize> = const { Cell::new(usize::MAX) };
    /// The case this thread runs: its family and index.
    static CASE: Cell<(&'static str, u64)> = const { Cell::new(("", 0)) };
}

fn allowed(size: usize) -> bool {
    let ceiling = CEILING.try_with(Cell::get).unwrap_or(usize::MAX);
    if size <= ceiling {
        return true;
    }
    let (family, index) = CASE.try_with(Cell::get).unwrap_or(("?", 0));
    let _ = writeln!(
        std::io::stderr(),
        "fuzz: case {family}:{index} asked for {size} bytes at once, above its ceiling of \
         {ceiling}: it believed a size it had not checked. Replay it with \
         TESSERA_FUZZ_CASE={family}:{index}"
    );
    false
}

// SAFETY: every call is passed on unchanged to `System`, or refused with a null pointer,
// which `GlobalAlloc` allows.
unsafe impl GlobalAlloc for Ceiling {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if !allowed(layout.size()) {
            return std::ptr::null_mut();
        }
        // SAFETY: the caller's contract is passed on.
        unsafe { System.alloc(layout) }
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        if !allowed(layout.size()) {
            return std::ptr::null_mut();
        }
        // SAFETY: the caller's contract is passed on.
        unsafe { System.alloc_zeroed(layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if !allowed(new_size) {
            return std::ptr::null_mut();
        }
        // SAFETY: the caller's contract is passed on.
        unsafe { System.realloc(ptr, layout, new_size) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: the caller's contract is passed on.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static ALLOCATOR: Ceiling = Ceiling;

/// Runs `f` with this thread's allocations capped at `ceiling` bytes each, catching a panic.
fn capped<T>(ceiling: usize, f: impl FnOnce() -> T) -> std::thread::Result<T> {
    CEILING.with(|c| c.set(ceiling));
    let result = catch_unwind(AssertUnwindSafe(f));
    CEILING.with(|c| c.set(usize::MAX));
    result
}

// ---------------------------------------------------------------------------------------
// Cases: seeds, names, replay, a watchdog.

/// A generator of one case's choices.
struct Gen(Pcg32);

impl Gen {
    fn for_case(family: &str, index: u64) -> Self {
        let family = family
            .bytes()
            .fold(0u64, |h, b| h.wrapping_mul(31) ^ u64::from(b));
        Gen(Pcg32::new(
            tessera::sampling::mix64(family ^ index.wrapping_mul(0x9e37_79b9_7f4a_7c15)),
            0xda3e_39cb_94b9_5bdb,
        ))
    }

    fn below(&mut self, n: usize) -> usize {
        (self.0.next_u64() % n.max(1) as u64) as usize
    }

    fn chance(&mut self, percent: usize) -> bool {
        self.below(100) < percent
    }

    fn pick<T: Copy>(&mut self, items: &[T]) -> T {
        items[self.below(items.len())]
    }
}

/// How many cases of a family to run: `base` times `TESSERA_FUZZ_SCALE` (default 1).
fn count(base: u64) -> u64 {
    let scale = std::env::var("TESSERA_FUZZ_SCALE")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1u64);
    base * scale.max(1)
}

/// The case indices of `family` to run: all of `0..n`, or the one `TESSERA_FUZZ_CASE` names.
fn cases(family: &str, n: u64) -> Vec<u64> {
    match std::env::var("TESSERA_FUZZ_CASE") {
        Ok(one) => match one.split_once(':') {
            Some((f, i)) if f == family => i.parse().map(|i| vec![i]).unwrap_or_default(),
            _ => Vec::new(),
        },
        Err(_) => (0..n).collect(),
    }
}

/// Ends the test binary, naming the case, if one case runs longer than `limit`: a hang.
struct Watchdog {
    current: Arc<std::sync::Mutex<(String, Instant)>>,
    done: Arc<AtomicBool>,
}

impl Watchdog {
    fn new(limit: Duration) -> Self {
        let current = Arc::new(std::sync::Mutex::new((String::new(), Instant::now())));
        let done = Arc::new(AtomicBool::new(false));
        let (watched, finished) = (Arc::clone(&current), Arc::clone(&done));
        std::thread::spawn(move || {
            while !finished.load(Ordering::Relaxed) {
                std::thread::sleep(Duration::from_millis(100));
                let (name, since) = watched.lock().unwrap().clone();
                if since.elapsed() > limit {
                    let _ = writeln!(
                        std::io::stderr(),
                        "fuzz: case {name} still runs after {limit:?}: a hang; replay it with \
                         TESSERA_FUZZ_CASE={name}"
                    );
                    std::process::exit(1);
                }
            }
        });
        Self { current, done }
    }

    /// Case `name` starts now.
    fn begin(&self, name: &str) {
        *self.current.lock().unwrap() = (name.to_owned(), Instant::now());
    }
}

impl Drop for Watchdog {
    fn drop(&mut self) {
        self.done.store(true, Ordering::Relaxed);
    }
}

/// The failures of a family, reported together at the end.
#[derive(Default)]
struct Failures(Vec<String>);

impl Failures {
    fn add(&mut self, case: &str, what: String, input: &str) {
        let input: String = input.chars().take(3000).collect();
        self.0.push(format!(
            "case {case} (replay: TESSERA_FUZZ_CASE={case}): {what}\n--- input:\n{input}\n---"
        ));
    }

    fn check(self, family: &str, ran: usize) {
        assert!(
            self.0.is_empty(),
            "{} of {ran} {family} cases failed:\n{}",
            self.0.len(),
            self.0.join("\n")
        );
    }
}

/// Says on the real standard error (which the test harness does not capture) what a family
/// ran, so CI's log shows it.
fn summary(line: std::fmt::Arguments) {
    let _ = writeln!(std::io::stderr(), "fuzz: {line}");
}

fn panic_text(p: &(dyn std::any::Any + Send)) -> String {
    p.downcast_ref::<&str>()
        .map(|s| (*s).to_owned())
        .or_else(|| p.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "a panic".to_owned())
}

// ---------------------------------------------------------------------------------------
// Scene files.

/// Numbers chosen to sit on every edge: zero, signs, f32 and integer limits, NaN.
const NUMBERS: &[&str] = &[
    "0",
    "-0.0",
    "1",
    "-1",
    "2",
    "0.5",
    "1e-45",
    "1e-39",
    "1e-30",
    "1e-18",
    "1e18",
    "1e19",
    "1e20",
    "3e38",
    "4e38",
    "1.7e308",
    "-1.7e308",
    "nan",
    "inf",
    "-inf",
    "1e-300",
    "255",
    "4294967295",
    "4294967296",
    "2147483648",
    "268435457",
    "16384",
    "9223372036854775807",
    "-9223372036854775808",
    "18446744073709551616",
    "1000",
    "1001",
    "179.99999",
    "180",
];

/// Values of other types and shapes, to put where a number or string belongs.
const VALUES: &[&str] = &[
    "\"junk\"",
    "\"metal\"",
    "\"dielectric\"",
    "\"lambertian\"",
    "\"uniform\"",
    "\"gradient\"",
    "\"always\"",
    "\"inverted\"",
    "\"normals\"",
    "\"uv\"",
    "true",
    "[]",
    "[1, 2]",
    "[0, 0, 0]",
    "[1, 2, 3, 4]",
    "[0, 0, -1, \"junk\", [1, 2]]",
    "[1e20, 0, 0]",
    "[0, 1e-18, 0]",
    "[nan, 0, 0]",
    "[1, 0, 9223372036854775807, 4]",
    "[0, 0, 4294967295, 4294967295]",
    "{ a = 1 }",
    "1979-05-27",
    "'''\nmulti\n'''",
];

/// Whole lines to insert: keys of every table, some in the wrong place.
const LINES: &[&str] = &[
    "crop = [1, 1, 4, 4]",
    "crop = [0, 0, 9223372036854775807, 1]",
    "seed = 18446744073709551615",
    "vup = [0, 1e20, 0]",
    "aperture = 1e18",
    "focus_dist = 1e-30",
    "[camera]\nlookfrom = [3e38, 0, 0]\nlookat = [-3e38, 0, 0]\nvfov_deg = 90",
    "[camera]\nlookfrom = [0, 0, 0]\nlookat = [0, 0, 0]\nvfov_deg = 90",
    "[[spheres]]\ncenter = [0, 0, 0]\nradius = 1e18\nmaterial = \"ground\"",
    "[[spheres]]\ncenter = [0, 0, 0]\nradius = -1e-18\nmaterial = \"x\"",
    "[materials.x]\ntype = \"dielectric\"\nir = 1e-30\nrefraction = \"inverted\"",
    "[materials.y]\ntype = \"metal\"\nalbedo = [3e38, 3e38, 3e38]\nfuzz = 1",
    "[background]\ntype = \"uniform\"\ncolor = [3e38, 0, 1]",
    "[random_spheres]\ngrid = 3\nradius = 1e18",
    "[render]\nshading = \"normals\"\ngamma = 1e-30\nt_min = 1e30",
    "[image]\nwidth = 1\nheight = 268435456\nsamples_per_pixel = 1\nmax_depth = 1",
    "width = 0",
    "height = -5",
    "max_depth = 4294967296",
    "unknown = 1",
    "[[spheres]]",
    "[materials]",
    "\u{feff}",
    "\u{0}",
];

/// A scene with a table of every kind, as a seed for mutation besides the scene files.
const EVERYTHING: &str = r#"[image]
width = 24
height = 16
samples_per_pixel = 2
max_depth = 6
seed = 3
crop = [2, 2, 20, 12]

[render]
shading = "path"
diffuse = "unit_sphere"
gamma = 2.2
t_min = 0.001
jitter = true

[camera]
lookfrom = [3.0, 2.0, 3.0]
lookat = [0.0, 0.0, -1.0]
vup = [0.0, 1.0, 0.0]
vfov_deg = 40.0
aperture = 0.2
focus_dist = 4.0

[background]
type = "gradient"
bottom = [1.0, 1.0, 1.0]
top = [0.5, 0.7, 1.0]

[materials.ground]
type = "lambertian"
albedo = [0.8, 0.8, 0.0]

[materials.glass]
type = "dielectric"
ir = 1.5
refraction = "snell"

[materials.gold]
type = "metal"
albedo = [0.8, 0.6, 0.2]
fuzz = 0.3

[[spheres]]
center = [0.0, -100.5, -1.0]
radius = 100.0
material = "ground"

[[spheres]]
center = [-1.0, 0.0, -1.0]
radius = -0.45
material = "glass"

[[spheres]]
center = [1.0, 0.0, -1.0]
radius = 0.5
material = "gold"

[random_spheres]
grid = 2
radius = 0.2
keep_clear = [[4.0, 0.2, 0.0]]
clearance = 0.9
p_diffuse = 0.8
p_metal = 0.15
glass_ir = 1.5
seed = 7
"#;

/// The scene files to mutate: every file in `scenes/` and `EVERYTHING`.
fn scene_corpus() -> Vec<String> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(root().join("scenes"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    files.sort();
    let mut corpus: Vec<String> = files
        .iter()
        .map(|p| std::fs::read_to_string(p).unwrap())
        .collect();
    corpus.push(EVERYTHING.to_owned());
    corpus
}

/// Byte offsets of the numbers in `text` (runs of digits, signs, points and exponents).
fn number_spans(bytes: &[u8]) -> Vec<(usize, usize)> {
    let mut spans = Vec::new();
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i].is_ascii_digit() {
            let start = if i > 0 && bytes[i - 1] == b'-' {
                i - 1
            } else {
                i
            };
            while i < bytes.len()
                && (bytes[i].is_ascii_alphanumeric() || b".+-_".contains(&bytes[i]))
            {
                i += 1;
            }
            spans.push((start, i));
        } else {
            i += 1;
        }
    }
    spans
}

/// One random change to a scene file's bytes; `keep_syntax` keeps to changes that mostly
/// leave valid TOML, so the checks behind the parser are reached.
fn mutate_scene(g: &mut Gen, text: &mut Vec<u8>, keep_syntax: bool) {
    let lines =
        |t: &[u8]| -> Vec<Vec<u8>> { t.split(|&b| b == b'\n').map(<[u8]>::to_vec).collect() };
    match if keep_syntax { g.below(4) } else { g.below(9) } {
        // A number becomes an edge value.
        0 | 1 => {
            let spans = number_spans(text);
            if let Some(&(a, b)) = spans.get(g.below(spans.len())) {
                text.splice(a..b, g.pick(NUMBERS).bytes());
            }
        }
        // A value (after `=`) becomes something of another type or shape.
        2 => {
            let mut ls = lines(text);
            let i = g.below(ls.len());
            if let Some(eq) = ls[i].iter().position(|&b| b == b'=') {
                ls[i].truncate(eq + 1);
                ls[i].extend_from_slice(b" ");
                ls[i].extend_from_slice(g.pick(VALUES).as_bytes());
            }
            *text = ls.join(&b'\n');
        }
        // A line is inserted, deleted, duplicated or moved.
        3 => {
            let mut ls = lines(text);
            let at = g.below(ls.len() + 1);
            ls.insert(at, g.pick(LINES).as_bytes().to_vec());
            *text = ls.join(&b'\n');
        }
        4 => {
            let mut ls = lines(text);
            let (i, j) = (g.below(ls.len()), g.below(ls.len()));
            match g.below(3) {
                0 => drop(ls.remove(i)),
                1 => ls.insert(j, ls[i].clone()),
                _ => ls.swap(i, j),
            }
            *text = ls.join(&b'\n');
        }
        // Bytes: flipped, set to an odd value, inserted or cut.
        5 => {
            if !text.is_empty() {
                let i = g.below(text.len());
                text[i] ^= 1 << g.below(8);
            }
        }
        6 => {
            let i = g.below(text.len() + 1);
            let byte = g.pick(&[0u8, 0xff, 0xc3, b'[', b']', b'"', b'=', b'\n', b'#']);
            text.insert(i, byte);
        }
        7 => {
            let i = g.below(text.len() + 1);
            text.truncate(i);
        }
        // Everything doubled: duplicate tables and keys.
        _ => {
            let copy = text.clone();
            text.push(b'\n');
            text.extend_from_slice(&copy);
        }
    }
}

/// What became of one case's input.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Outcome {
    Refused,
    Accepted,
}

/// Checks that refusal `e` of a scene named `fuzz.toml` starts `fuzz.toml:LINE:COLUMN:`.
fn located(e: tessera::Error) -> Result<Outcome, String> {
    let message = e.to_string();
    let mut fields = message.splitn(4, ':');
    let placed = fields.next() == Some("fuzz.toml")
        && fields.next().is_some_and(|l| l.parse::<u32>().is_ok())
        && fields.next().is_some_and(|c| c.parse::<u32>().is_ok());
    if placed {
        Ok(Outcome::Refused)
    } else {
        Err(format!("a refusal without file:line:column: {message}"))
    }
}

/// Checks one scene file: reading it never panics; a refusal names the file, line and
/// column; an accepted scene renders small without panicking.
fn check_scene_case(bytes: &[u8]) -> Result<Outcome, String> {
    let path = Path::new("fuzz.toml");
    let Ok(text) = std::str::from_utf8(bytes) else {
        // Only loading a file meets invalid UTF-8.
        let dir = temp_dir("fuzz-utf8");
        std::fs::write(dir.join(path), bytes).unwrap();
        let e = Scene::load(&dir.join(path), &Overrides::default())
            .err()
            .ok_or("invalid UTF-8 accepted")?;
        let message = e.to_string().replace(&format!("{}/", dir.display()), "");
        return if message.starts_with("fuzz.toml:") && message.contains("UTF-8") {
            Ok(Outcome::Refused)
        } else {
            Err(format!(
                "invalid UTF-8 refused without its place: {message}"
            ))
        };
    };
    if let Err(e) = Scene::parse(text, path, &Overrides::default()) {
        return located(e);
    }
    // Accepted: render it tiny (a few pixels, one sample, short paths).
    let small = Overrides {
        width: Some(8),
        samples_per_pixel: Some(1),
        max_depth: Some(4),
        seed: None,
    };
    let scene = match Scene::parse(text, path, &small) {
        Ok(scene) => scene,
        // The new width can be what is refused (8 wide makes a tall file too tall).
        Err(tessera::Error::Setting { .. }) => return Ok(Outcome::Refused),
        Err(e) => return located(e),
    };
    let options = RenderOptions {
        threads: Some(1),
        tile: 8,
    };
    let (film, stats) = render::render(&scene, &options, &|_| {}).map_err(|e| e.to_string())?;
    let window = scene.settings.window;
    if film.sums.len() as u64 != window.area() || stats.samples != window.area() {
        return Err(format!(
            "rendered {} pixels of a {window:?} window",
            film.sums.len()
        ));
    }
    Ok(Outcome::Accepted)
}

/// Runs `check` on each case of `family`, under an allocation ceiling and a watchdog, and
/// fails with every case that failed. `make` generates a case's input and its printable
/// form from the case's generator.
fn run_family<I>(
    family: &'static str,
    base_count: u64,
    ceiling: usize,
    make: impl Fn(&mut Gen) -> (I, String),
    check: impl Fn(&I) -> Result<Outcome, String>,
) {
    let watchdog = Watchdog::new(Duration::from_secs(60));
    let mut failures = Failures::default();
    let todo = cases(family, count(base_count));
    let start = Instant::now();
    let mut accepted = 0;
    for &i in &todo {
        let name = format!("{family}:{i}");
        watchdog.begin(&name);
        CASE.with(|c| c.set((family, i)));
        let (input, shown) = make(&mut Gen::for_case(family, i));
        match capped(ceiling, || check(&input)) {
            Ok(Ok(outcome)) => accepted += usize::from(outcome == Outcome::Accepted),
            Ok(Err(what)) => failures.add(&name, what, &shown),
            Err(p) => failures.add(&name, format!("panicked: {}", panic_text(&*p)), &shown),
        }
    }
    summary(format_args!(
        "{} {family} cases ({accepted} accepted, {} refused) in {:.1} s",
        todo.len(),
        todo.len() - accepted,
        start.elapsed().as_secs_f64()
    ));
    failures.check(family, todo.len());
}

#[test]
fn mutated_scene_files_never_panic_and_refusals_say_where() {
    let corpus = scene_corpus();
    run_family(
        "scene",
        20_000,
        // Nothing a scene file says needs more than this at once, rendered 8 pixels wide.
        1 << 30,
        |g| {
            let mut text = corpus[g.below(corpus.len())].as_bytes().to_vec();
            let keep_syntax = g.chance(70);
            for _ in 0..1 + g.below(4) {
                mutate_scene(g, &mut text, keep_syntax);
            }
            let shown = String::from_utf8_lossy(&text).into_owned();
            (text, shown)
        },
        |text| check_scene_case(text),
    );
}

// ---------------------------------------------------------------------------------------
// Partial files.

/// A small scene whose parts the partial-file cases start from.
const PART_SCENE: &str = r#"[image]
width = 12
height = 8
samples_per_pixel = 4
max_depth = 3

[materials.red]
type = "lambertian"
albedo = [0.9, 0.1, 0.1]

[[spheres]]
center = [0.0, 0.0, -1.0]
radius = 0.5
material = "red"
"#;

/// Real parts of `PART_SCENE`: the whole render, a sample range, a band of rows, and an
/// unfinished checkpoint.
fn seed_parts(scene: &Scene) -> Vec<Part> {
    let options = RenderOptions {
        threads: Some(1),
        tile: 4,
    };
    let whole = Job::whole(scene);
    let rows = shard::job(
        scene,
        Some(Shard { index: 1, count: 3 }),
        shard::Split::Rows,
        None,
    )
    .unwrap();
    let range = Job {
        samples: SampleRange { start: 1, end: 3 },
        ..whole
    };
    let mut parts = Vec::new();
    for job in [whole, rows, range] {
        let mut progress = Progress::new(job, 4);
        let stop = AtomicBool::new(false);
        let control = render::Control {
            stop: &stop,
            on_samples: &|_| {},
            on_snapshot: None,
        };
        render::render_job(scene, &options, &mut progress, control).unwrap();
        parts.push(Part::from_progress(scene, &progress, 4));
    }
    let mut unfinished = parts[0].clone();
    unfinished.header.done[1] = 1;
    parts.push(unfinished);
    parts
}

const U32S: &[u32] = &[
    0,
    1,
    2,
    3,
    4,
    7,
    8,
    12,
    16,
    255,
    16384,
    65536,
    1 << 28,
    u32::MAX - 1,
    u32::MAX,
];

/// One random change to a part: to its header's fields (the file is then written with a
/// valid checksum, so the deeper checks are reached) or to its bytes.
fn mutate_part(g: &mut Gen, part: &mut Part, bytes: &mut Option<Vec<u8>>) {
    let n = |g: &mut Gen| U32S[g.below(U32S.len())];
    if let Some(b) = bytes.as_mut() {
        match g.below(5) {
            0 if !b.is_empty() => {
                let i = g.below(b.len());
                b[i] ^= 1 << g.below(8);
            }
            1 => b.truncate(g.below(b.len() + 1)),
            2 => {
                let more = g.below(64);
                b.extend((0..more).map(|k| k as u8));
            }
            3 if b.len() >= 24 => {
                let claims = [0u64, 1, 8, 1 << 20, 1 << 32, u64::MAX, u64::MAX - 23];
                let claim = claims[g.below(claims.len())];
                b[16..24].copy_from_slice(&claim.to_le_bytes());
            }
            _ => {
                // A header value rewritten in the JSON text (its length word follows).
                let spans = number_spans(b);
                if let Some(&(a, e)) = spans.get(g.below(spans.len())) {
                    b.splice(a..e, g.pick(NUMBERS).bytes());
                }
            }
        }
        return;
    }
    let h = &mut part.header;
    match g.below(13) {
        // A coherent claim of a huge image, which only the file's length belies.
        11 | 12 => {
            let (w, ht) = g.pick(&[
                (16384, 16384),
                (65536, 4096),
                (1, 1 << 28),
                (1 << 14, 1 << 13),
            ]);
            (h.width, h.height) = (w, ht);
            h.window = [0, 0, w, ht];
            h.region = [0, 0, w, ht];
            if g.chance(50) {
                h.tile = 1;
            }
        }
        0 => h.width = n(g),
        1 => h.height = n(g),
        2 => h.window[g.below(4)] = n(g),
        3 => h.region[g.below(4)] = n(g),
        4 => h.samples[g.below(2)] = n(g),
        5 => h.target = n(g),
        6 => h.tile = n(g),
        7 => match g.below(3) {
            0 => h.done.clear(),
            1 => h.done.push(n(g)),
            _ => {
                if let Some(d) = h.done.first_mut() {
                    *d = n(g);
                }
            }
        },
        8 => h.version = n(g),
        9 => {
            let keep = g.below(part.sums.len() + 2);
            part.sums.resize(keep, [u64::MAX, 0, 1 << 40]);
        }
        _ => {
            for s in part.sums.iter_mut() {
                *s = [u64::MAX; 3];
            }
        }
    }
}

/// Checks one part's bytes: reading never panics nor allocates beyond the ceiling; what is
/// accepted is consistent, and merging or resuming it never panics.
fn check_part_case(scene: &Scene, bytes: &[u8]) -> Result<Outcome, String> {
    let path = Path::new("fuzz.part");
    let part = match Part::from_bytes(bytes, path) {
        Ok(part) => part,
        Err(e) => {
            let message = e.to_string();
            return if message.starts_with("fuzz.part: ") {
                Ok(Outcome::Refused)
            } else {
                Err(format!("a refusal that does not name the file: {message}"))
            };
        }
    };
    if part.sums.len() as u64 != part.region().area() {
        return Err(format!(
            "accepted {} sums for region {:?}",
            part.sums.len(),
            part.region()
        ));
    }
    let named = vec![(PathBuf::from("fuzz.part"), part.clone())];
    if let Ok((film, _)) = tessera::partial::merge(&named)
        && film.sums.len() as u64 != u64::from(film.width) * u64::from(film.height)
    {
        return Err("merged into a film of the wrong size".to_owned());
    }
    if part.check_scene(scene, path).is_ok() {
        let mut progress = part.progress();
        progress.extend_to(part.samples().end.saturating_add(1));
        let _ = progress.percent_done();
    }
    Ok(Outcome::Accepted)
}

#[test]
fn mutated_partial_files_are_refused_cleanly_and_never_believed() {
    let scene = Scene::parse(PART_SCENE, Path::new("part.toml"), &Overrides::default()).unwrap();
    let parts = seed_parts(&scene);
    run_family(
        "part",
        20_000,
        // The files here are a few kilobytes: reading one never needs 16 MiB.
        16 << 20,
        |g| {
            let mut part = parts[g.below(parts.len())].clone();
            // Half the cases change fields, then write a file with a valid checksum; half
            // change the bytes.
            let mut bytes = g.chance(50).then(|| part.to_bytes());
            for _ in 0..1 + g.below(3) {
                mutate_part(g, &mut part, &mut bytes);
            }
            let bytes = bytes.unwrap_or_else(|| part.to_bytes());
            let head = String::from_utf8_lossy(&bytes[..bytes.len().min(400)]).into_owned();
            let shown = format!("{} bytes, beginning {head:?}", bytes.len());
            (bytes, shown)
        },
        |bytes| check_part_case(&scene, bytes),
    );
}

// ---------------------------------------------------------------------------------------
// Command lines, through the binary.

/// Flags, values that make sense with them, and values that do not. None makes a valid render
/// longer than a moment.
#[rustfmt::skip]
const FLAGS: &[(&str, &[&str], &[&str])] = &[
    ("--width", &["1", "7", "12"], &["0", "-1", "x", "4294967296", "9000000", "1e3", ""]),
    ("--spp", &["1", "2", "3"], &["0", "-3", "x", "4294967296", "99999999999"]),
    ("--depth", &["1", "3", "50"], &["0", "-1", "4294967296"]),
    ("--seed", &["0", "7", "18446744073709551615"], &["18446744073709551616", "-1", "x"]),
    ("--threads", &["1", "2", "3", "64"], &["0", "-1", "x"]),
    ("--tile", &["1", "3", "16", "100000"], &["0", "-1"]),
    ("--shard", &["0/1", "1/2", "0/2", "env", "env/2"], &["2/2", "0/0", "3/2", "a/b", "0/4294967295", "1", "/", ""]),
    ("--split", &["samples", "rows"], &["columns", ""]),
    ("--samples", &["0..1", "0..2", "1..2"], &["1..0", "0..100", "5..9", "x", "..", "0..4294967295"]),
    ("--checkpoint", &["ck", "ck2"], &["no/dir/ck", "dir", "p0.part", "bad.part", "good.toml"]),
    ("--checkpoint-every", &["0", "0.01", "1e300", "2e19"], &["-1", "nan", "inf", "x"]),
    ("-o", &["out.png", "out.ppm", "out.exr", "part.bin"], &["out.jpg", "out", "no/dir/x.png", "dir"]),
    ("--repeat", &["1", "2"], &["0", "x"]),
    ("--json", &[], &[]),
    ("--no-scaling", &[], &[]),
    ("--quiet", &[], &[]),
    ("--bogus", &[], &[]),
];

/// Positional arguments: scenes, images, parts, and things that are none of those.
const POSITIONALS: &[&str] = &[
    "good.toml",
    "tiny-cover.toml",
    "junk.toml",
    "utf8.toml",
    "missing.toml",
    "dir",
    "empty",
    "a.png",
    "a.exr",
    "a.ppm",
    "p0.part",
    "p1.part",
    "bad.part",
    "good.toml",
];

/// The files command lines refer to, in a fresh directory.
fn cli_workspace() -> PathBuf {
    let dir = temp_dir("fuzz-cli");
    let write = |name: &str, bytes: &[u8]| std::fs::write(dir.join(name), bytes).unwrap();
    write("good.toml", PART_SCENE.as_bytes());
    let cover = std::fs::read_to_string(scene_path("cover.toml")).unwrap();
    let tiny = cover
        .replace("width = 1200", "width = 24")
        .replace("height = 800", "height = 16")
        .replace("samples_per_pixel = 500", "samples_per_pixel = 2");
    assert_ne!(
        tiny, cover,
        "the cover's size lines changed; update this test"
    );
    write("tiny-cover.toml", tiny.as_bytes());
    write(
        "junk.toml",
        &(0..600u32)
            .map(|i| (i * 7919 % 251) as u8)
            .collect::<Vec<_>>(),
    );
    write("utf8.toml", b"[image]\nwidth = 4 # \xff\n");
    write("empty", b"");
    std::fs::create_dir_all(dir.join("dir")).unwrap();
    let tessera = |args: &[&str]| {
        let o = Command::new(env!("CARGO_BIN_EXE_tessera"))
            .args(args)
            .current_dir(&dir)
            .output()
            .unwrap();
        assert!(
            o.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    };
    for out in ["a.png", "a.exr", "a.ppm"] {
        tessera(&["render", "good.toml", "-q", "-o", out]);
    }
    tessera(&[
        "render",
        "good.toml",
        "-q",
        "--shard",
        "0/2",
        "-o",
        "p0.part",
    ]);
    tessera(&[
        "render",
        "good.toml",
        "-q",
        "--shard",
        "1/2",
        "-o",
        "p1.part",
    ]);
    let mut bad = std::fs::read(dir.join("p1.part")).unwrap();
    let middle = bad.len() / 2;
    bad[middle] ^= 0x40;
    write("bad.part", &bad);
    dir
}

/// A random command line: mostly sensible, with a nonsensical value one time in five.
fn command_line(g: &mut Gen) -> Vec<String> {
    let command = g.pick(&[
        "render", "render", "render", "render", "bench", "merge", "compare", "help", "renderr", "",
    ]);
    let mut args = vec![command.to_owned()];
    let positionals = match command {
        "merge" => 1 + g.below(4),
        "compare" => g.below(4),
        _ => usize::from(g.chance(80)),
    };
    for _ in 0..positionals {
        let sensible = match command {
            "render" | "bench" => g.pick(&["good.toml", "tiny-cover.toml"]),
            "merge" => g.pick(&["p0.part", "p1.part"]),
            _ => g.pick(&["a.png", "a.exr", "a.ppm"]),
        };
        let any = g.pick(POSITIONALS);
        args.push(if g.chance(80) { sensible } else { any }.to_owned());
    }
    for _ in 0..g.below(5) {
        let (flag, good, bad) = FLAGS[g.below(FLAGS.len())];
        args.push(flag.to_owned());
        let values = if bad.is_empty() || (g.chance(80) && !good.is_empty()) {
            good
        } else {
            bad
        };
        if !values.is_empty() {
            args.push(g.pick(values).to_owned());
        }
    }
    if command == "merge" && g.chance(80) {
        args.extend(["-o".to_owned(), "merged.png".to_owned()]);
    }
    args
}

/// Runs tessera in `dir` with a deadline; `None` if it ran past it.
fn run_bounded(
    args: &[String],
    dir: &Path,
    env: &[(&str, &str)],
    deadline: Duration,
) -> Option<std::process::Output> {
    let mut child = Command::new(env!("CARGO_BIN_EXE_tessera"))
        .args(args)
        .envs(env.iter().copied())
        .current_dir(dir)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > deadline {
            let _ = child.kill();
            let _ = child.wait();
            return None;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    Some(child.wait_with_output().unwrap())
}

/// Runs one command line in `dir` and checks how it ended: success, or exit 2 with a
/// message; never a signal (an abort), another status, a panic or a hang.
fn check_command_line(
    dir: &Path,
    args: &[String],
    env: &[(&str, &str)],
) -> Result<Outcome, String> {
    let Some(o) = run_bounded(args, dir, env, Duration::from_secs(30)) else {
        return Err("ran for over 30 s: a hang".to_owned());
    };
    let err = String::from_utf8_lossy(&o.stderr);
    match o.status.code() {
        None => Err(format!("killed by a signal ({:?}): {err}", o.status)),
        _ if err.contains("panicked") => Err(format!("panicked: {err}")),
        Some(0) => Ok(Outcome::Accepted),
        Some(2) if !err.trim().is_empty() => Ok(Outcome::Refused),
        Some(2) => Err("exit 2 without a message".to_owned()),
        Some(c) => Err(format!("exit status {c}: {err}")),
    }
}

/// Job-system environments a command line may run in.
const ENVIRONMENTS: &[&[(&str, &str)]] = &[
    &[],
    &[
        ("SLURM_ARRAY_TASK_ID", "1"),
        ("SLURM_ARRAY_TASK_COUNT", "2"),
    ],
    &[("SLURM_ARRAY_TASK_ID", "x"), ("SLURM_ARRAY_TASK_MIN", "3")],
    &[("JOB_COMPLETION_INDEX", "4294967295")],
];

#[test]
fn generated_command_lines_end_in_success_or_a_clear_refusal() {
    let dir = cli_workspace();
    run_family(
        "cli",
        2000,
        usize::MAX,
        |g| {
            let args = command_line(g);
            let env = g.pick(ENVIRONMENTS);
            let shown = format!("{env:?} tessera {}", args.join(" "));
            ((args, env), shown)
        },
        |(args, env)| check_command_line(&dir, args, env),
    );
}

/// Shard and sample-range specs, as the command line and job systems give them.
#[test]
fn shard_and_sample_specs_never_panic() {
    let pieces = [
        "0",
        "1",
        "2",
        "/",
        "..",
        "env",
        "4294967295",
        "4294967296",
        "-1",
        " ",
        "x",
        "18446744073709551615",
    ];
    let scene = Scene::parse(PART_SCENE, Path::new("part.toml"), &Overrides::default()).unwrap();
    for i in cases("spec", count(20_000)) {
        let mut g = Gen::for_case("spec", i);
        let spec: String = (0..1 + g.below(4)).map(|_| g.pick(&pieces)).collect();
        let value = |g: &mut Gen| g.pick(&pieces).to_owned();
        let (id, min, count, index) = (value(&mut g), value(&mut g), value(&mut g), value(&mut g));
        let var = |k: &str| match k {
            "SLURM_ARRAY_TASK_ID" => Some(id.clone()),
            "SLURM_ARRAY_TASK_MIN" => Some(min.clone()),
            "SLURM_ARRAY_TASK_COUNT" => Some(count.clone()),
            "JOB_COMPLETION_INDEX" => Some(index.clone()),
            _ => None,
        };
        let outcome = catch_unwind(AssertUnwindSafe(|| {
            let shard = Shard::parse(&spec, var).ok();
            let samples = tessera::shard::parse_samples(&spec).ok();
            let split = if g.chance(50) {
                shard::Split::Rows
            } else {
                shard::Split::Samples
            };
            let _ = shard::job(&scene, shard, split, samples);
        }));
        assert!(
            outcome.is_ok(),
            "spec:{i}: `{spec}` with {id} {min} {count} {index} panicked"
        );
    }
}

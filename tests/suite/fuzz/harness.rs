//! The fuzzing harness: an allocation ceiling per case, a generator per case from a fixed
//! seed, replay of one case, a watchdog against hangs, and failures reported together.

use rand_core::Rng as _;
use rand_pcg::Pcg32;
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::io::Write;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

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

/// A generator of one case's choices.
pub(crate) struct Gen(Pcg32);

impl Gen {
    pub(crate) fn for_case(family: &str, index: u64) -> Self {
        let family = family
            .bytes()
            .fold(0u64, |h, b| h.wrapping_mul(31) ^ u64::from(b));
        Gen(Pcg32::new(
            tessera::sampling::mix64(family ^ index.wrapping_mul(0x9e37_79b9_7f4a_7c15)),
            0xda3e_39cb_94b9_5bdb,
        ))
    }

    pub(crate) fn below(&mut self, n: usize) -> usize {
        (self.0.next_u64() % n.max(1) as u64) as usize
    }

    pub(crate) fn chance(&mut self, percent: usize) -> bool {
        self.below(100) < percent
    }

    pub(crate) fn pick<T: Copy>(&mut self, items: &[T]) -> T {
        items[self.below(items.len())]
    }
}

/// How many cases of a family to run: a fifth of `base` (the same first cases), or `base`
/// times `TESSERA_FUZZ_SCALE` / 5. The bulk of the search is the coverage-guided fuzzers'
/// (fuzz/, which `.ci/run` runs); these families keep every reader's contract in every test
/// run.
pub(crate) fn count(base: u64) -> u64 {
    let scale: u64 = std::env::var("TESSERA_FUZZ_SCALE")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1);
    (base * scale.max(1) / 5).max(1)
}

/// The case indices of `family` to run: all of `0..n`, or the one `TESSERA_FUZZ_CASE` names.
pub(crate) fn cases(family: &str, n: u64) -> Vec<u64> {
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
    pub(crate) fn new(limit: Duration) -> Self {
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
    pub(crate) fn begin(&self, name: &str) {
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
    pub(crate) fn add(&mut self, case: &str, what: String, input: &str) {
        let input: String = input.chars().take(3000).collect();
        self.0.push(format!(
            "case {case} (replay: TESSERA_FUZZ_CASE={case}): {what}\n--- input:\n{input}\n---"
        ));
    }

    pub(crate) fn check(self, family: &str, ran: usize) {
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

/// What became of one case's input.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(crate) enum Outcome {
    Refused,
    Accepted,
}

/// Runs `check` on each case of `family`, under an allocation ceiling and a watchdog, and
/// fails with every case that failed. `make` generates a case's input and its printable
/// form from the case's generator.
pub(crate) fn run_family<I>(
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

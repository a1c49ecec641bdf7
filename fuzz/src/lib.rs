//! The fuzz targets' shared code: the checks (`checks.rs`, which the corpus replay of the
//! tests shares) and an allocator that refuses, with a message and an abort that libFuzzer
//! reports as a crash, any single allocation above the running target's ceiling. libFuzzer's
//! own `-malloc_limit_mb` needs a sanitizer's allocator hooks, which a build without a
//! sanitizer (what stable Rust builds) does not have.

use std::alloc::{GlobalAlloc, Layout, System};
use std::io::Write;
use std::sync::atomic::{AtomicUsize, Ordering};

#[path = "../checks.rs"]
pub mod checks;

static CEILING: AtomicUsize = AtomicUsize::new(usize::MAX);

/// The system allocator, refusing any single allocation above `CEILING`.
struct Ceiling;

fn allowed(size: usize) -> bool {
    let ceiling = CEILING.load(Ordering::Relaxed);
    if size <= ceiling {
        return true;
    }
    // Written without allocating, then refused: Rust aborts on a failed allocation.
    let mut line = [0u8; 256];
    let mut cursor = std::io::Cursor::new(&mut line[..]);
    let _ = writeln!(
        cursor,
        "tessera-fuzz: one allocation of {size} bytes, above the ceiling of {ceiling}: the \
         input made tessera believe a size it had not checked"
    );
    let n = cursor.position() as usize;
    let _ = std::io::stderr().write_all(&line[..n]);
    // The abort that follows may allocate to print its backtrace.
    CEILING.store(usize::MAX - 1, Ordering::Relaxed);
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

/// Runs target `name`'s check on one input under its allocation ceiling; a broken contract
/// panics, which libFuzzer's panic hook turns into a crash report with the input saved.
pub fn run(name: &str, data: &[u8]) {
    let check = checks::check_of(name).expect("a known target");
    if CEILING.load(Ordering::Relaxed) == usize::MAX {
        // As a Rust `main` does, and tessera's binary with it: a write to a closed socket is
        // an error, not a SIGPIPE that kills the process (libFuzzer's `main` is C++'s; the
        // viewer's server writes with `writev`, which has no MSG_NOSIGNAL).
        // SAFETY: setting a signal's disposition to "ignore" before any thread relies on it.
        unsafe {
            libc::signal(libc::SIGPIPE, libc::SIG_IGN);
        }
        // TESSERA_FUZZ_CEILING=BYTES tries another ceiling.
        let ceiling = (std::env::var("TESSERA_FUZZ_CEILING").ok())
            .and_then(|c| c.parse().ok())
            .or_else(|| (checks::CEILINGS.iter()).find_map(|&(n, c)| (n == name).then_some(c)))
            .unwrap_or(usize::MAX);
        CEILING.store(ceiling, Ordering::Relaxed);
    }
    if let Err(broken) = check(data) {
        panic!("tessera-fuzz {name}: {broken}");
    }
}

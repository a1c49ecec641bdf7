//! Ctrl-C off the main thread: a SIGINT handler that counts each one, then calls the handler
//! it took the place of (Python's, which raises KeyboardInterrupt in the main thread), put in
//! place again by every render that looks for Ctrl-C.
//!
//! Again, since Python's `signal.signal` (which `asyncio.run` calls, to install and then
//! restore a handler) replaces the process's handler: signal-hook's, installed once and never
//! again, was so replaced, and every later render off the main thread went on to its end
//! after Ctrl-C.

use libc::{c_int, c_void, siginfo_t};
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};

/// The Ctrl-Cs this handler has seen.
static SEEN: AtomicU64 = AtomicU64::new(0);
/// How many handlers `PREVIOUS` keeps.
const KEPT: usize = 8;
/// The handlers this one took the place of, oldest first: the last is called after it
/// counts. A render that finds another in its place adds that one, which may call this one
/// in turn (as a handler does that calls the one it replaced): that call is given the one
/// before it, as this one did when that handler replaced it.
static PREVIOUS: [AtomicUsize; KEPT] = [const { AtomicUsize::new(libc::SIG_DFL) }; KEPT];
/// Whether each of `PREVIOUS` takes a `siginfo_t` (`SA_SIGINFO`).
static TAKES_INFO: [AtomicBool; KEPT] = [const { AtomicBool::new(false) }; KEPT];
/// How many of `PREVIOUS` hold a handler.
static KEPT_NOW: AtomicUsize = AtomicUsize::new(0);
/// The thread calling one of `PREVIOUS` (`pthread_self`, 0: none), and how many of them it
/// is inside: a Ctrl-C that came back this way once called this handler and the one it
/// replaced in turn forever, until the stack overflowed (a segfault).
static CHAINING: AtomicUsize = AtomicUsize::new(0);
static DEPTH: AtomicUsize = AtomicUsize::new(0);
/// One render installs it at a time.
static INSTALLING: Mutex<()> = Mutex::new(());

/// Installs the handler where another has taken its place (or none was), and says how many
/// Ctrl-Cs it has seen: one more than that is a Ctrl-C during what follows.
pub fn watch() -> std::io::Result<u64> {
    let _one = INSTALLING.lock().unwrap_or_else(|e| e.into_inner());
    // SAFETY: `sigaction` with valid pointers, reading the current action and then putting
    // this one in its place with the same mask and flags (Python's leave out `SA_RESTART`,
    // so that the main thread's waits end for its handlers to run); `counted` is
    // async-signal-safe.
    unsafe {
        let mut current: libc::sigaction = std::mem::zeroed();
        if libc::sigaction(libc::SIGINT, std::ptr::null(), &mut current) != 0 {
            return Err(std::io::Error::last_os_error());
        }
        let ours = counted as extern "C" fn(c_int, *mut siginfo_t, *mut c_void) as usize;
        if current.sa_sigaction != ours {
            // Not ours now: where `current` is one kept already, the handlers after it are no
            // longer installed; else it goes after them (in the last place, when all are
            // taken).
            let kept = KEPT_NOW.load(Ordering::SeqCst);
            let at = (0..kept)
                .find(|&i| PREVIOUS[i].load(Ordering::SeqCst) == current.sa_sigaction)
                .unwrap_or(kept.min(KEPT - 1));
            TAKES_INFO[at].store(current.sa_flags & libc::SA_SIGINFO != 0, Ordering::SeqCst);
            PREVIOUS[at].store(current.sa_sigaction, Ordering::SeqCst);
            KEPT_NOW.store(at + 1, Ordering::SeqCst);
            let mut action = current;
            action.sa_sigaction = ours;
            action.sa_flags = (current.sa_flags & !libc::SA_RESETHAND) | libc::SA_SIGINFO;
            if libc::sigaction(libc::SIGINT, &action, std::ptr::null_mut()) != 0 {
                return Err(std::io::Error::last_os_error());
            }
        }
    }
    Ok(seen())
}

/// The Ctrl-Cs seen so far.
pub fn seen() -> u64 {
    SEEN.load(Ordering::SeqCst)
}

/// Counts a Ctrl-C and calls the last handler this one took the place of (or, called again
/// by that one, the one before it), unless that was the default (this one is installed only
/// where Python's handler is a function) or `SIG_IGN`. A Ctrl-C on another thread meanwhile
/// is counted, and its handlers are left to the one running.
extern "C" fn counted(signal: c_int, info: *mut siginfo_t, context: *mut c_void) {
    // SAFETY: `pthread_self` only reads the calling thread's own pointer.
    let this = unsafe { libc::pthread_self() } as usize;
    let depth = if CHAINING.load(Ordering::SeqCst) == this {
        DEPTH.load(Ordering::SeqCst)
    } else {
        SEEN.fetch_add(1, Ordering::SeqCst);
        if (CHAINING.compare_exchange(0, this, Ordering::SeqCst, Ordering::SeqCst)).is_err() {
            return;
        }
        0
    };
    if let Some(at) = KEPT_NOW.load(Ordering::SeqCst).checked_sub(depth + 1) {
        let previous = PREVIOUS[at].load(Ordering::SeqCst);
        if previous != libc::SIG_DFL && previous != libc::SIG_IGN {
            DEPTH.store(depth + 1, Ordering::SeqCst);
            // SAFETY: `previous` is a handler `sigaction` reported, of the kind its flags
            // said.
            unsafe {
                if TAKES_INFO[at].load(Ordering::SeqCst) {
                    let handler: extern "C" fn(c_int, *mut siginfo_t, *mut c_void) =
                        std::mem::transmute(previous);
                    handler(signal, info, context);
                } else {
                    let handler: extern "C" fn(c_int) = std::mem::transmute(previous);
                    handler(signal);
                }
            }
            DEPTH.store(depth, Ordering::SeqCst);
        }
    }
    if depth == 0 {
        CHAINING.store(0, Ordering::SeqCst);
    }
}

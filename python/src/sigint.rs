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
/// The handler this one took the place of, called after it counts.
static PREVIOUS: AtomicUsize = AtomicUsize::new(libc::SIG_DFL);
/// Whether `PREVIOUS` takes a `siginfo_t` (`SA_SIGINFO`).
static PREVIOUS_TAKES_INFO: AtomicBool = AtomicBool::new(false);
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
            // Not ours now: no Ctrl-C reads these while they change.
            PREVIOUS_TAKES_INFO.store(current.sa_flags & libc::SA_SIGINFO != 0, Ordering::SeqCst);
            PREVIOUS.store(current.sa_sigaction, Ordering::SeqCst);
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

/// Counts a Ctrl-C and calls the handler this one took the place of, unless that was the
/// default (this one is installed only where Python's handler is a function) or `SIG_IGN`.
extern "C" fn counted(signal: c_int, info: *mut siginfo_t, context: *mut c_void) {
    SEEN.fetch_add(1, Ordering::SeqCst);
    let previous = PREVIOUS.load(Ordering::SeqCst);
    if previous == libc::SIG_DFL || previous == libc::SIG_IGN {
        return;
    }
    // SAFETY: `previous` is the handler `sigaction` reported, of the kind its flags said.
    unsafe {
        if PREVIOUS_TAKES_INFO.load(Ordering::SeqCst) {
            let handler: extern "C" fn(c_int, *mut siginfo_t, *mut c_void) =
                std::mem::transmute(previous);
            handler(signal, info, context);
        } else {
            let handler: extern "C" fn(c_int) = std::mem::transmute(previous);
            handler(signal);
        }
    }
}

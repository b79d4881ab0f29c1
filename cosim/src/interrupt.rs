//! SIGINT, SIGTERM and SIGHUP as a request to stop at the next communication point.
//!
//! [`install`] replaces the default disposition of these signals by a handler that only records
//! the first one; the master polls [`requested`] at each communication point, ends the run
//! cleanly (observers finished with whole rows, unpacked FMUs removed) and reports where it
//! stopped. A hang-up (the terminal closed, an SSH session lost) stops a run like SIGTERM. Later
//! signals are ignored while the run stops, so that pressing Ctrl-C twice still cleans up; a run
//! stuck inside an FMU is ended by SIGKILL. [`ignore_file_size_limit`] turns the SIGXFSZ of a
//! file size limit into a write error (EFBIG) the CSV writer reports.

use std::sync::atomic::{AtomicI32, Ordering};

static SIGNAL: AtomicI32 = AtomicI32::new(0);

/// The signals that stop a run.
pub const SIGNALS: [libc::c_int; 3] = [libc::SIGINT, libc::SIGTERM, libc::SIGHUP];

extern "C" fn record(signal: libc::c_int) {
    // The first signal is the one reported; later ones change nothing.
    let _ = SIGNAL.compare_exchange(0, signal, Ordering::Relaxed, Ordering::Relaxed);
}

/// Route SIGINT, SIGTERM and SIGHUP to [`requested`] (once per process; later calls re-arm).
pub fn install() {
    for signal in SIGNALS {
        // SAFETY: a zeroed sigaction with a handler that only does an atomic compare-exchange
        // (async-signal-safe) and an empty mask; the handler stays installed.
        unsafe {
            let mut action: libc::sigaction = std::mem::zeroed();
            action.sa_sigaction = record as extern "C" fn(libc::c_int) as libc::sighandler_t;
            action.sa_flags = 0;
            libc::sigemptyset(&mut action.sa_mask);
            libc::sigaction(signal, &action, std::ptr::null_mut());
        }
    }
}

/// Ignore SIGXFSZ: a write beyond the file size limit (`ulimit -f`) then fails with EFBIG,
/// reported as an error naming the file, instead of killing the process.
pub fn ignore_file_size_limit() {
    // SAFETY: setting a signal's disposition to SIG_IGN.
    unsafe {
        libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
    }
}

/// The signal received since [`install`], if any.
pub fn requested() -> Option<i32> {
    match SIGNAL.load(Ordering::Relaxed) {
        0 => None,
        s => Some(s),
    }
}

//! SIGINT and SIGTERM as a request to stop at the next communication point.
//!
//! [`install`] replaces the default disposition of both signals by a handler that only records
//! the signal; the master polls [`requested`] at each communication point, ends the run cleanly
//! (observers finished, unpacked FMUs removed) and reports where it stopped. The handler resets
//! itself, so a second signal terminates the process as usual.

use std::sync::atomic::{AtomicI32, Ordering};

static SIGNAL: AtomicI32 = AtomicI32::new(0);

extern "C" fn record(signal: libc::c_int) {
    SIGNAL.store(signal, Ordering::Relaxed);
}

/// Route SIGINT and SIGTERM to [`requested`] (once per process; later calls re-arm).
pub fn install() {
    for signal in [libc::SIGINT, libc::SIGTERM] {
        // SAFETY: a zeroed sigaction with a handler that only stores into an atomic (which is
        // async-signal-safe), an empty mask and SA_RESETHAND.
        unsafe {
            let mut action: libc::sigaction = std::mem::zeroed();
            action.sa_sigaction = record as extern "C" fn(libc::c_int) as libc::sighandler_t;
            action.sa_flags = libc::SA_RESETHAND;
            libc::sigemptyset(&mut action.sa_mask);
            libc::sigaction(signal, &action, std::ptr::null_mut());
        }
    }
}

/// The signal received since [`install`], if any.
pub fn requested() -> Option<i32> {
    match SIGNAL.load(Ordering::Relaxed) {
        0 => None,
        s => Some(s),
    }
}

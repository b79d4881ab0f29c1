//! The log sink of an instance: the messages its FMU logged, through the C logger shim.

use super::Status;
use std::ffi::{c_char, c_int, c_void, CStr};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;

extern "C" {
    /// The logger handed to FMUs (c/logger.c): formats the printf-style message with its
    /// arguments and passes the text on to [`dvpp_cosim_log_sink`].
    pub(super) fn dvpp_cosim_logger(
        env: *mut c_void,
        instance: *const c_char,
        status: c_int,
        category: *const c_char,
        message: *const c_char,
        ...
    );
}

/// One message an FMU logged.
#[derive(Debug, Clone)]
pub struct LogRecord {
    pub status: Status,
    pub category: String,
    pub message: String,
}

/// Where one instance's log messages go. Thread-safe: each instance has its own sink, the
/// records sit behind a mutex, the C shim formats into its own heap buffer, and echoed lines go
/// through the locked stderr; instances stepping in parallel threads log independently.
pub(super) struct LogSink {
    pub(super) instance: String,
    pub(super) records: Mutex<Vec<LogRecord>>,
    /// How many records are held, so that taking none needs no lock (the master asks after
    /// every FMI call).
    pub(super) held: AtomicUsize,
    pub(super) echo: bool,
}

/// Records one message already formatted by `dvpp_cosim_logger` (c/logger.c); never unwinds.
#[no_mangle]
unsafe extern "C" fn dvpp_cosim_log_sink(
    env: *mut c_void,
    name: *const c_char,
    status: c_int,
    category: *const c_char,
    message: *const c_char,
) {
    // A panic (e.g. stderr gone) must not unwind into the FMU's C frames: drop the message.
    // SAFETY: the arguments as the FMU passed them (see `log_sink`).
    let _ = std::panic::catch_unwind(|| unsafe { log_sink(env, name, status, category, message) });
}

/// Record one message of an FMU.
///
/// # Safety
/// `env` is NULL or the `LogSink` this master gave the instance as its environment, alive while
/// the instance is; `category` and `message` are NULL or NUL-terminated strings.
unsafe fn log_sink(
    env: *mut c_void,
    _name: *const c_char,
    status: c_int,
    category: *const c_char,
    message: *const c_char,
) {
    // SAFETY: NULL or our live `LogSink` (the contract above).
    let Some(sink) = (unsafe { (env as *const LogSink).as_ref() }) else {
        return;
    };
    let text = |p: *const c_char| {
        if p.is_null() {
            String::new()
        } else {
            // SAFETY: a non-null NUL-terminated string (the contract above).
            unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned()
        }
    };
    // The C shim already substituted the printf arguments (and turned `%%` into `%`).
    let record = LogRecord {
        status: Status::from_c(status),
        category: text(category),
        message: text(message),
    };
    if sink.echo {
        eprintln!(
            "[{}] {:?} {}: {}",
            sink.instance, record.status, record.category, record.message
        );
    }
    if let Ok(mut r) = sink.records.lock() {
        r.push(record);
        sink.held.store(r.len(), Ordering::Release);
    }
}

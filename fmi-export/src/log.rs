//! Per-instance logging through the master's `fmi2CallbackLogger`, by declared category.

use crate::ffi::{fmi2CallbackLogger, fmi2ComponentEnvironment};
use crate::Status;
use std::ffi::CString;
use std::sync::{Arc, Mutex};

/// The log categories every FMU declares, in `LogCategories` order.
pub const CATEGORIES: [(&str, &str); 6] = [
    (
        "logEvents",
        "Model events: initialization results, parameter changes, limits reached",
    ),
    ("logStatusWarning", "Calls that return fmi2Warning"),
    ("logStatusDiscard", "Calls that return fmi2Discard"),
    (
        "logStatusError",
        "Calls that return fmi2Error: illegal call sequences, rejected values",
    ),
    (
        "logStatusFatal",
        "Calls that return fmi2Fatal: contained panics",
    ),
    ("logAll", "Everything above"),
];

const ALL: u32 = (1 << CATEGORIES.len()) - 1;
/// Warnings, errors and fatal errors reach the master even when debug logging is off.
const ALWAYS: u32 = (1 << 1) | (1 << 3) | (1 << 4);

/// One message as the master's `fmi2CallbackLogger` receives it (text `%`-escaped).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LogRecord {
    pub instance: String,
    pub status: Status,
    pub category: String,
    pub message: String,
}

/// Where a logger sends its messages.
#[derive(Clone)]
pub enum LogSink {
    /// The master's `fmi2CallbackLogger` and its `componentEnvironment`.
    Callback {
        callback: fmi2CallbackLogger,
        environment: fmi2ComponentEnvironment,
    },
    /// In-process capture: every record the callback would have received, in order.
    Capture(Arc<Mutex<Vec<LogRecord>>>),
}

/// The master's logger for one instance.
pub struct Logger {
    sink: LogSink,
    instance_name: CString,
    enabled: u32,
}

fn category_of(status: Status) -> usize {
    match status {
        Status::Ok | Status::Pending => 0,
        Status::Warning => 1,
        Status::Discard => 2,
        Status::Error => 3,
        Status::Fatal => 4,
    }
}

/// Make `text` safe to pass as a C string that some masters use as a printf format.
pub fn c_message(text: &str) -> CString {
    let escaped = text.replace('%', "%%").replace('\0', " ");
    CString::new(escaped).expect("NUL bytes were replaced")
}

impl Logger {
    pub fn new(
        callback: fmi2CallbackLogger,
        environment: fmi2ComponentEnvironment,
        instance_name: &str,
        logging_on: bool,
    ) -> Self {
        Self::with_sink(
            LogSink::Callback {
                callback,
                environment,
            },
            instance_name,
            logging_on,
        )
    }

    /// A logger that sends to `sink`; `logging_on` as `fmi2Instantiate`'s `loggingOn`.
    pub fn with_sink(sink: LogSink, instance_name: &str, logging_on: bool) -> Self {
        Logger {
            sink,
            instance_name: c_message(instance_name),
            enabled: if logging_on { ALL } else { ALWAYS },
        }
    }

    /// Where this logger sends its messages.
    pub fn sink(&self) -> &LogSink {
        &self.sink
    }

    /// Send `message` with `status` if its category is enabled.
    pub fn log(&self, status: Status, message: &str) {
        let cat = category_of(status);
        if self.enabled & (1 << cat) == 0 {
            return;
        }
        let text = c_message(message);
        match &self.sink {
            LogSink::Callback {
                callback,
                environment,
            } => {
                let Some(callback) = callback else {
                    return;
                };
                let category = CString::new(CATEGORIES[cat].0).expect("static name");
                // SAFETY: the master gave us this logger and promised it stays valid for the
                // instance's life.
                unsafe {
                    callback(
                        *environment,
                        self.instance_name.as_ptr(),
                        status.into(),
                        category.as_ptr(),
                        text.as_ptr(),
                    )
                }
            }
            LogSink::Capture(records) => {
                let record = LogRecord {
                    instance: self.instance_name.to_string_lossy().into_owned(),
                    status,
                    category: CATEGORIES[cat].0.to_owned(),
                    message: text.to_string_lossy().into_owned(),
                };
                // A panic contained while the lock was held leaves the records intact.
                records
                    .lock()
                    .unwrap_or_else(|e| e.into_inner())
                    .push(record);
            }
        }
    }

    /// `fmi2SetDebugLogging`: with no categories, switch all on or back to the default set.
    pub fn set_debug_logging(&mut self, on: bool, categories: &[String]) -> Result<(), String> {
        if categories.is_empty() {
            self.enabled = if on { ALL } else { ALWAYS };
            return Ok(());
        }
        let mut mask = 0;
        for name in categories {
            let i = CATEGORIES
                .iter()
                .position(|(n, _)| n == name)
                .ok_or_else(|| format!("unknown log category '{name}'"))?;
            mask |= if i == CATEGORIES.len() - 1 {
                ALL
            } else {
                1 << i
            };
        }
        if on {
            self.enabled |= mask;
        } else {
            self.enabled &= !mask;
        }
        Ok(())
    }
}

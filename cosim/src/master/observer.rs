//! Observers of a run: what the master hands each communication point to (CSV file, progress,
//! an in-memory table), so that a new output never touches the simulate loop.

use super::Error;
use crate::table::{write_header, write_row, Table};
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What a run is, as observers see it before the first sample.
#[derive(Debug, Clone)]
pub struct RunInfo<'a> {
    /// The system's name.
    pub system: &'a str,
    /// `time`, then `component.variable` of every recorded output.
    pub columns: &'a [String],
    /// Start and stop time, s.
    pub start: f64,
    pub stop: f64,
}

/// How a run ended.
#[derive(Debug, Clone, PartialEq)]
pub enum End {
    /// It reached the stop time.
    Completed,
    /// A signal (SIGINT, SIGTERM) stopped it at the communication point `at`, s.
    Interrupted { signal: i32, at: f64 },
    /// An error stopped it; `at` is the last communication point recorded, s.
    Failed { at: f64, error: String },
}

/// Receives the results of a run as they are produced.
pub trait Observer {
    /// Once, after initialization and before the first sample.
    fn start(&mut self, run: &RunInfo) -> Result<(), Error>;
    /// One communication point: `row[0]` is the time (s), then the columns' values.
    fn sample(&mut self, row: &[f64]) -> Result<(), Error>;
    /// Once, however the run ended (also after an error in `start` or `sample`).
    fn finish(&mut self, end: &End) -> Result<(), Error>;
}

/// The whole run in memory (tests, the demo's metrics): memory grows with the run's length.
#[derive(Debug, Default)]
pub struct Recorder {
    pub table: Table,
}

impl Observer for Recorder {
    fn start(&mut self, run: &RunInfo) -> Result<(), Error> {
        self.table.columns = run.columns.to_vec();
        Ok(())
    }

    fn sample(&mut self, row: &[f64]) -> Result<(), Error> {
        self.table.rows.push(row.to_vec());
        Ok(())
    }

    fn finish(&mut self, _: &End) -> Result<(), Error> {
        Ok(())
    }
}

/// The CSV file of a run, written as it goes through a buffer of whole rows.
///
/// Rows go to `<path>.partial` and the file is renamed to `path` only when the run completes:
/// a file named `path` is always a complete run, and a `.partial` file (left by an interrupted
/// or failed run) holds every complete row up to where the run stopped, never part of a row: rows
/// are written whole, and a write that fails part-way (a full disk, a file size limit) is cut
/// back to the last whole row. A run that stops before its first row leaves no file. An existing
/// file at `path` is replaced only by a complete run. A `path` that exists and is not a regular
/// file or directory (`/dev/null`, a named pipe) is written directly: renaming a file over it
/// would replace the device.
pub struct CsvWriter {
    path: PathBuf,
    partial: PathBuf,
    /// Written in place (a device or pipe), no `.partial`.
    direct: bool,
    file: Option<std::fs::File>,
    /// Whole rows (and the header) not yet written to the file.
    buf: Vec<u8>,
    /// Rows in `buf`.
    pending: u64,
    /// Bytes of the file that hold the header and whole rows.
    whole: u64,
    /// Rows in the file.
    rows: u64,
}

/// How many bytes of whole rows [`CsvWriter`] gathers before writing them.
const CSV_BUFFER: usize = 1 << 16;

impl CsvWriter {
    pub fn new(path: &Path) -> CsvWriter {
        let direct = std::fs::metadata(path).is_ok_and(|m| !m.is_file() && !m.is_dir());
        CsvWriter {
            path: path.to_path_buf(),
            partial: if direct {
                path.to_path_buf()
            } else {
                partial_path(path)
            },
            direct,
            file: None,
            buf: Vec::with_capacity(CSV_BUFFER + 4096),
            pending: 0,
            whole: 0,
            rows: 0,
        }
    }

    /// Rows written so far (complete rows, once the run has finished).
    pub fn rows(&self) -> u64 {
        self.rows + self.pending
    }

    fn io(&self, e: std::io::Error) -> Error {
        Error(format!("{}: {e}", self.partial.display()))
    }

    /// Write the buffered rows. On an error the file keeps only whole rows (cut back to the last
    /// complete one) and is closed: the rows not written are dropped.
    fn write_out(&mut self) -> Result<(), Error> {
        let Some(file) = self.file.as_mut() else {
            self.buf.clear();
            self.pending = 0;
            return Ok(());
        };
        let mut done = 0;
        let failure = loop {
            if done == self.buf.len() {
                break None;
            }
            match std::io::Write::write(file, &self.buf[done..]) {
                Ok(0) => break Some(std::io::Error::from(std::io::ErrorKind::WriteZero)),
                Ok(n) => done += n,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => break Some(e),
            }
        };
        let Some(e) = failure else {
            self.whole += done as u64;
            self.rows += self.pending;
            self.buf.clear();
            self.pending = 0;
            return Ok(());
        };
        // Keep the whole rows that made it; cut the torn one.
        let kept = self.buf[..done]
            .iter()
            .rposition(|&b| b == b'\n')
            .map_or(0, |p| p + 1);
        let rows = self.buf[..kept].iter().filter(|&&b| b == b'\n').count() as u64;
        let header = u64::from(self.whole == 0 && kept > 0);
        if !self.direct {
            let _ = file.set_len(self.whole + kept as u64);
        }
        self.whole += kept as u64;
        self.rows += rows - header;
        self.buf.clear();
        self.pending = 0;
        self.file = None;
        Err(self.io(e))
    }
}

/// Where [`CsvWriter`] keeps the rows of `path` until the run completes.
pub fn partial_path(path: &Path) -> PathBuf {
    let mut name = path.as_os_str().to_owned();
    name.push(".partial");
    PathBuf::from(name)
}

impl Observer for CsvWriter {
    fn start(&mut self, run: &RunInfo) -> Result<(), Error> {
        let file = if self.direct {
            std::fs::OpenOptions::new().write(true).open(&self.partial)
        } else {
            std::fs::File::create(&self.partial)
        }
        .map_err(|e| self.io(e))?;
        self.file = Some(file);
        write_header(&mut self.buf, run.columns).map_err(|e| self.io(e))?;
        Ok(())
    }

    fn sample(&mut self, row: &[f64]) -> Result<(), Error> {
        if self.file.is_none() {
            return Ok(());
        }
        write_row(&mut self.buf, row).map_err(|e| self.io(e))?;
        self.pending += 1;
        if self.buf.len() >= CSV_BUFFER {
            self.write_out()?;
        }
        Ok(())
    }

    fn finish(&mut self, end: &End) -> Result<(), Error> {
        // Whole rows only: the buffer holds nothing else.
        let written = self.write_out();
        let Some(file) = self.file.take() else {
            if self.rows == 0 && !self.direct {
                // A failed write left no row: no file either.
                let _ = std::fs::remove_file(&self.partial);
            }
            return written;
        };
        if self.direct {
            return Ok(());
        }
        file.sync_data().map_err(|e| self.io(e))?;
        drop(file);
        if *end != End::Completed && self.rows == 0 {
            // Nothing to keep: the run stopped before its first communication point.
            return std::fs::remove_file(&self.partial).map_err(|e| self.io(e));
        }
        if *end == End::Completed {
            std::fs::rename(&self.partial, &self.path).map_err(|e| {
                Error(format!(
                    "cannot rename {} to {}: {e}",
                    self.partial.display(),
                    self.path.display()
                ))
            })?;
        }
        Ok(())
    }
}

/// Progress on stderr: a line rewritten in place on a terminal, every 25 % otherwise.
pub struct Progress {
    name: String,
    start: f64,
    span: f64,
    shown: i32,
    terminal: bool,
    started: Instant,
}

impl Default for Progress {
    fn default() -> Self {
        Progress {
            name: String::new(),
            start: 0.0,
            span: 1.0,
            shown: 0,
            terminal: std::io::stderr().is_terminal(),
            started: Instant::now(),
        }
    }
}

impl Observer for Progress {
    fn start(&mut self, run: &RunInfo) -> Result<(), Error> {
        self.name = run.system.to_owned();
        self.start = run.start;
        self.span = run.stop - run.start;
        self.started = Instant::now();
        Ok(())
    }

    fn sample(&mut self, row: &[f64]) -> Result<(), Error> {
        let t = row[0];
        let percent = ((t - self.start) / self.span * 100.0) as i32;
        let every = if self.terminal { 1 } else { 25 };
        if percent >= self.shown + every {
            self.shown = percent - percent % every;
            let line = format!(
                "{}: {percent:3}% (t = {t:.3} s, {:.1} s wall)",
                self.name,
                self.started.elapsed().as_secs_f64()
            );
            if self.terminal {
                eprint!("\r{line}");
            } else {
                eprintln!("{line}");
            }
        }
        Ok(())
    }

    fn finish(&mut self, _: &End) -> Result<(), Error> {
        if self.terminal && self.shown > 0 {
            eprintln!();
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Read;
    use std::os::unix::fs::FileTypeExt;

    #[test]
    fn a_named_pipe_is_written_in_place_and_stays_a_pipe() {
        let dir = crate::tmp::TempDir::new("csv-fifo").unwrap();
        let fifo = dir.path().join("out.csv");
        let c = std::ffi::CString::new(fifo.as_os_str().as_encoded_bytes()).unwrap();
        // SAFETY: a valid NUL-terminated path.
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
        // The read end first, non-blocking, so that the writer's open does not wait and a
        // writer that replaced the pipe leaves it empty rather than hanging the test.
        let mut reader = {
            use std::os::unix::fs::OpenOptionsExt;
            std::fs::OpenOptions::new()
                .read(true)
                .custom_flags(libc::O_NONBLOCK)
                .open(&fifo)
                .unwrap()
        };
        let columns = ["time".to_string(), "a.y".to_string()];
        let info = RunInfo {
            system: "s",
            columns: &columns,
            start: 0.0,
            stop: 1.0,
        };
        let mut w = CsvWriter::new(&fifo);
        w.start(&info).unwrap();
        w.sample(&[0.0, 1.5]).unwrap();
        w.finish(&End::Completed).unwrap();
        let mut text = String::new();
        let _ = reader.read_to_string(&mut text);
        assert!(text.starts_with("time,a.y\n"), "{text}");
        assert_eq!(text.lines().count(), 2, "{text}");
        let kind = std::fs::symlink_metadata(&fifo).unwrap().file_type();
        assert!(kind.is_fifo(), "the pipe was replaced: {kind:?}");
        assert!(!partial_path(&fifo).exists());
    }
}

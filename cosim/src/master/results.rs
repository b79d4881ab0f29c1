//! Result files of a run (CSV, MATLAB v4 `.mat`) and the choice of what they record (signal
//! patterns, output interval).
//!
//! Both files are written as the run goes, through a buffer of whole rows, to a `.partial` file
//! of the run's own, renamed to `path` only when the run completes: a file named `path` is always
//! a complete run, and a `.partial` file (left by an interrupted or failed run) holds every
//! complete row up to where the run stopped, never part of a row. The `.partial` file is created
//! new (`O_EXCL`), as `<path>.partial` when that name is free and `<path>.<pid>-<n>.partial`
//! when it is taken (another run writing the same `path`, or rows an earlier run kept), so that
//! two runs never write one file and only the run that made it renames it
//! ([`ResultWriter::kept`] names it). A write that fails part-way (a full disk, a file size
//! limit) is cut back to the last whole row. A run that stops before its first row leaves no
//! file. An existing file at `path` is replaced only by a complete run. A CSV `path` that exists
//! and is not a regular file or directory (`/dev/null`, a named pipe) is written directly:
//! renaming a file over it would replace the device; a named pipe that nobody reads is refused
//! at once (opening it would wait for a reader), and a pipe whose reader stops reading does not
//! keep a signal from ending the run.

use super::{End, Error, Observer, RunInfo};
use crate::table::{write_header, write_row};
use std::fs::File;
use std::os::unix::fs::{FileExt, OpenOptionsExt};
use std::os::unix::io::AsRawFd;
use std::path::{Path, PathBuf};

/// How a result file lays out its header and rows.
pub trait Format {
    /// The bytes before the first row.
    fn header(&mut self, run: &RunInfo, out: &mut Vec<u8>);
    /// One row: the time, then the recorded values.
    fn row(&mut self, row: &[f64], out: &mut Vec<u8>);
    /// Of `bytes`, the start of a buffer that was only partly written (`header` bytes of it the
    /// header), the length that holds the header and whole rows, and how many rows that is.
    fn whole(&self, bytes: &[u8], header: usize) -> (usize, u64);
    /// Bring a file holding the header and `rows` rows up to date (the `.mat` row count), so
    /// that it reads as it is at any moment; `None` for a file written in place (a pipe).
    fn close(&mut self, file: Option<&File>, rows: u64) -> std::io::Result<()>;
    /// Whether the format can be written to a device or pipe (it never seeks).
    const STREAMS: bool;
}

/// Comma-separated values: a header of column names, one line per row, each number the
/// shortest text that reads back as the same `f64`.
#[derive(Debug, Default)]
pub struct Csv;

impl Format for Csv {
    const STREAMS: bool = true;

    fn header(&mut self, run: &RunInfo, out: &mut Vec<u8>) {
        // Writing into a Vec cannot fail.
        let _ = write_header(out, run.columns);
    }

    fn row(&mut self, row: &[f64], out: &mut Vec<u8>) {
        let _ = write_row(out, row);
    }

    fn whole(&self, bytes: &[u8], header: usize) -> (usize, u64) {
        let kept = bytes.iter().rposition(|&b| b == b'\n').map_or(0, |p| p + 1);
        let lines = bytes[..kept].iter().filter(|&&b| b == b'\n').count() as u64;
        (kept, lines - u64::from(header > 0 && kept >= header))
    }

    fn close(&mut self, _: Option<&File>, _: u64) -> std::io::Result<()> {
        Ok(())
    }
}

/// A MATLAB v4 result file as Modelica tools write it (the `binTrans` trajectory layout that
/// Dymola, OpenModelica and OMSimulator write and their readers, scipy's `loadmat` and MATLAB
/// read): `Aclass`, `name`, `description`, `dataInfo`, `data_1` (start and stop time) and
/// `data_2`, one column of `time, values…` per row. The row count in `data_2`'s header is
/// brought up to date after every write, so the file reads at any moment.
#[derive(Debug, Default)]
pub struct Mat {
    /// Byte offset of `data_2`'s column count.
    columns_at: u64,
    /// Bytes of the header (everything before the first row) and of one row.
    header_len: usize,
    row_len: usize,
}

/// MAT v4 type codes: little-endian IEEE, then the element type and the matrix class.
const MAT_F64: i32 = 0;
const MAT_I32: i32 = 20;
const MAT_TEXT: i32 = 51;

/// A MAT v4 matrix header: type, rows, columns, no imaginary part, the name.
fn mat_header(out: &mut Vec<u8>, kind: i32, rows: usize, cols: usize, name: &str) {
    for v in [kind, rows as i32, cols as i32, 0, name.len() as i32 + 1] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out.extend_from_slice(name.as_bytes());
    out.push(0);
}

/// A text matrix of `strings`, each a column of `width` bytes padded with spaces (MAT stores
/// matrices column by column, so each string is contiguous).
fn mat_strings(out: &mut Vec<u8>, name: &str, strings: &[&str]) {
    let width = strings.iter().map(|s| s.len()).max().unwrap_or(0).max(1);
    mat_header(out, MAT_TEXT, width, strings.len(), name);
    for s in strings {
        out.extend_from_slice(s.as_bytes());
        out.resize(out.len() + width - s.len(), b' ');
    }
}

impl Format for Mat {
    const STREAMS: bool = false;

    fn header(&mut self, run: &RunInfo, out: &mut Vec<u8>) {
        let start = out.len();
        // Aclass: 4 strings of 11 characters, stored row-interleaved (a 4 x 11 char matrix).
        let aclass = ["Atrajectory", "1.1", "", "binTrans"];
        mat_header(out, MAT_TEXT, 4, 11, "Aclass");
        for c in 0..11 {
            for s in aclass {
                out.push(*s.as_bytes().get(c).unwrap_or(&b' '));
            }
        }
        let names: Vec<&str> = run.columns.iter().map(String::as_str).collect();
        mat_strings(out, "name", &names);
        mat_strings(out, "description", &vec![""; names.len()]);
        // dataInfo: time is the abscissa (matrix 0); every value a row of data_2.
        mat_header(out, MAT_I32, 4, names.len(), "dataInfo");
        for k in 0..names.len() {
            let info: [i32; 4] = if k == 0 {
                [0, 1, 0, -1]
            } else {
                [2, k as i32 + 1, 0, -1]
            };
            for v in info {
                out.extend_from_slice(&v.to_le_bytes());
            }
        }
        mat_header(out, MAT_F64, 1, 2, "data_1");
        out.extend_from_slice(&run.start.to_le_bytes());
        out.extend_from_slice(&run.stop.to_le_bytes());
        self.columns_at = (out.len() - start + 8) as u64;
        mat_header(out, MAT_F64, names.len(), 0, "data_2");
        self.header_len = out.len() - start;
        self.row_len = 8 * names.len();
    }

    fn row(&mut self, row: &[f64], out: &mut Vec<u8>) {
        out.reserve(8 * row.len());
        for x in row {
            out.extend_from_slice(&x.to_le_bytes());
        }
    }

    fn whole(&self, bytes: &[u8], header: usize) -> (usize, u64) {
        if bytes.len() < header {
            return (0, 0);
        }
        let rows = (bytes.len() - header) / self.row_len.max(1);
        (header + rows * self.row_len, rows as u64)
    }

    fn close(&mut self, file: Option<&File>, rows: u64) -> std::io::Result<()> {
        let Some(file) = file else {
            return Ok(());
        };
        let rows = i32::try_from(rows).map_err(|_| {
            std::io::Error::other("more rows than a MAT v4 matrix holds (2^31 - 1)")
        })?;
        file.write_all_at(&rows.to_le_bytes(), self.columns_at)
    }
}

/// A result file of format `F`, written as the run goes (see the module documentation).
///
/// The run's thread only copies each row into a chunk; a writer thread of the file's own turns
/// full chunks into bytes (CSV text or `.mat` doubles) and writes them, so that formatting and
/// the kernel's copying overlap the simulation on another core. At most `CHUNKS` chunks wait
/// for it (then the run waits). A write error stops the writer; the run sees it at its next
/// row and ends with it.
pub struct ResultWriter<F: Format + Send + 'static> {
    path: PathBuf,
    /// The file the rows go to: this writer's own `.partial` file once created (`path` itself
    /// when written in place; before [`Observer::start`], the name it tries first).
    partial: PathBuf,
    /// Whether `partial` exists and holds this run's rows (created, not yet renamed or removed).
    holds: bool,
    /// Written in place (a device or pipe), no `.partial`.
    direct: bool,
    /// The format until the writer thread takes it.
    format: Option<F>,
    writer: Option<Writer<F>>,
    /// Rows of the current chunk and their values, row after row.
    chunk: Vec<f64>,
    chunk_rows: usize,
    /// Chunks made so far (they circulate between the run and the writer thread).
    chunks: usize,
    /// Values per row.
    width: usize,
    /// Rows handed to the writer thread, and (once finished) rows in the file.
    rows: u64,
}

/// The writer thread of a [`ResultWriter`] and its channels.
struct Writer<F: Format> {
    chunks: std::sync::mpsc::SyncSender<Vec<f64>>,
    empty: std::sync::mpsc::Receiver<Vec<f64>>,
    failed: std::sync::Arc<std::sync::Mutex<Option<Error>>>,
    thread: std::thread::JoinHandle<Sink<F>>,
}

/// What the writer thread owns: the file and its bytes.
struct Sink<F: Format> {
    format: F,
    partial: PathBuf,
    direct: bool,
    file: Option<File>,
    /// The header (until written) and whole rows not yet written to the file.
    buf: Vec<u8>,
    /// Header bytes at the start of `buf`, 0 once written.
    header: usize,
    /// Rows in `buf`.
    pending: u64,
    /// Bytes of the file that hold the header and whole rows.
    whole: u64,
    /// Rows in the file.
    rows: u64,
}

/// The CSV file of a run.
pub type CsvWriter = ResultWriter<Csv>;
/// The MATLAB v4 `.mat` file of a run.
pub type MatWriter = ResultWriter<Mat>;

/// How many bytes of whole rows the writer thread gathers before writing them.
const BUFFER: usize = 1 << 16;
/// Values in a chunk of rows (at least one row): 1 MiB.
const CHUNK: usize = 1 << 17;
/// Chunks that may wait for the writer thread.
const CHUNKS: usize = 4;

impl<F: Format + Send + Default + 'static> ResultWriter<F> {
    pub fn new(path: &Path) -> ResultWriter<F> {
        let direct = std::fs::metadata(path).is_ok_and(|m| !m.is_file() && !m.is_dir());
        ResultWriter {
            path: path.to_path_buf(),
            partial: if direct {
                path.to_path_buf()
            } else {
                partial_path(path)
            },
            holds: false,
            direct,
            format: Some(F::default()),
            writer: None,
            chunk: Vec::new(),
            chunk_rows: 0,
            chunks: 1,
            width: 0,
            rows: 0,
        }
    }
}

impl<F: Format + Send + 'static> ResultWriter<F> {
    /// Rows written so far (complete rows in the file, once the run has finished).
    pub fn rows(&self) -> u64 {
        self.rows + self.chunk_rows as u64
    }

    fn io(&self, e: std::io::Error) -> Error {
        Error::Output(format!("{}: {e}", self.partial.display()))
    }

    /// The file that holds the rows of a run that has not completed (interrupted, failed or
    /// still going): this writer's own `.partial` file, or `path` when written in place; `None`
    /// when there is no such file (not started, no row kept, or renamed to `path` on
    /// completion). Messages about the rows a run kept name this file.
    pub fn kept(&self) -> Option<&Path> {
        (self.holds || (self.direct && self.rows() > 0)).then_some(self.partial.as_path())
    }

    /// Hand the current chunk to the writer thread (and take an empty one back); the writer's
    /// error, if it had one.
    fn hand_over(&mut self) -> Result<(), Error> {
        let Some(w) = self.writer.as_ref() else {
            return Ok(());
        };
        if let Some(e) = w.failed.lock().map_or(None, |f| f.clone()) {
            return Err(e);
        }
        if self.chunk_rows == 0 {
            return Ok(());
        }
        // The chunks circulate: a fresh one only while fewer than CHUNKS + 1 exist, then wait
        // for the writer to hand one back (memory stays bounded, pages stay mapped).
        let next = match w.empty.try_recv() {
            Ok(c) => c,
            Err(_) if self.chunks < CHUNKS + 1 => {
                self.chunks += 1;
                Vec::with_capacity(self.chunk.capacity())
            }
            Err(_) => match w.empty.recv() {
                Ok(c) => c,
                Err(_) => {
                    return Err(w
                        .failed
                        .lock()
                        .map_or(None, |f| f.clone())
                        .unwrap_or_else(|| {
                            Error::Output(format!("{}: the writer stopped", self.partial.display()))
                        }))
                }
            },
        };
        let full = std::mem::replace(&mut self.chunk, next);
        self.rows += self.chunk_rows as u64;
        self.chunk_rows = 0;
        if w.chunks.send(full).is_err() {
            // The thread ended: it failed and said why.
            return Err(w
                .failed
                .lock()
                .map_or(None, |f| f.clone())
                .unwrap_or_else(|| {
                    Error::Output(format!("{}: the writer stopped", self.partial.display()))
                }));
        }
        Ok(())
    }
}

impl<F: Format> Sink<F> {
    fn io(&self, e: std::io::Error) -> Error {
        Error::Output(format!("{}: {e}", self.partial.display()))
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
                // A pipe or device opened non-blocking whose reader is not reading.
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                    if let Err(e) = wait_writable(file) {
                        break Some(e);
                    }
                }
                Err(e) => break Some(e),
            }
        };
        let (kept, rows) = match failure {
            None => (done, self.pending),
            Some(_) => self.format.whole(&self.buf[..done], self.header),
        };
        if failure.is_some() && !self.direct {
            let _ = file.set_len(self.whole + kept as u64);
        }
        self.whole += kept as u64;
        self.rows += rows;
        if kept >= self.header {
            self.header = 0;
        }
        self.buf.clear();
        self.pending = 0;
        let closed = match self.direct || self.whole == 0 {
            true => Ok(()),
            false => self.format.close(self.file.as_ref(), self.rows),
        };
        if let Some(e) = failure {
            self.file = None;
            return Err(self.io(e));
        }
        closed.map_err(|e| self.io(e))
    }

    /// The writer thread: format and write each chunk of `width`-value rows as it comes; on
    /// an error, record it and stop.
    fn run(
        mut self,
        width: usize,
        chunks: std::sync::mpsc::Receiver<Vec<f64>>,
        empty: std::sync::mpsc::SyncSender<Vec<f64>>,
        failed: std::sync::Arc<std::sync::Mutex<Option<Error>>>,
    ) -> Sink<F> {
        let mut result = Ok(());
        for mut chunk in chunks.iter() {
            for row in chunk.chunks_exact(width) {
                self.format.row(row, &mut self.buf);
                self.pending += 1;
                if self.buf.len() >= BUFFER {
                    result = self.write_out();
                    if result.is_err() {
                        break;
                    }
                }
            }
            if result.is_err() {
                break;
            }
            chunk.clear();
            let _ = empty.try_send(chunk);
        }
        if result.is_ok() {
            result = self.write_out();
        }
        if let Err(e) = result {
            if let Ok(mut f) = failed.lock() {
                *f = Some(e);
            }
        }
        self
    }
}

/// Wait until `file` (a pipe or device written non-blocking) takes more bytes; an error when a
/// signal asks the run to stop first (the reader may never read again).
fn wait_writable(file: &File) -> std::io::Result<()> {
    loop {
        let mut fd = libc::pollfd {
            fd: file.as_raw_fd(),
            events: libc::POLLOUT,
            revents: 0,
        };
        // SAFETY: one valid pollfd, for 100 ms at most.
        let n = unsafe { libc::poll(&mut fd, 1, 100) };
        if n > 0 {
            return Ok(());
        }
        if let Some(signal) = crate::interrupt::requested() {
            return Err(std::io::Error::other(format!(
                "stopped by signal {signal} while the reader was not reading"
            )));
        }
        if n < 0 {
            let e = std::io::Error::last_os_error();
            if e.kind() != std::io::ErrorKind::Interrupted {
                return Err(e);
            }
        }
    }
}

/// The name a [`ResultWriter`] tries first for the rows of `path` until the run completes,
/// `<path>.partial` (when it is taken, [`create_partial`] takes another).
fn partial_path(path: &Path) -> PathBuf {
    let mut name = path.as_os_str().to_owned();
    name.push(".partial");
    PathBuf::from(name)
}

/// `<path>.<pid>-<n>.partial`.
fn numbered_partial(path: &Path, n: u32) -> PathBuf {
    let mut name = path.as_os_str().to_owned();
    name.push(format!(".{}-{n}.partial", std::process::id()));
    PathBuf::from(name)
}

/// Create, new (`O_EXCL`: never an existing file, never through a link), the file that keeps
/// the rows of `path` until the run completes: `<path>.partial` when that name is free, else
/// the first free `<path>.<pid>-<n>.partial`. No other run, and no other writer of this one,
/// can have the same file. An error names the first name tried.
fn create_partial(path: &Path) -> std::io::Result<(PathBuf, File)> {
    let first = partial_path(path);
    let candidates =
        std::iter::once(first.clone()).chain((1..=1000).map(|n| numbered_partial(path, n)));
    for name in candidates {
        match std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .mode(0o644)
            .open(&name)
        {
            Ok(file) => return Ok((name, file)),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
            Err(e) => return Err(e),
        }
    }
    Err(std::io::Error::new(
        std::io::ErrorKind::AlreadyExists,
        format!(
            "{} and 1000 numbered names beside it are taken",
            first.display()
        ),
    ))
}

/// Open the device or pipe `path` for writing in place without waiting: a named pipe with no
/// reader is refused at once (a blocking open would wait for one, deaf to signals).
fn open_direct(path: &Path) -> Result<File, Error> {
    std::fs::OpenOptions::new()
        .write(true)
        .custom_flags(libc::O_NONBLOCK)
        .open(path)
        .map_err(|e| {
            Error::Output(if e.raw_os_error() == Some(libc::ENXIO) {
                format!(
                    "{}: a named pipe that nothing reads; refused (start its reader first)",
                    path.display()
                )
            } else {
                format!("{}: {e}", path.display())
            })
        })
}

impl<F: Format + Send + 'static> Observer for ResultWriter<F> {
    fn start(&mut self, run: &RunInfo) -> Result<(), Error> {
        if self.direct && !F::STREAMS {
            return Err(Error::Output(format!(
                "{}: a .mat result is patched as it grows and needs a regular file, not a device or pipe",
                self.path.display()
            )));
        }
        let mut format = self
            .format
            .take()
            .ok_or_else(|| Error::Output(format!("{}: started twice", self.path.display())))?;
        let file = if self.direct {
            open_direct(&self.partial)?
        } else {
            let (name, file) = create_partial(&self.path).map_err(|e| self.io(e))?;
            self.partial = name;
            self.holds = true;
            file
        };
        let mut buf = Vec::with_capacity(BUFFER + 4096);
        format.header(run, &mut buf);
        let sink = Sink {
            format,
            partial: self.partial.clone(),
            direct: self.direct,
            file: Some(file),
            header: buf.len(),
            buf,
            pending: 0,
            whole: 0,
            rows: 0,
        };
        self.width = run.columns.len().max(1);
        self.chunk = Vec::with_capacity(CHUNK.max(self.width));
        let (chunks, inbox) = std::sync::mpsc::sync_channel(CHUNKS);
        let (recycle, empty) = std::sync::mpsc::sync_channel(CHUNKS + 2);
        let failed = std::sync::Arc::new(std::sync::Mutex::new(None));
        let (width, flag) = (self.width, failed.clone());
        let thread = std::thread::Builder::new()
            .name("results".into())
            .spawn(move || sink.run(width, inbox, recycle, flag))
            .map_err(|e| {
                Error::Output(format!(
                    "cannot start the writer of {}: {e}",
                    self.path.display()
                ))
            })?;
        self.writer = Some(Writer {
            chunks,
            empty,
            failed,
            thread,
        });
        Ok(())
    }

    fn sample(&mut self, row: &[f64]) -> Result<(), Error> {
        if self.writer.is_none() {
            return Ok(());
        }
        self.chunk.extend_from_slice(row);
        self.chunk_rows += 1;
        if self.chunk.len() + self.width > self.chunk.capacity() {
            self.hand_over()?;
        }
        Ok(())
    }

    fn finish(&mut self, end: &End) -> Result<(), Error> {
        let handed = self.hand_over();
        let Some(w) = self.writer.take() else {
            return handed;
        };
        drop(w.chunks);
        let sink = w.thread.join().map_err(|_| {
            Error::Output(format!(
                "{}: the writer thread panicked",
                self.partial.display()
            ))
        })?;
        self.rows = sink.rows;
        self.chunk_rows = 0;
        let failure = w.failed.lock().map_or(None, |f| f.clone());
        let Some(file) = sink.file else {
            if self.rows == 0 && !self.direct {
                // A failed write left no row: no file either.
                if std::fs::remove_file(&self.partial).is_ok() {
                    self.holds = false;
                }
            }
            return Err(
                failure.unwrap_or_else(|| handed.err().unwrap_or(Error::Output(String::new())))
            );
        };
        if let Some(e) = failure {
            return Err(e);
        }
        handed?;
        if self.direct {
            return Ok(());
        }
        // No fsync: the name is given to a complete file (the rename is atomic); flushing it to
        // the disk is the kernel's business, and would cost a run that writes tens of MB as
        // much as its simulation.
        drop(file);
        if *end != End::Completed && self.rows == 0 {
            // Nothing to keep: the run stopped before its first communication point.
            std::fs::remove_file(&self.partial).map_err(|e| self.io(e))?;
            self.holds = false;
            return Ok(());
        }
        if *end == End::Completed {
            // Our own file (created new), so the rows named `path` are this run's, whole.
            std::fs::rename(&self.partial, &self.path).map_err(|e| {
                Error::Output(format!(
                    "cannot rename {} to {}: {e}",
                    self.partial.display(),
                    self.path.display()
                ))
            })?;
            self.holds = false;
        }
        Ok(())
    }
}

/// What a run records: outputs by pattern and an output interval.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Record {
    /// `component.variable` patterns, `*` matching any run of characters (`grid.pcc.*`,
    /// `*.p`); empty records every output; `None` the system's default set
    /// ([`RunInfo::record`]). A pattern, given or the system's, that matches no output is an
    /// error.
    pub patterns: Option<Vec<String>>,
    /// Record at this interval, s: a whole multiple of the communication step (`None`: each
    /// communication point).
    pub interval: Option<f64>,
}

impl Record {
    /// Patterns from a comma-separated list (`all` for every output).
    pub fn parse(list: &str) -> Record {
        let patterns: Vec<String> = list
            .split(',')
            .map(str::trim)
            .filter(|p| !p.is_empty())
            .map(String::from)
            .collect();
        Record {
            patterns: Some(if patterns.iter().any(|p| p == "all") {
                Vec::new()
            } else {
                patterns
            }),
            interval: None,
        }
    }

    /// The system's default set, at every point.
    pub fn system_default() -> Record {
        Record {
            patterns: None,
            interval: None,
        }
    }

    /// Every how many communication points of `step` s a point is recorded.
    fn every(&self, step: f64) -> Result<u64, Error> {
        let Some(interval) = self.interval else {
            return Ok(1);
        };
        let ratio = interval / step;
        let every = ratio.round();
        if !(interval > 0.0 && interval.is_finite())
            || every < 1.0
            || (ratio - every).abs() > 1e-9 * ratio
        {
            return Err(Error::Output(format!(
                "output interval {interval} s is not a whole multiple of the communication step {step} s"
            )));
        }
        Ok(every as u64)
    }

    /// Whether every output is recorded at every point.
    pub fn is_all(&self) -> bool {
        self.patterns.as_ref().is_some_and(Vec::is_empty) && self.interval.is_none()
    }
}

/// Whether `name` matches `pattern`, where `*` matches any run of characters.
pub fn matches(pattern: &str, name: &str) -> bool {
    let mut parts = pattern.split('*');
    let first = parts.next().unwrap_or("");
    let Some(mut rest) = name.strip_prefix(first) else {
        return false;
    };
    let parts: Vec<&str> = parts.collect();
    let Some((last, middle)) = parts.split_last() else {
        return rest.is_empty();
    };
    for p in middle {
        match rest.find(p) {
            Some(at) => rest = &rest[at + p.len()..],
            None => return false,
        }
    }
    rest.len() >= last.len() && rest.ends_with(last)
}

/// An observer that hands `inner` only the recorded columns at the recorded points.
pub struct Select<O: Observer> {
    pub inner: O,
    record: Record,
    /// Indices of the recorded columns in a full row, time first.
    keep: Vec<usize>,
    columns: Vec<String>,
    every: u64,
    seen: u64,
    row: Vec<f64>,
}

impl<O: Observer> Select<O> {
    /// The recorded columns, time first (once started).
    pub fn columns(&self) -> &[String] {
        &self.columns
    }

    pub fn new(inner: O, record: Record) -> Select<O> {
        Select {
            inner,
            record,
            keep: Vec::new(),
            columns: Vec::new(),
            every: 1,
            seen: 0,
            row: Vec::new(),
        }
    }
}

impl<O: Observer> Observer for Select<O> {
    fn start(&mut self, run: &RunInfo) -> Result<(), Error> {
        self.every = self.record.every(run.step)?;
        let (p, whose) = match &self.record.patterns {
            Some(p) => (p.as_slice(), ""),
            None => (run.record, " of the system's record annotation"),
        };
        self.keep = (0..run.columns.len())
            .filter(|&k| k == 0 || p.is_empty() || p.iter().any(|p| matches(p, &run.columns[k])))
            .collect();
        let unmatched = p
            .iter()
            .find(|p| !run.columns[1..].iter().any(|c| matches(p, c)));
        // A pattern of the system's own is held to what `--record` is: one that matches
        // nothing is a mistake in the system (a renamed component or variable), not silence.
        if let Some(none) = unmatched {
            return Err(Error::Output(format!(
                "record pattern '{none}'{whose} matches no output of {} (outputs are named component.variable, e.g. {})",
                run.system,
                run.columns.get(1).map_or("", String::as_str)
            )));
        }
        self.columns = self.keep.iter().map(|&k| run.columns[k].clone()).collect();
        self.inner.start(&RunInfo {
            columns: &self.columns,
            ..run.clone()
        })
    }

    fn sample(&mut self, row: &[f64]) -> Result<(), Error> {
        let due = self.seen.is_multiple_of(self.every);
        self.seen += 1;
        if !due {
            return Ok(());
        }
        if self.keep.len() == row.len() {
            // Every column: the row as it is.
            return self.inner.sample(row);
        }
        self.row.clear();
        self.row.extend(self.keep.iter().map(|&k| row[k]));
        self.inner.sample(&self.row)
    }

    fn finish(&mut self, end: &End) -> Result<(), Error> {
        self.inner.finish(end)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Read;
    use std::os::unix::fs::FileTypeExt;

    fn info(columns: &[String]) -> RunInfo<'_> {
        RunInfo {
            system: "s",
            columns,
            start: 0.0,
            stop: 1.0,
            step: 0.001,
            record: &[],
        }
    }

    #[test]
    fn patterns_match_as_globs() {
        assert!(matches("grid.pcc.*", "grid.pcc.f"));
        assert!(matches("*.p", "wind.p"));
        assert!(!matches("*.p", "wind.p_set"));
        assert!(matches("*.p*", "wind.p_set"));
        assert!(matches("operator.ref.*", "operator.ref.df"));
        assert!(matches("a*b*c", "a.x.b.y.c"));
        assert!(!matches("a*b*c", "a.x.c.y.b"));
        assert!(matches("wind.p", "wind.p"));
        assert!(!matches("wind.p", "wind.pp"));
    }

    #[test]
    fn a_selection_keeps_time_the_matching_columns_and_every_nth_point() {
        let columns: Vec<String> = ["time", "a.p", "a.q", "b.p"].map(String::from).to_vec();
        let record = Record {
            interval: Some(0.002),
            ..Record::parse("*.p")
        };
        let mut s = Select::new(crate::master::Recorder::default(), record);
        s.start(&info(&columns)).unwrap();
        for k in 0..5 {
            let t = k as f64 * 1e-3;
            s.sample(&[t, 1.0 + t, 2.0, 3.0 + t]).unwrap();
        }
        s.finish(&End::Completed).unwrap();
        assert_eq!(s.inner.table.columns, ["time", "a.p", "b.p"]);
        let times: Vec<f64> = s.inner.table.rows.iter().map(|r| r[0]).collect();
        assert_eq!(times, [0.0, 0.002, 0.004]);
    }

    #[test]
    fn a_pattern_that_matches_nothing_and_a_fractional_interval_are_refused() {
        let columns: Vec<String> = ["time", "a.p"].map(String::from).to_vec();
        let mut s = Select::new(crate::master::Recorder::default(), Record::parse("grid.*"));
        let e = s.start(&info(&columns)).unwrap_err();
        assert!(e.to_string().contains("'grid.*' matches no output"), "{e}");
        let fraction = Record {
            interval: Some(0.0015),
            ..Record::parse("all")
        };
        let e = Select::new(crate::master::Recorder::default(), fraction)
            .start(&info(&columns))
            .unwrap_err();
        assert!(e.to_string().contains("not a whole multiple"), "{e}");
        assert!(Record::parse("all, *.p").is_all());
        // The system's default set is held to the same rule, in the same words, saying whose
        // the pattern is (it was dropped silently).
        let default = ["*.p".to_string(), "operator.*".to_string()];
        let mut s = Select::new(crate::master::Recorder::default(), Record::system_default());
        let e = s
            .start(&RunInfo {
                record: &default,
                ..info(&columns)
            })
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("record pattern 'operator.*' of the system's record annotation matches no output of s"),
            "{e}"
        );
        let default = ["*.p".to_string()];
        let mut s = Select::new(crate::master::Recorder::default(), Record::system_default());
        s.start(&RunInfo {
            record: &default,
            ..info(&columns)
        })
        .unwrap();
        assert_eq!(s.inner.table.columns, ["time", "a.p"]);
    }

    /// `data_2` of a `.mat` file as rows (time first), read back by hand.
    fn mat_rows(bytes: &[u8], width: usize) -> (i32, Vec<Vec<f64>>) {
        let Some(at) = bytes.windows(7).position(|w| w == b"data_2\0") else {
            // Not written yet.
            return (0, Vec::new());
        };
        let header = at - 20;
        let cols = i32::from_le_bytes(bytes[header + 8..header + 12].try_into().unwrap());
        let data = &bytes[at + 7..];
        let rows = data
            .chunks_exact(8 * width)
            .map(|r| {
                r.chunks_exact(8)
                    .map(|b| f64::from_le_bytes(b.try_into().unwrap()))
                    .collect()
            })
            .collect();
        (cols, rows)
    }

    #[test]
    fn a_mat_file_counts_its_rows_while_it_grows_and_keeps_the_partial_name_on_interrupt() {
        let dir = crate::tmp::TempDir::new("mat").unwrap();
        let path = dir.path().join("r.mat");
        let columns: Vec<String> = ["time", "a.p"].map(String::from).to_vec();
        let mut w = MatWriter::new(&path);
        w.start(&info(&columns)).unwrap();
        // Enough rows to fill the buffer several times.
        let n = 3 * CHUNK / 2 + 7;
        for k in 0..n {
            w.sample(&[k as f64, -(k as f64)]).unwrap();
        }
        let partial = w.kept().expect("the run's own .partial file").to_path_buf();
        assert_eq!(
            partial,
            partial_path(&path),
            "the name is free: the plain one"
        );
        // The writer thread writes as the chunks come: wait for rows on disk.
        let since = std::time::Instant::now();
        let (cols, rows) = loop {
            let (cols, rows) = mat_rows(&std::fs::read(&partial).unwrap(), 2);
            if cols > 0 || since.elapsed().as_secs() > 10 {
                break (cols, rows);
            }
            std::thread::sleep(std::time::Duration::from_millis(5));
        };
        assert!(cols > 0, "no row on disk while the run goes");
        assert!(
            rows.len() >= cols as usize,
            "the header counts rows on disk"
        );
        w.finish(&End::Interrupted { signal: 2, at: 1.0 }).unwrap();
        assert!(!path.exists());
        let (cols, rows) = mat_rows(&std::fs::read(&partial).unwrap(), 2);
        assert_eq!((cols as usize, rows.len()), (n, n));
        assert_eq!(rows[n - 1], [(n - 1) as f64, -((n - 1) as f64)]);
    }

    #[test]
    fn a_mat_result_refuses_a_pipe() {
        let dir = crate::tmp::TempDir::new("mat-fifo").unwrap();
        let fifo = dir.path().join("out.mat");
        let c = std::ffi::CString::new(fifo.as_os_str().as_encoded_bytes()).unwrap();
        // SAFETY: a valid NUL-terminated path.
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
        let columns: Vec<String> = ["time", "a.p"].map(String::from).to_vec();
        let e = MatWriter::new(&fifo).start(&info(&columns)).unwrap_err();
        assert!(e.to_string().contains("needs a regular file"), "{e}");
    }

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
        let mut w = CsvWriter::new(&fifo);
        w.start(&info(&columns)).unwrap();
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

    #[test]
    fn a_named_pipe_that_nothing_reads_is_refused_at_once() {
        let dir = crate::tmp::TempDir::new("csv-fifo-no-reader").unwrap();
        let fifo = dir.path().join("out.csv");
        let c = std::ffi::CString::new(fifo.as_os_str().as_encoded_bytes()).unwrap();
        // SAFETY: a valid NUL-terminated path.
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
        let columns = ["time".to_string(), "a.y".to_string()];
        let started = std::time::Instant::now();
        let mut w = CsvWriter::new(&fifo);
        let e = w.start(&info(&columns)).unwrap_err().to_string();
        assert!(started.elapsed() < std::time::Duration::from_secs(5));
        assert!(
            e.contains(&fifo.display().to_string()) && e.contains("named pipe that nothing reads"),
            "{e}"
        );
        assert!(!e.contains('\n'), "{e}");
        w.finish(&End::Failed {
            at: 0.0,
            error: e.clone(),
        })
        .unwrap();
        assert_eq!(w.kept(), None, "no file holds rows");
    }

    /// The rows of a CSV file as text lines after the header, each checked whole.
    fn csv_times(path: &Path) -> Vec<f64> {
        let text = std::fs::read_to_string(path).unwrap();
        assert!(text.ends_with('\n'), "{} ends in a cut row", path.display());
        let mut lines = text.lines();
        assert_eq!(lines.next(), Some("time,a.y"));
        lines
            .map(|l| {
                let (t, y) = l.split_once(',').expect("two fields");
                let (t, y): (f64, f64) = (t.parse().unwrap(), y.parse().unwrap());
                assert_eq!(y, 2.0 * t, "{l}");
                t
            })
            .collect()
    }

    /// Two runs writing one `--out` (here two writers of one process, as two processes do):
    /// each keeps its rows in a file of its own, the completed one renames its own file, and
    /// the interrupted one names a file that exists and holds its rows, whole.
    #[test]
    fn two_writers_of_one_path_never_share_a_file() {
        let dir = crate::tmp::TempDir::new("csv-two-runs").unwrap();
        let path = dir.path().join("out.csv");
        let columns = ["time".to_string(), "a.y".to_string()];
        let (n_a, n_b) = (3 * CHUNK / 2 + 11, CHUNK + 5);
        let mut a = CsvWriter::new(&path);
        let mut b = CsvWriter::new(&path);
        a.start(&info(&columns)).unwrap();
        b.start(&info(&columns)).unwrap();
        let (pa, pb) = (
            a.kept().unwrap().to_path_buf(),
            b.kept().unwrap().to_path_buf(),
        );
        assert_ne!(pa, pb);
        assert!(
            pb.to_str().unwrap().ends_with(".partial"),
            "{}",
            pb.display()
        );
        for k in 0..n_a.max(n_b) {
            // Run B's times are negative: a row of one run in the other's file would show.
            if k < n_a {
                a.sample(&[k as f64, 2.0 * k as f64]).unwrap();
            }
            if k < n_b {
                b.sample(&[-(k as f64), -2.0 * k as f64]).unwrap();
            }
        }
        a.finish(&End::Completed).unwrap();
        b.finish(&End::Interrupted { signal: 2, at: 1.0 }).unwrap();
        assert_eq!(a.kept(), None, "renamed to the final name");
        assert!(!pa.exists());
        let times = csv_times(&path);
        assert_eq!(times, (0..n_a).map(|k| k as f64).collect::<Vec<_>>());
        assert_eq!(b.kept(), Some(pb.as_path()));
        let times = csv_times(&pb);
        assert_eq!(times, (0..n_b).map(|k| -(k as f64)).collect::<Vec<_>>());

        // Both complete: the file is one run's rows, whole, and no .partial file is left.
        std::fs::remove_file(&pb).unwrap();
        let mut a = CsvWriter::new(&path);
        let mut b = CsvWriter::new(&path);
        a.start(&info(&columns)).unwrap();
        b.start(&info(&columns)).unwrap();
        for k in 0..n_b {
            a.sample(&[k as f64, 2.0 * k as f64]).unwrap();
            b.sample(&[-(k as f64), -2.0 * k as f64]).unwrap();
        }
        b.finish(&End::Completed).unwrap();
        a.finish(&End::Completed).unwrap();
        let times = csv_times(&path);
        assert_eq!(times, (0..n_b).map(|k| k as f64).collect::<Vec<_>>());
        let left: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(left, ["out.csv"]);
    }

    #[test]
    fn a_run_that_keeps_no_row_names_no_file() {
        let dir = crate::tmp::TempDir::new("csv-no-row").unwrap();
        let path = dir.path().join("out.csv");
        let columns = ["time".to_string(), "a.y".to_string()];
        let mut w = CsvWriter::new(&path);
        w.start(&info(&columns)).unwrap();
        assert!(w.kept().is_some_and(Path::exists));
        w.finish(&End::Interrupted {
            signal: 15,
            at: 0.0,
        })
        .unwrap();
        assert_eq!(w.kept(), None);
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }
}

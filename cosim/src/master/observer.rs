//! Observers of a run: what the master hands each communication point to (result files in
//! `results`, progress, an in-memory table), so that a new output never touches the simulate loop.

use super::Error;
use crate::table::Table;
use std::io::IsTerminal;
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
    /// Communication step, s.
    pub step: f64,
    /// The `component.variable` patterns the system records by default (its SSP's record
    /// annotation; empty: every output), for [`super::Select`]; each must match an output.
    pub record: &'a [String],
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

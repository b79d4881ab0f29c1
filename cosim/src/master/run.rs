//! A run of a loaded system: observers started, initialization, the loop of samples and
//! communication steps to the stop time (or a signal, or an error), and how it went.

use super::coupling::Direct;
use super::pool::Pool;
use super::results::{Record, Select};
use super::system::{Builder, System};
use super::unit::Phase;
use super::{Algorithm, Coupling, End, Error, Observer, Options, Recorder, RunInfo};
use crate::interrupt;
use crate::table::{seconds, Table};

/// How a run went: how it ended, its warnings (also printed to stderr as they happen) and
/// where the time went.
#[derive(Debug, Clone)]
pub struct Outcome {
    pub end: End,
    pub warnings: Vec<String>,
    /// Communication points recorded (the initial one included).
    pub samples: u64,
    /// Simulated time, s.
    pub simulated: f64,
    /// Recorded outputs (columns besides `time`).
    pub columns: usize,
    /// Wall time of reading the system and loading its FMUs, and of initializing and stepping.
    pub load_time: std::time::Duration,
    pub run_time: std::time::Duration,
    /// Of `run_time`, the steps and samples after initialization ([`System::advance_time`]).
    pub advance_time: std::time::Duration,
    /// Components, and the libraries they run in (fewer when identical binaries are shared).
    pub units: usize,
    pub libraries: usize,
    /// Threads that stepped the units.
    pub threads: usize,
}

impl Builder<'_> {
    /// Load the system and simulate it, handing every communication point to `observers`.
    ///
    /// `Err` when the system cannot be loaded or its experiment is invalid (no observer has
    /// started then); a run that starts returns `Ok` with [`Outcome::end`] saying how it ended.
    pub fn run(
        mut self,
        opts: &Options,
        observers: &mut [&mut dyn Observer],
    ) -> Result<Outcome, Error> {
        let started = std::time::Instant::now();
        let mut system = self.load()?;
        let load_time = started.elapsed();
        let columns = system.columns().len() - 1;
        let (units, libraries, threads) = (
            system.units(),
            system.libraries(),
            system.stepping_threads(),
        );
        let mut builtin = None;
        let algorithm: &mut dyn Algorithm = match self.take_algorithm() {
            Some(a) => a,
            None => &mut **builtin.insert(opts.algorithm.algorithm()),
        };
        let (end, samples, simulated) = system.simulate_with(opts, algorithm, observers)?;
        Ok(Outcome {
            end,
            warnings: system.core_mut().take_warnings(),
            samples,
            simulated,
            columns,
            load_time,
            run_time: started.elapsed() - load_time,
            advance_time: system.advance_time(),
            units,
            libraries,
            threads,
        })
    }

    /// Load the system and simulate it to its end with the algorithm `opts` names, every
    /// output kept in memory (tests and short runs; [`Builder::run`] streams them instead).
    pub fn simulate(&self, opts: &Options) -> Result<Table, Error> {
        self.load()?.simulate(opts)
    }
}

/// The most communication steps one run takes (a billion rows would be a CSV of tens of GB per
/// column group, and hours of stepping: a start or stop time off by orders of magnitude).
pub const MAX_STEPS: i64 = 1_000_000_000;

/// A run's start, stop and step, ticks.
#[derive(Clone, Copy)]
struct Span {
    start: i64,
    stop: i64,
    step: i64,
}

/// What a run has recorded: the last communication point, and how many.
#[derive(Default)]
struct Tally {
    last: Option<i64>,
    samples: u64,
}

impl System {
    /// Simulate to the end keeping every output in memory.
    pub fn simulate(&mut self, opts: &Options) -> Result<Table, Error> {
        self.simulate_recording(opts, Record::parse("all"))
    }

    /// Simulate to the end keeping what `record` chooses in memory (the studies keep the
    /// system's default set, [`Record::system_default`]).
    pub fn simulate_recording(&mut self, opts: &Options, record: Record) -> Result<Table, Error> {
        let mut recorder = Select::new(Recorder::default(), record);
        let mut algorithm = opts.algorithm.algorithm();
        let (end, _, _) = self.simulate_with(opts, &mut *algorithm, &mut [&mut recorder])?;
        match end {
            End::Completed => Ok(recorder.inner.table),
            End::Interrupted { signal, at } => Err(Error::Run(format!(
                "interrupted by signal {signal} at t = {at} s"
            ))),
            End::Failed { error, .. } => Err(Error::Run(error)),
        }
    }

    /// Initialize, step with `algorithm` to the stop time (or until an error or a signal) and
    /// hand every communication point to `observers`; returns how the run ended, the number of
    /// communication points recorded and the simulated time, s.
    ///
    /// `Err` only when the experiment is invalid, before any observer started; an error during
    /// the run ends it as [`End::Failed`] after the observers had every point up to it.
    pub fn simulate_with(
        &mut self,
        opts: &Options,
        algorithm: &mut dyn Algorithm,
        observers: &mut [&mut dyn Observer],
    ) -> Result<(End, u64, f64), Error> {
        let (start, stop, step) = self.experiment(opts)?;
        let threads = self.stepping_threads();
        self.set_advance_time(std::time::Duration::ZERO);
        let pool = if threads > 1 {
            let pool = Pool::new(threads)
                .map_err(|e| Error::Run(format!("cannot start {threads} stepping threads: {e}")))?;
            Some(pool)
        } else {
            None
        };
        self.core_mut().set_pool(pool);
        let columns = self.columns();
        let info = RunInfo {
            system: self.name(),
            columns: &columns,
            start: seconds(start),
            stop: seconds(stop),
            step: seconds(step),
            record: self.record(),
        };
        let mut started = Vec::with_capacity(observers.len());
        let mut result = Ok(None);
        for (k, o) in observers.iter_mut().enumerate() {
            if let Err(e) = o.start(&info) {
                result = Err(e);
                break;
            }
            started.push(k);
        }
        let mut tally = Tally::default();
        if result.is_ok() {
            let span = Span { start, stop, step };
            result = self.drive(span, algorithm, observers, &mut tally);
        }
        // The traces (`--trace`) are flushed however the run went: a failed run's is the one
        // worth replaying.
        if let Err(e) = self.core_mut().finish_traces() {
            if result.is_ok() {
                result = Err(e);
            } else {
                eprintln!("cosim: {e}");
            }
        }
        let Tally { last, samples } = tally;
        let at = last.map_or(seconds(start), seconds);
        let end = match result {
            Ok(None) => End::Completed,
            Ok(Some(signal)) => End::Interrupted { signal, at },
            Err(e) => End::Failed {
                at,
                error: e.to_string(),
            },
        };
        // The workers end with the run.
        self.core_mut().set_pool(None);
        for k in started {
            if let Err(e) = observers[k].finish(&end) {
                if end == End::Completed {
                    let error = e.to_string();
                    return Ok((End::Failed { at, error }, samples, at - seconds(start)));
                }
                eprintln!("cosim: {e}");
            }
        }
        Ok((end, samples, at - seconds(start)))
    }

    /// The run itself: `Ok(Some(signal))` when interrupted; `tally` counts what was recorded.
    fn drive(
        &mut self,
        span: Span,
        algorithm: &mut dyn Algorithm,
        observers: &mut [&mut dyn Observer],
        tally: &mut Tally,
    ) -> Result<Option<i32>, Error> {
        if let Some(signal) = interrupt::requested() {
            return Ok(Some(signal));
        }
        let (core, plans) = self.core_and_plans();
        core.initialize(span.start, span.stop, plans, &mut Direct::default())
            .map_err(|e| Error::Initialization(Box::new(e)))?;
        algorithm.start(&mut Coupling::new(self))?;
        let started = std::time::Instant::now();
        let result = self.advance(span, algorithm, observers, tally);
        self.set_advance_time(started.elapsed());
        if let Some(report) = algorithm.finish(&mut Coupling::new(self)) {
            eprintln!("cosim: {report}");
        }
        result
    }

    /// Sample, step, repeat until the stop time (or a signal).
    fn advance(
        &mut self,
        Span { start, stop, step }: Span,
        algorithm: &mut dyn Algorithm,
        observers: &mut [&mut dyn Observer],
        tally: &mut Tally,
    ) -> Result<Option<i32>, Error> {
        let mut t = start;
        loop {
            self.core_mut().sample(t)?;
            for o in observers.iter_mut() {
                o.sample(self.core().row())?;
            }
            tally.last = Some(t);
            tally.samples += 1;
            if t >= stop {
                break;
            }
            if let Some(signal) = interrupt::requested() {
                return Ok(Some(signal));
            }
            let h = step.min(stop - t);
            algorithm
                .step(&mut Coupling::new(self), t, h)
                .map_err(|e| Error::Step {
                    from: seconds(t),
                    to: seconds(t + h),
                    algorithm: Some(algorithm.name().to_owned()),
                    cause: Box::new(e),
                })?;
            t += h;
        }
        self.core_mut().terminate()?;
        Ok(None)
    }

    /// Exchange every connection's value in the master's step plan.
    pub(crate) fn exchange(&mut self) -> Result<(), Error> {
        let (core, plans) = self.core_and_plans();
        core.exchange(
            Phase::Step,
            &plans[Phase::Step as usize],
            &mut Direct::default(),
        )
        .map(|_| ())
    }
}

//! Running one FMU on its own (inputs at their start values) and writing the results as CSV.

use crate::fmu::{Error, Fmu, Status};
use model_description::Causality;
use std::io::{IsTerminal, Write};
use std::path::Path;
use std::sync::Arc;

/// Simulation results: `time` then one column per recorded variable.
#[derive(Debug, Clone, Default)]
pub struct Table {
    pub columns: Vec<String>,
    pub rows: Vec<Vec<f64>>,
}

impl Table {
    /// The values of column `name`.
    pub fn column(&self, name: &str) -> Option<Vec<f64>> {
        let i = self.columns.iter().position(|c| c == name)?;
        Some(self.rows.iter().map(|r| r[i]).collect())
    }

    /// Write as CSV with full `f64` precision.
    pub fn write_csv(&self, path: &Path) -> std::io::Result<()> {
        let mut w = std::io::BufWriter::new(std::fs::File::create(path)?);
        writeln!(w, "{}", self.columns.join(","))?;
        for row in &self.rows {
            let line: Vec<String> = row.iter().map(|x| format!("{x:?}")).collect();
            writeln!(w, "{}", line.join(","))?;
        }
        w.flush()
    }
}

/// Nanoseconds per second: the master counts time in integer ticks.
pub const NS: i64 = 1_000_000_000;

/// Seconds to ticks, rounded to the nearest nanosecond.
pub fn ticks(seconds: f64) -> i64 {
    (seconds * NS as f64).round() as i64
}

/// Simulate `fmu` alone from its default experiment (or `stop`/`step`), recording every output.
pub fn simulate_alone(
    fmu: &Arc<Fmu>,
    stop: Option<f64>,
    step: Option<f64>,
    progress: bool,
) -> Result<Table, Error> {
    let progress = progress && std::io::stderr().is_terminal();
    let de = fmu
        .description
        .default_experiment
        .clone()
        .unwrap_or_default();
    let start = ticks(de.start_time.unwrap_or(0.0));
    let stop = ticks(stop.or(de.stop_time).unwrap_or(1.0));
    let step = ticks(step.or(de.step_size).unwrap_or(1e-3));
    if step <= 0 || stop <= start {
        return Err(Error(format!(
            "bad experiment: start {start} ns, stop {stop} ns, step {step} ns"
        )));
    }
    let outputs: Vec<_> = fmu
        .description
        .model_variables
        .variables
        .iter()
        .filter(|v| {
            v.causality() == Causality::Output && v.base_type() == model_description::BaseType::Real
        })
        .collect();
    let vrs: Vec<u32> = outputs.iter().map(|v| v.value_reference).collect();
    let mut table = Table {
        columns: vec!["time".into()],
        rows: Vec::new(),
    };
    table.columns.extend(outputs.iter().map(|v| v.name.clone()));

    let mut inst = fmu.instantiate(&fmu.description.model_name)?;
    let fail = |inst: &crate::Instance, what: &str, s: Status| {
        Error(format!(
            "{what} returned {s:?}: {}",
            inst.last_message().unwrap_or_default()
        ))
    };
    let secs = |t: i64| t as f64 / NS as f64;
    let s = inst.setup_experiment(secs(start), Some(secs(stop)));
    if s > Status::Warning {
        return Err(fail(&inst, "fmi2SetupExperiment", s));
    }
    for (what, s) in [
        (
            "fmi2EnterInitializationMode",
            inst.enter_initialization_mode(),
        ),
        (
            "fmi2ExitInitializationMode",
            inst.exit_initialization_mode(),
        ),
    ] {
        if s > Status::Warning {
            return Err(fail(&inst, what, s));
        }
    }
    let mut values = vec![0.0; vrs.len()];
    let mut record = |inst: &mut crate::Instance, t: i64, table: &mut Table| -> Result<(), Error> {
        let s = inst.get_real(&vrs, &mut values);
        if s > Status::Warning {
            return Err(fail(inst, "fmi2GetReal", s));
        }
        let mut row = Vec::with_capacity(values.len() + 1);
        row.push(secs(t));
        row.extend_from_slice(&values);
        table.rows.push(row);
        Ok(())
    };
    let mut t = start;
    record(&mut inst, t, &mut table)?;
    let total = ((stop - start) + step - 1) / step;
    let mut last_percent = 0;
    while t < stop {
        let h = step.min(stop - t);
        let s = inst.do_step(secs(t), secs(h));
        if s > Status::Warning {
            return Err(fail(&inst, &format!("fmi2DoStep at t = {}", secs(t)), s));
        }
        t += h;
        record(&mut inst, t, &mut table)?;
        let percent = (table.rows.len() as i64 - 1) * 100 / total.max(1);
        if progress && percent >= last_percent + 10 {
            last_percent = percent;
            eprint!("\r{}: {percent:3}%", fmu.description.model_name);
        }
    }
    if progress {
        eprintln!();
    }
    inst.terminate();
    Ok(table)
}

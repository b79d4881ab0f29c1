//! `bench`: nanoseconds per `fmi2DoStep` of bundled FMUs, measured one after another in one run.
//!
//! Each argument is `LABEL|FMU|H|NAME=VALUE,...`; the values are set before initialization.

use dvpp_cosim::{Fmu, Status};
use model_description::BaseType;
use std::process::ExitCode;
use std::sync::Arc;
use std::time::{Duration, Instant};

fn measure(spec: &str) -> Result<(String, f64, usize), String> {
    let parts: Vec<&str> = spec.split('|').collect();
    let [label, path, h, sets] = parts.as_slice() else {
        return Err(format!(
            "bad benchmark '{spec}': expected LABEL|FMU|H|NAME=VALUE,..."
        ));
    };
    let h: f64 = h.parse().map_err(|_| format!("{label}: bad step '{h}'"))?;
    let fmu = Arc::new(Fmu::load(std::path::Path::new(path)).map_err(|e| e.to_string())?);
    let mut i = fmu.instantiate(label).map_err(|e| e.to_string())?;
    for set in sets.split(',').filter(|s| !s.is_empty()) {
        let (name, value) = set
            .split_once('=')
            .ok_or(format!("{label}: bad setting '{set}'"))?;
        let var = fmu
            .description
            .variable(name)
            .ok_or(format!("{label}: no variable '{name}'"))?;
        let x: f64 = value
            .parse()
            .map_err(|_| format!("{label}: bad value '{value}'"))?;
        let vr = [var.value_reference];
        let s = match var.base_type() {
            BaseType::Integer => i.set_integer(&vr, &[x as i32]),
            BaseType::Boolean => i.set_boolean(&vr, &[x != 0.0]),
            _ => i.set_real(&vr, &[x]),
        };
        if s != Status::Ok {
            return Err(format!("{label}: setting {name}: {:?}", i.last_message()));
        }
    }
    let ok = |s: Status, what: &str, i: &dvpp_cosim::Instance| {
        if s > Status::Warning {
            Err(format!("{label}: {what}: {:?}", i.last_message()))
        } else {
            Ok(())
        }
    };
    ok(i.setup_experiment(0.0, None), "setup", &i)?;
    ok(i.enter_initialization_mode(), "enter init", &i)?;
    ok(i.exit_initialization_mode(), "exit init", &i)?;
    let mut t = 0.0;
    let mut steps = 0usize;
    for _ in 0..1000 {
        ok(i.do_step(t, h), "step", &i)?;
        t += h;
    }
    let start = Instant::now();
    while start.elapsed() < Duration::from_millis(500) {
        for _ in 0..1000 {
            ok(i.do_step(t, h), "step", &i)?;
            t += h;
        }
        steps += 1000;
    }
    Ok((
        label.to_string(),
        start.elapsed().as_nanos() as f64 / steps as f64,
        steps,
    ))
}

fn main() -> ExitCode {
    println!(
        "{:<40} {:>14} {:>10}",
        "benchmark", "ns/fmi2DoStep", "steps"
    );
    let mut failed = false;
    for spec in std::env::args().skip(1) {
        match measure(&spec) {
            Ok((label, ns, steps)) => println!("{label:<40} {ns:>14.1} {steps:>10}"),
            Err(e) => {
                eprintln!("bench: {e}");
                failed = true;
            }
        }
    }
    if failed {
        ExitCode::FAILURE
    } else {
        ExitCode::SUCCESS
    }
}

//! `scale|FMU|N,N,...|UNIT_STEPS[|KEEP_DIR]`: the master's cost against the number of units
//! (with KEEP_DIR the systems are left in `KEEP_DIR/nN/` for other masters).
//!
//! For each N a system of N components of FMU (`unit1` … `unitN`, every output recorded as the
//! bundler records a DER's, inputs held at their start values, no connections) is written as
//! an SSP directory. Each configuration (identical binaries shared or each loaded separately;
//! 1 or 2 stepping threads) runs in a process of its own, so that its peak RSS is its own, for
//! UNIT_STEPS / N Jacobi steps of 1 ms (at least 200); every configuration runs five times,
//! interleaved, and the best and the median are reported (this machine's timings drift).
//! Reported: µs per macro step (stepping and sampling, initialization excluded), per unit, load
//! time, peak RSS, libraries loaded, the least-squares line of cost against N, the 2-thread
//! speed-up next to the throughput gain of two shared 1-thread runs at once (what two cores give
//! two independent copies of the work here), the serial part of a step (what stays on the
//! master's thread: T2 minus the stepping round, [`System::step_time`]) and the Amdahl bound
//! it sets for 4 and 8 cores.

use dvpp_cosim::master::{End, Jacobi, Observer, Options, RunInfo, Sharing, System};
use dvpp_cosim::ssp;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::Instant;

/// The first argument of a child run.
pub const CHILD: &str = "--scale-child";

const CONFIGS: [(Sharing, usize); 4] = [
    (Sharing::Shared, 1),
    (Sharing::Shared, 2),
    (Sharing::Separate, 1),
    (Sharing::Separate, 2),
];

const STEP: f64 = 1e-3;

/// Runs of each configuration (interleaved); the best counts.
const REPS: usize = 5;

fn sharing_name(s: Sharing) -> &'static str {
    match s {
        Sharing::Shared => "shared",
        Sharing::Separate => "separate",
    }
}

/// What one child run measured.
#[derive(Debug, Clone, Copy)]
struct Run {
    us_per_step: f64,
    load_s: f64,
    rss_mb: f64,
    libraries: usize,
    steps: u64,
    /// µs per step spent stepping the units ([`System::step_time`]).
    round_us: f64,
}

/// The peak resident set of this process, MB (`VmHWM`).
fn peak_rss_mb() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find_map(|l| l.strip_prefix("VmHWM:"))
                .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<f64>().ok())
        })
        .map_or(f64::NAN, |kb| kb / 1024.0)
}

/// Times the communication points after initialization.
#[derive(Default)]
struct Timer {
    first: Option<Instant>,
    last: Option<Instant>,
    samples: u64,
}

impl Observer for Timer {
    fn start(&mut self, _: &RunInfo) -> Result<(), dvpp_cosim::master::Error> {
        Ok(())
    }
    fn sample(&mut self, _: &[f64]) -> Result<(), dvpp_cosim::master::Error> {
        let now = Instant::now();
        self.first.get_or_insert(now);
        self.last = Some(now);
        self.samples += 1;
        Ok(())
    }
    fn finish(&mut self, _: &End) -> Result<(), dvpp_cosim::master::Error> {
        Ok(())
    }
}

/// A child run, `DIR|SHARING|THREADS|STEPS`: one line
/// `us_per_step load_s rss_mb libraries steps round_us`.
pub fn child(spec: &str) -> Result<String, String> {
    let parts: Vec<&str> = spec.split('|').collect();
    let [dir, sharing, threads, steps] = parts.as_slice() else {
        return Err(format!("bad child run '{spec}'"));
    };
    let sharing = match *sharing {
        "shared" => Sharing::Shared,
        _ => Sharing::Separate,
    };
    let threads: usize = threads.parse().map_err(|_| "bad threads".to_string())?;
    let steps: u64 = steps.parse().map_err(|_| "bad steps".to_string())?;
    let started = Instant::now();
    let package = ssp::read(Path::new(dir)).map_err(|e| e.to_string())?;
    let mut system = System::builder(&package)
        .sharing(sharing)
        .threads(threads)
        .load()
        .map_err(|e| e.to_string())?;
    let load_s = started.elapsed().as_secs_f64();
    let libraries = system.libraries();
    let opts = Options {
        stop: Some(steps as f64 * STEP),
        step: Some(STEP),
        ..Options::default()
    };
    let mut timer = Timer::default();
    let (end, _, _) = system
        .simulate_with(&opts, &mut Jacobi, &mut [&mut timer])
        .map_err(|e| e.to_string())?;
    if end != End::Completed {
        return Err(format!("{dir}: {end:?}"));
    }
    let (Some(first), Some(last)) = (timer.first, timer.last) else {
        return Err("no samples".into());
    };
    let done = timer.samples.saturating_sub(1).max(1);
    let us = (last - first).as_secs_f64() * 1e6 / done as f64;
    let round_us = system.step_time().as_secs_f64() * 1e6 / done as f64;
    Ok(format!(
        "{us} {load_s} {} {libraries} {done} {round_us}",
        peak_rss_mb()
    ))
}

/// Start a child run.
fn spawn_child(
    dir: &Path,
    sharing: Sharing,
    threads: usize,
    steps: u64,
) -> Result<(String, Child), String> {
    let exe = std::env::current_exe().map_err(|e| e.to_string())?;
    let spec = format!(
        "{}|{}|{threads}|{steps}",
        dir.display(),
        sharing_name(sharing)
    );
    let child = Command::new(exe)
        .args([CHILD, &spec])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| e.to_string())?;
    Ok((spec, child))
}

/// Wait for a child run and read its line.
fn collect((spec, child): (String, Child)) -> Result<Run, String> {
    let out = child.wait_with_output().map_err(|e| e.to_string())?;
    if !out.status.success() {
        return Err(format!(
            "{spec}: {}",
            String::from_utf8_lossy(&out.stderr).trim()
        ));
    }
    let text = String::from_utf8_lossy(&out.stdout);
    let f: Vec<f64> = text
        .split_whitespace()
        .filter_map(|w| w.parse().ok())
        .collect();
    let [us_per_step, load_s, rss_mb, libraries, steps, round_us] = f.as_slice() else {
        return Err(format!("{spec}: unexpected output '{text}'"));
    };
    Ok(Run {
        us_per_step: *us_per_step,
        load_s: *load_s,
        rss_mb: *rss_mb,
        libraries: *libraries as usize,
        steps: *steps as u64,
        round_us: *round_us,
    })
}

/// Least squares `y = a + b x`: (a, b, R²).
fn fit(xs: &[f64], ys: &[f64]) -> (f64, f64, f64) {
    let n = xs.len() as f64;
    let (mx, my) = (xs.iter().sum::<f64>() / n, ys.iter().sum::<f64>() / n);
    let sxy: f64 = xs.iter().zip(ys).map(|(x, y)| (x - mx) * (y - my)).sum();
    let sxx: f64 = xs.iter().map(|x| dvpp_math::powi(x - mx, 2)).sum();
    let syy: f64 = ys.iter().map(|y| dvpp_math::powi(y - my, 2)).sum();
    let b = sxy / sxx;
    let a = my - b * mx;
    (
        a,
        b,
        if syy > 0.0 {
            sxy * sxy / (sxx * syy)
        } else {
            1.0
        },
    )
}

/// `scale|FMU|N,N,...|UNIT_STEPS`: the table and fits on stdout.
pub fn measure(spec: &str) -> Result<(), String> {
    let parts: Vec<&str> = spec.split('|').collect();
    let (fmu, ns, unit_steps, keep) = match parts.as_slice() {
        [_, fmu, ns, unit_steps] => (fmu, ns, unit_steps, None),
        [_, fmu, ns, unit_steps, keep] => (fmu, ns, unit_steps, Some(Path::new(keep))),
        _ => {
            return Err(format!(
                "bad benchmark '{spec}': expected scale|FMU|N,N,...|UNIT_STEPS[|KEEP_DIR]"
            ))
        }
    };
    let ns: Vec<usize> = ns
        .split(',')
        .map(|n| n.trim().parse().map_err(|_| format!("scale: bad N '{n}'")))
        .collect::<Result<_, _>>()?;
    let unit_steps: u64 = unit_steps
        .parse()
        .map_err(|_| format!("scale: bad UNIT_STEPS '{unit_steps}'"))?;
    // KEEP_DIR: the systems stay there (`nN/`), for other masters to run the same ones.
    match keep {
        Some(root) => measure_in(root, Path::new(fmu), &ns, unit_steps),
        None => {
            let scratch =
                dvpp_cosim::tmp::TempDir::new("bench-scale").map_err(|e| e.to_string())?;
            measure_in(scratch.path(), Path::new(fmu), &ns, unit_steps)
        }
    }
}

/// The median of `xs` (not empty).
fn median(xs: &[f64]) -> f64 {
    let mut v = xs.to_vec();
    v.sort_by(f64::total_cmp);
    let m = v.len() / 2;
    if v.len() % 2 == 1 {
        v[m]
    } else {
        0.5 * (v[m - 1] + v[m])
    }
}

fn best(xs: &[f64]) -> f64 {
    xs.iter().copied().fold(f64::INFINITY, f64::min)
}

fn measure_in(root: &Path, fmu: &Path, ns: &[usize], unit_steps: u64) -> Result<(), String> {
    let dirs: Vec<PathBuf> = ns.iter().map(|n| root.join(format!("n{n}"))).collect();
    for (n, dir) in ns.iter().zip(&dirs) {
        ssp::write_copies(fmu, *n, dir, STEP)?;
    }
    // runs[i][c]: every run of N = ns[i] in configuration c.
    let mut runs: Vec<Vec<Vec<Run>>> = vec![vec![Vec::new(); CONFIGS.len()]; ns.len()];
    // Two shared 1-thread runs at once, µs per step of each: what two cores give two
    // independent copies of the work (caches, memory, the host), the ceiling for 2 threads.
    let mut pair: Vec<Vec<f64>> = vec![Vec::new(); ns.len()];
    for _ in 0..REPS {
        for (i, (n, dir)) in ns.iter().zip(&dirs).enumerate() {
            let steps = (unit_steps / *n as u64).max(200);
            let (a, b) = (
                spawn_child(dir, Sharing::Shared, 1, steps)?,
                spawn_child(dir, Sharing::Shared, 1, steps)?,
            );
            let (a, b) = (collect(a)?, collect(b)?);
            pair[i].push(0.5 * (a.us_per_step + b.us_per_step));
            for (c, (sharing, threads)) in CONFIGS.iter().enumerate() {
                runs[i][c].push(collect(spawn_child(dir, *sharing, *threads, steps)?)?);
            }
        }
    }
    let stat =
        |i: usize, c: usize, f: fn(&Run) -> f64| -> Vec<f64> { runs[i][c].iter().map(f).collect() };
    let us = |i: usize, c: usize| stat(i, c, |r| r.us_per_step);
    println!();
    println!(
        "scale: {} ({} unit-steps per run, {REPS} runs of each, interleaved, each run its own process)",
        fmu.display(),
        unit_steps
    );
    println!("| N | binaries | threads | libraries | steps | µs per macro step: best (median) | µs per unit: best (median) | load time (median) | peak RSS |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for (i, n) in ns.iter().enumerate() {
        for (c, (sharing, threads)) in CONFIGS.iter().enumerate() {
            let r = runs[i][c][0];
            let (b, m) = (best(&us(i, c)), median(&us(i, c)));
            let nf = *n as f64;
            println!(
                "| {n} | {} | {threads} | {} | {} | {b:.1} ({m:.1}) | {:.3} ({:.3}) | {:.0} ms | {:.1} MB |",
                sharing_name(*sharing),
                r.libraries,
                r.steps,
                b / nf,
                m / nf,
                median(&stat(i, c, |r| r.load_s)) * 1e3,
                stat(i, c, |r| r.rss_mb).into_iter().fold(0.0, f64::max)
            );
        }
    }
    println!();
    println!("| binaries | threads | cost = a + b·N on the best: a (µs), b (µs per unit), R² | on the medians: a, b, R² | load time per unit | RSS per unit |");
    println!("|---|---|---|---|---|---|");
    let xs: Vec<f64> = ns.iter().map(|&n| n as f64).collect();
    for (c, (sharing, threads)) in CONFIGS.iter().enumerate() {
        let col = |f: &dyn Fn(usize) -> f64| -> Vec<f64> { (0..ns.len()).map(f).collect() };
        let (a, b, r2) = fit(&xs, &col(&|i| best(&us(i, c))));
        let (am, bm, r2m) = fit(&xs, &col(&|i| median(&us(i, c))));
        let (_, load_b, _) = fit(&xs, &col(&|i| median(&stat(i, c, |r| r.load_s)) * 1e3));
        let (_, rss_b, _) = fit(&xs, &col(&|i| median(&stat(i, c, |r| r.rss_mb))));
        println!(
            "| {} | {threads} | {a:.1}, {b:.3}, {r2:.4} | {am:.1}, {bm:.3}, {r2m:.4} | {load_b:.2} ms | {:.0} kB |",
            sharing_name(*sharing),
            rss_b * 1024.0
        );
    }
    println!();
    // Amdahl from the 2-thread runs: the serial part S = T2 - (stepping round on 2 threads);
    // the parallel work W = T1 - S; on p cores at best S + W/p (the round scaling ideally).
    println!("| N | binaries | 2-thread speed-up: best (median) | two 1-thread runs at once, throughput gain (median) | serial part of a step (median) | stepping round on 2 threads vs 1 (median) | at most on 4 / 8 cores (Amdahl) |");
    println!("|---|---|---|---|---|---|---|");
    for (i, n) in ns.iter().enumerate() {
        for (one, two) in [(0, 1), (2, 3)] {
            let s = best(&us(i, one)) / best(&us(i, two));
            let (t1, t2) = (median(&us(i, one)), median(&us(i, two)));
            let serial = (t2 - median(&stat(i, two, |r| r.round_us))).max(0.0);
            let work = (t1 - serial).max(0.0);
            let round = work / median(&stat(i, two, |r| r.round_us));
            let at = |p: f64| t1 / (serial + work / p);
            let ceiling = if one == 0 {
                format!("{:.2}", 2.0 * t1 / median(&pair[i]))
            } else {
                String::new()
            };
            println!(
                "| {n} | {} | {s:.2} ({:.2}) | {ceiling} | {serial:.1} µs ({:.1} % of 1 thread) | {round:.2} | {:.2} / {:.2} |",
                sharing_name(CONFIGS[one].0),
                t1 / t2,
                100.0 * serial / t1,
                at(4.0),
                at(8.0)
            );
        }
    }
    Ok(())
}

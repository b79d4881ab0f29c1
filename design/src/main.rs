//! `dvpp-design`: synthesize the LPV H∞ matching controller, check it without the solver, and write its gains (what `cargo xtask hinf` runs).

use dvpp_design::checks::{frame_units, grid_points, Report, GRID};
use dvpp_design::generate;
use dvpp_design::plant::DesignSpec;
use dvpp_design::synthesis::synthesize;
use std::process::ExitCode;

const USAGE: &str = "usage: dvpp-design [--write] [--set NAME=VALUE]...

Synthesizes option B's LPV H∞ gains for the default design (docs/hinf.md), checks them (LMI
residuals, closed-loop eigenvalues continuous and sampled with the delay on a grid of 50 values of
mu, the H-infinity norm by a frequency sweep) and prints the figures; fails if a check fails.
  --write            write the gains to dvpp-control/src/converter/hinf_gains.rs
  --set NAME=VALUE   change a weight or the operating point to explore (tracking,
                     tracking_corner, alignment, alignment_corner, effort, rolloff,
                     pole_radius, p0, q0), the box of grids (theta_min,
                     phi_max) or the frame stabilizer (stabilizer);
                     not with --write";

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("dvpp-design: {e}");
            ExitCode::FAILURE
        }
    }
}

fn run() -> Result<(), String> {
    let mut spec = DesignSpec::default();
    let (mut write, mut changed) = (false, false);
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--write" => write = true,
            "--set" => {
                let kv = args.next().ok_or(USAGE)?;
                let (k, v) = kv.split_once('=').ok_or(USAGE)?;
                let v: f64 = v.parse().map_err(|e| format!("{kv}: {e}"))?;
                let w = &mut spec.weights;
                match k {
                    "tracking" => w.tracking = v,
                    "tracking_corner" => w.tracking_corner = v,
                    "alignment" => w.alignment = v,
                    "alignment_corner" => w.alignment_corner = v,
                    "effort" => w.effort = v,
                    "rolloff" => w.rolloff = v,
                    "pole_radius" => spec.pole_radius = v,
                    "stabilizer" => spec.stabilizer = v,
                    "p0" => spec.p0 = v,
                    "q0" => spec.q0 = v,
                    "theta_min" => spec.theta_min = v,
                    "phi_max" => spec.phi_max = v,
                    _ => return Err(format!("unknown NAME {k}\n{USAGE}")),
                }
                changed = true;
            }
            _ => return Err(USAGE.into()),
        }
    }
    if write && changed {
        return Err(
            "--write writes the default design only (change it in DesignSpec::default)".into(),
        );
    }
    let started = std::time::Instant::now();
    let design = synthesize(&spec)?;
    let took = started.elapsed().as_secs_f64();
    println!(
        "synthesis: gamma = {:.6} (clarabel: {}, {} iterations) in {:.2} s",
        design.gamma, design.status, design.iterations, took
    );
    let wb = spec.omega_b();
    let r = Report::of(&design);
    let grids = grid_points(&spec);
    println!(
        "grids: theta in [{}, 1], phi in [0, {}] ({} corners; checks on {} grids)",
        spec.theta_min,
        spec.phi_max,
        spec.grid_corners().len(),
        grids.len()
    );
    for (mu, g, e) in &r.residuals {
        println!(
            "LMI residual (largest eigenvalue of the vertex LMI, must be < 0): {e:.3e} at mu = {mu}, {g}"
        );
    }
    println!(
        "continuous closed loop, {GRID} values of mu x {} grids: largest real part {:.3} rad/s (at mu = {:.3}, {}), largest magnitude {:.0} rad/s (disk {:.0} rad/s)",
        grids.len(),
        r.worst_real_part.0,
        r.worst_real_part.1,
        r.worst_real_part.2,
        r.fastest_pole,
        spec.pole_radius * wb
    );
    println!(
        "sampled closed loop at {} us with one sample of delay: largest |z| {:.6} (at mu = {:.3}, {})",
        spec.h * 1e6,
        r.worst_sampled_radius.0,
        r.worst_sampled_radius.1,
        r.worst_sampled_radius.2
    );
    println!(
        "sampled closed loop stable for the gain scaled by {:.3} to {:.3} (gain margins {:.1} dB, {:.1} dB)",
        r.gain_margins.0,
        r.gain_margins.1,
        20.0 * dvpp_math::log10(r.gain_margins.0),
        20.0 * dvpp_math::log10(r.gain_margins.1)
    );
    let (lo, hi) = r
        .sweep
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(a, b), &(_, _, s)| {
            (a.min(s), b.max(s))
        });
    println!("H-infinity norm by frequency sweep over mu and the grids: from {lo:.6} to {hi:.6}");
    println!(
        "H-infinity norm by frequency sweep: largest {:.6} at mu = {:.3}, {}, {:.1} Hz; sweep/gamma = {:.6}",
        r.worst_sweep.0,
        r.worst_sweep.1,
        r.worst_sweep.2,
        r.worst_sweep.3,
        r.worst_sweep.0 / r.gamma
    );
    println!(
        "the frame's swing (stabilizer {}; {} units, the grids and the island's load): worst {:.3} rad/s at {:.2} Hz (mu = {:.2}, {}, {})",
        spec.stabilizer,
        frame_units().len(),
        r.worst_frame.0,
        r.worst_frame.1,
        r.worst_frame.2,
        r.worst_frame.3,
        r.worst_frame.4
    );
    println!("synthesis time: {took:.2} s");
    if !r.passes() {
        return Err("a check failed (see above)".into());
    }
    println!("all checks pass");
    if write {
        let path = generate::path();
        std::fs::write(&path, generate::render(&design))
            .map_err(|e| format!("{}: {e}", path.display()))?;
        println!("wrote {}", generate::RELATIVE_PATH);
    }
    Ok(())
}

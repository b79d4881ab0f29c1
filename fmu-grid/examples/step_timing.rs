//! Times `Grid::step` at h = 1 ms on each built-in case (what the FMU benchmark measures, without
//! the FMI layer). Usage: cargo run --release -p grid-model --example step_timing
use grid_model::{Case, Grid};
fn main() {
    for name in Case::builtin_names() {
        let mut g = Grid::new(&Case::builtin(name).unwrap()).unwrap();
        let h = 1e-3;
        let n = 20_000;
        let t0 = std::time::Instant::now();
        for i in 0..n {
            g.step(i as f64 * h, h).unwrap();
            std::hint::black_box(g.outputs());
        }
        let us = t0.elapsed().as_secs_f64() * 1e6 / n as f64;
        println!(
            "{name:>14}: {us:.2} us per 1 ms step (step + outputs), coi_f(20 s) = {:.7}",
            g.outputs().coi_f
        );
    }
}

//! Prints the figures of a load step (default: 28 MW at bus 5 of the IEEE 9-bus base case).
//! Usage: cargo run --release --example load_step [case] [bus] [MW] [t_end] [cp]
//! (`cp` switches every load, and the step, to constant power.)
use grid_model::{analysis::run_load_step_with, Case, LoadModel};
fn main() {
    let a: Vec<String> = std::env::args().collect();
    let name = a.get(1).map(String::as_str).unwrap_or("ieee9");
    let bus: u32 = a.get(2).and_then(|s| s.parse().ok()).unwrap_or(5);
    let mw: f64 = a.get(3).and_then(|s| s.parse().ok()).unwrap_or(28.0);
    let t_end: f64 = a.get(4).and_then(|s| s.parse().ok()).unwrap_or(300.0);
    let cp = a.get(5).map(|s| s == "cp").unwrap_or(false);
    let mut case = Case::builtin(name).expect("unknown built-in case");
    let model = if cp {
        LoadModel::ConstantPower
    } else {
        LoadModel::ConstantImpedance
    };
    for l in &mut case.loads {
        l.model = model;
    }
    let fig =
        run_load_step_with(&case, bus, mw, model, 1.0, t_end, 0.01).expect("simulation failed");
    println!("case {name} ({model:?} loads):\n{fig}");
    let marks = [
        0.0, 1.0, 1.5, 2.0, 3.0, 5.0, 10.0, 20.0, 30.0, 60.0, 100.0, 150.0, 200.0, 250.0, 300.0,
    ];
    for &(t, f) in fig
        .trace
        .iter()
        .filter(|(t, _)| marks.iter().any(|x| (x - t).abs() < 1e-6))
    {
        println!("  t = {t:6.1} s  coi_f = {f:.7}");
    }
}

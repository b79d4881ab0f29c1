//! Prints the power flow of each built-in case and runs 10 s of flat start.
use grid_model::{Case, Grid};
fn main() {
    for name in Case::builtin_names() {
        let case = Case::builtin(name).unwrap();
        let mut g = Grid::new(&case).unwrap();
        let pf = g.power_flow();
        println!("{name}: it {} mism {:e}", pf.iterations, pf.mismatch);
        for (i, v) in pf.v.iter().enumerate() {
            println!(
                "  bus {} {:.4} {:.3}",
                i + 1,
                dvpp_math::cabs(*v),
                dvpp_math::carg(*v).to_degrees()
            );
        }
        println!("  mach {:?}\n  der {:?}", pf.machine_pq, pf.der_pq);
        println!("  maxderiv {:e}", g.max_derivative().unwrap());
        g.disable_events();
        let t0 = std::time::Instant::now();
        for i in 0..1000 {
            g.step(i as f64 * 0.01, 0.01).unwrap();
        }
        let o = g.outputs();
        println!(
            "  10 s in {:?}: coi {:e} pcc.f {:e} bal {:e}",
            t0.elapsed(),
            o.coi_f - 1.0,
            o.pcc.f - 1.0,
            o.balance_p
        );
    }
}

//! `dvpp-design`: synthesize the LPV H∞ matching controller, check it, and write its gains.

use dvpp_design::checks::Report;
use dvpp_design::plant::DesignSpec;
use dvpp_design::synthesis::synthesize;

fn main() {
    let mut spec = DesignSpec::default();
    for a in std::env::args().skip(1) {
        let (k, v) = a.split_once('=').unwrap();
        let v: f64 = v.parse().unwrap();
        let w = &mut spec.weights;
        match k {
            "tracking" => w.tracking = v,
            "tracking_corner" => w.tracking_corner = v,
            "alignment" => w.alignment = v,
            "alignment_corner" => w.alignment_corner = v,
            "effort" => w.effort = v,
            "rolloff" => w.rolloff = v,
            "p0" => spec.p0 = v,
            _ => panic!("{k}"),
        }
    }
    let t0 = std::time::Instant::now();
    let d = synthesize(&spec).unwrap_or_else(|e| {
        eprintln!("{e}");
        std::process::exit(1)
    });
    let dt = t0.elapsed();
    println!(
        "gamma {} ({} , {} it) in {:?}",
        d.gamma, d.status, d.iterations, dt
    );
    println!("K0 {:.4}", d.gains[0]);
    println!("K1 {:.4}", d.gains[1]);
    let r = Report::of(&d);
    println!(
        "{:?} {:?} {:?} {:?}",
        r.residuals, r.worst_real_part, r.worst_sampled_radius, r.worst_sweep
    );
    dbg_eigs(&d);
}
#[allow(dead_code)]
fn dbg_eigs(d: &dvpp_design::synthesis::Design) {
    for mu in [0.0, 0.5, 1.0] {
        let (a, _, _) = dvpp_design::checks::closed_loop(d, mu);
        let mut e: Vec<_> = a
            .complex_eigenvalues()
            .iter()
            .map(|l| (l.re * 314.159, l.im * 314.159 / 6.283))
            .collect();
        e.sort_by(|x, y| x.0.partial_cmp(&y.0).unwrap());
        println!("mu {mu}: {e:.1?}");
    }
}

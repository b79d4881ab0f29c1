//! The operator DLL's functions in process under an allocator that counts: the library's operator allocates in each step (its gains and command are vectors, as the FMU's), so `Model_Outputs` allocates a few small blocks per call; the number is the library step's own and stays the same call after call (the queue of delayed commands stops growing once it holds the delay).

#[allow(dead_code)]
mod support;

use dvpp_realcode::{ffi, DllSpec};
use support::{allocations, ok, Counting, Host};

#[global_allocator]
static COUNTING: Counting = Counting;

const SPEC: DllSpec = DllSpec {
    step: 1e-3,
    emt_rms_mode: 3,
    state_words: 8192,
    step_parameter: None,
    config: "",
};

mod dll {
    dvpp_realcode::export_dll!(operator_model::Operator, crate::SPEC);
}
use dll::tb958;

#[test]
fn model_outputs_allocates_the_same_few_blocks_every_call() {
    let info = tb958::info().expect("the info");
    let l = &info.layout;
    let mut h = Host::new(l);
    let inputs = |h: &mut Host, k: usize| {
        // A DVPP near its dispatch with a slow swing in frequency and power.
        let s = dvpp_math::sin(k as f64 * 0.01);
        for d in 1..=3 {
            h.input(l, &format!("der_{d}_P_avail"), 0.5);
            h.input(l, &format!("der_{d}_p"), 0.3 + 0.01 * s);
            h.input(l, &format!("der_{d}_p_set"), 0.3);
            h.input(l, &format!("der_{d}_q"), 0.02);
        }
        h.input(l, "pcc_p", 0.9 + 0.03 * s);
        h.input(l, "pcc_q", 0.06);
        h.input(l, "pcc_f", 1.0 - 1e-3 * s);
        h.input(l, "pcc_v", 1.0);
    };
    inputs(&mut h, 0);
    let inst: *mut ffi::Instance = &mut *h.inst;
    // SAFETY: `inst` is this host's instance, its pointers its own buffers laid out from the
    // DLL's layout.
    unsafe {
        ok(tb958::Model_FirstCall(inst), "first call", &h);
        ok(tb958::Model_CheckParameters(inst), "check", &h);
        ok(tb958::Model_Initialize(inst), "initialize", &h);
    }
    let mut per_call = Vec::new();
    for k in 1..3000 {
        inputs(&mut h, k);
        h.inst.time = k as f64 * 1e-3;
        let before = allocations();
        // SAFETY: as above.
        let r = unsafe { tb958::Model_Outputs(inst) };
        ok(r, "outputs", &h);
        if r == ffi::RETURN_OK {
            per_call.push((k, allocations() - before));
        }
    }
    let late: Vec<usize> = per_call
        .iter()
        .filter(|(k, _)| *k >= 100)
        .map(|c| c.1)
        .collect();
    let (lo, hi) = (
        late.iter().copied().min().unwrap_or(0),
        late.iter().copied().max().unwrap_or(0),
    );
    eprintln!(
        "operator: {} calls from step 100 on allocate {lo} to {hi} blocks each",
        late.len()
    );
    assert!(late.len() > 2800, "calls without a message");
    assert!(
        lo == hi && hi <= 16,
        "allocations per call vary or grow: {lo}..{hi}"
    );
    // SAFETY: as above.
    unsafe { ok(tb958::Model_Terminate(inst), "terminate", &h) };
}

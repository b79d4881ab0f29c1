//! The DER DLL's functions in process under an allocator that counts: after `Model_Initialize`, `Model_Outputs` allocates nothing in a call that returns no message, over the library's conformance trajectories (grid-forming A and B, grid-following).

mod support;

use dvpp_controllers::emt::trajectory::{Trajectory, INPUTS};
use dvpp_controllers::emt::ParamValue;
use dvpp_realcode::info::c_name;
use dvpp_realcode::{ffi, DllSpec};
use support::{allocations, ok, Counting, Host};

#[global_allocator]
static COUNTING: Counting = Counting;

const SPEC: DllSpec = DllSpec {
    step: 50e-6,
    emt_rms_mode: 1,
    state_words: 4096,
    step_parameter: Some("t_s"),
    config: "",
};

mod dll {
    dvpp_realcode::export_dll!(der_model::emt::DerEmt, crate::SPEC);
}
use dll::tb958;

#[test]
fn model_outputs_allocates_nothing_per_step() {
    let info = tb958::info().expect("the info");
    let l = &info.layout;
    for case in ["stiff_gfm_a", "weak_gfm_b", "weak_gfl", "island_gfm_b"] {
        let path = format!(
            "{}/../controllers/tests/conformance/{case}.txt",
            env!("CARGO_MANIFEST_DIR")
        );
        let t = Trajectory::parse(&std::fs::read_to_string(&path).expect("the trajectory"))
            .expect("parses");
        let mut h = Host::new(l);
        for (name, v) in &t.params {
            let x = match v {
                ParamValue::Real(x) => *x,
                ParamValue::Integer(k) => f64::from(*k),
                ParamValue::Boolean(b) => f64::from(u8::from(*b)),
            };
            h.parameter(l, &c_name(name), x);
        }
        h.input(l, "mu_p", t.gains.mu_p);
        h.input(l, "mu_q", t.gains.mu_q);
        for (n, x) in INPUTS.iter().zip(t.init_inputs) {
            h.input(l, n, x);
        }
        let inst: *mut ffi::Instance = &mut *h.inst;
        // SAFETY: `inst` is this host's instance, its pointers its own buffers laid out from
        // the DLL's layout.
        unsafe {
            ok(tb958::Model_FirstCall(inst), "first call", &h);
            ok(tb958::Model_CheckParameters(inst), "check", &h);
            ok(tb958::Model_Initialize(inst), "initialize", &h);
        }
        let (mut quiet, mut messages) = (0, 0);
        let mut allocating = Vec::new();
        for (k, s) in t.steps.iter().enumerate() {
            for (n, x) in INPUTS.iter().zip(s.inputs) {
                h.input(l, n, x);
            }
            h.inst.time = s.t;
            let before = allocations();
            // SAFETY: as above.
            let r = unsafe { tb958::Model_Outputs(inst) };
            ok(r, "outputs", &h);
            if r == ffi::RETURN_OK {
                if allocations() != before {
                    allocating.push((k, allocations() - before));
                } else {
                    quiet += 1;
                }
            } else {
                messages += 1;
            }
        }
        // SAFETY: as above.
        unsafe { ok(tb958::Model_Terminate(inst), "terminate", &h) };

        eprintln!("{case}: {quiet} calls without allocation, {messages} with a message, allocating: {allocating:?}");
        // The library's objects make some buffers on their first step (a state-space model's
        // output vector); from the second call on, none.
        assert!(
            allocating.iter().all(|(k, _)| *k == 0),
            "{case}: Model_Outputs allocated at steps {allocating:?}"
        );
        assert!(
            quiet > t.steps.len() * 9 / 10,
            "{case}: most calls give no message"
        );
    }
}

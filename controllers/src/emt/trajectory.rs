//! A recorded trajectory of an [`EmtUnit`](super::EmtUnit) (every input it received, every output it returned, reals as exact bits) as text, and the bit-for-bit comparison of a replay with it: the host-conformance test's reference.
//!
//! # Format (version 1)
//!
//! Lines of words separated by one space; `#` starts a comment line. Reals are the 16 hex
//! digits of their IEEE 754 bits.
//!
//! ```text
//! dvpp-emt-conformance 1
//! case NAME
//! param NAME r HEX | param NAME i INT | param NAME b 0|1   every parameter, by the FMU's name
//! gains MU_P MU_Q MU_P_LPF[1..8]                             the operator's gains (all steps)
//! init T INPUTS(10)                                          the measurement at initialization
//! out 0 OUTPUTS(19)                                          the command of initialization
//! step T H INPUTS(10) HASH                                   step k = 1, 2, ...: the measurement
//!                                                            at T, the step H, the hash of the
//!                                                            command's 19 outputs
//! out K OUTPUTS(19)                                          the full command of step K (the
//!                                                            first and last steps)
//! block K0 K1 HASH(19)                                       per output, the hash of its values
//!                                                            over the steps K0..=K1
//! ```
//!
//! Inputs in the order of [`INPUTS`], outputs in the order of [`OUTPUTS`] (a flag as 0 or 1).
//! A hash is FNV-1a (64 bits) over the little-endian bytes of the values' bits.

use super::{EmtCommand, EmtMeasurement, ParamValue};
use crate::{OperatorGains, MAX_LPF};
use dvpp_control::converter::Abc;
use std::fmt::{self, Write as _};

/// The first line of a trajectory.
pub const MAGIC: &str = "dvpp-emt-conformance 1";

/// The measurement's values, by the FMU's input names.
pub const INPUTS: [&str; 10] = [
    "v_a", "v_b", "v_c", "i_a", "i_b", "i_c", "ig_a", "ig_b", "ig_c", "v_dc",
];

/// The number of outputs compared.
pub const N_OUT: usize = 19;

/// The command's values, by the FMU's output names (the last three are flags).
pub const OUTPUTS: [&str; N_OUT] = [
    "m_a",
    "m_b",
    "m_c",
    "i_dc_ref",
    "p_src_min",
    "p_src_max",
    "p",
    "q",
    "v",
    "df",
    "theta",
    "E",
    "p_set",
    "q_ref",
    "P_avail",
    "i_ac",
    "limit.current",
    "limit.modulation",
    "limit.source",
];

/// Steps per block of per-output hashes.
pub const BLOCK: usize = 50;

/// Steps at each end of the trajectory whose commands are kept in full.
pub const FULL: usize = 5;

impl EmtMeasurement {
    /// Its values in the order of [`INPUTS`].
    pub fn inputs(&self) -> [f64; 10] {
        let (v, i, g) = (self.v_c, self.i_f, self.i_g);
        [v.a, v.b, v.c, i.a, i.b, i.c, g.a, g.b, g.c, self.v_dc]
    }

    /// The measurement at `t` of values in the order of [`INPUTS`].
    pub fn from_inputs(t: f64, x: &[f64; 10]) -> EmtMeasurement {
        let abc = |k: usize| Abc {
            a: x[k],
            b: x[k + 1],
            c: x[k + 2],
        };
        EmtMeasurement {
            t,
            v_c: abc(0),
            i_f: abc(3),
            i_g: abc(6),
            v_dc: x[9],
        }
    }
}

impl EmtCommand {
    /// Its values in the order of [`OUTPUTS`] (flags as 0 or 1).
    pub fn outputs(&self) -> [f64; N_OUT] {
        let flag = |b: bool| if b { 1.0 } else { 0.0 };
        [
            self.m_abc[0],
            self.m_abc[1],
            self.m_abc[2],
            self.i_dc_ref,
            self.p_src_min,
            self.p_src_max,
            self.p,
            self.q,
            self.v,
            self.df,
            self.theta,
            self.e,
            self.p_set,
            self.q_ref,
            self.p_avail,
            self.i_ac,
            flag(self.limit_current),
            flag(self.limit_modulation),
            flag(self.limit_source),
        ]
    }
}

/// FNV-1a over the values' bits.
pub fn hash<'a>(values: impl IntoIterator<Item = &'a f64>) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for v in values {
        for b in v.to_bits().to_le_bytes() {
            h ^= u64::from(b);
            h = h.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
    h
}

/// One step of a trajectory: the measurement at `t`, the step `h`, the hash of the command.
#[derive(Debug, Clone, PartialEq)]
pub struct StepRecord {
    pub t: f64,
    pub h: f64,
    pub inputs: [f64; 10],
    pub hash: u64,
}

/// A recorded trajectory (see the module's documentation).
#[derive(Debug, Clone, PartialEq)]
pub struct Trajectory {
    pub case: String,
    pub comments: Vec<String>,
    pub params: Vec<(String, ParamValue)>,
    pub gains: OperatorGains,
    pub init_t: f64,
    pub init_inputs: [f64; 10],
    pub init_outputs: [f64; N_OUT],
    pub steps: Vec<StepRecord>,
    /// Full commands of some steps (1-based step numbers).
    pub full: Vec<(usize, [f64; N_OUT])>,
    /// Per-output hashes over the steps `k0..=k1`.
    pub blocks: Vec<(usize, usize, [u64; N_OUT])>,
}

fn hex(x: f64) -> String {
    format!("{:016x}", x.to_bits())
}

fn unhex(s: &str) -> Result<f64, String> {
    if s.len() != 16 {
        return Err(format!("\"{s}\": a real is 16 hex digits"));
    }
    u64::from_str_radix(s, 16)
        .map(f64::from_bits)
        .map_err(|e| format!("\"{s}\": {e}"))
}

/// A mismatch of a replay with a trajectory: where and which outputs.
#[derive(Debug, Clone, PartialEq)]
pub struct Mismatch {
    pub case: String,
    /// 0: the command of initialization; k: step k.
    pub step: usize,
    pub t: f64,
    /// The outputs that differ (at `step`, or within its block where only hashes are kept).
    pub signals: Vec<String>,
    /// Recorded and replayed values, where the trajectory keeps the step in full.
    pub values: Vec<(String, f64, f64)>,
    /// The steps the signals were located within.
    pub within: (usize, usize),
}

impl fmt::Display for Mismatch {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}: first mismatch at step {} (t = {}): {}",
            self.case,
            self.step,
            self.t,
            self.signals.join(", ")
        )?;
        if self.within != (self.step, self.step) {
            write!(
                f,
                " (the outputs whose values differ within steps {}..={})",
                self.within.0, self.within.1
            )?;
        }
        for (name, want, got) in &self.values {
            write!(
                f,
                "; {name}: recorded {want:e} ({}), replayed {got:e} ({})",
                hex(*want),
                hex(*got)
            )?;
        }
        Ok(())
    }
}

impl Trajectory {
    /// A trajectory of `case` from its initialization and its steps (measurement, step, command).
    pub fn record(
        case: &str,
        comments: &[&str],
        params: Vec<(String, ParamValue)>,
        gains: OperatorGains,
        init: (&EmtMeasurement, &EmtCommand),
        steps: &[(EmtMeasurement, f64, EmtCommand)],
    ) -> Trajectory {
        let outs: Vec<[f64; N_OUT]> = steps.iter().map(|s| s.2.outputs()).collect();
        let n = steps.len();
        let full = (1..=n)
            .filter(|k| *k <= FULL || *k > n.saturating_sub(FULL))
            .map(|k| (k, outs[k - 1]))
            .collect();
        Trajectory {
            case: case.to_string(),
            comments: comments.iter().map(|c| c.to_string()).collect(),
            params,
            gains,
            init_t: init.0.t,
            init_inputs: init.0.inputs(),
            init_outputs: init.1.outputs(),
            steps: steps
                .iter()
                .zip(&outs)
                .map(|((m, h, _), o)| StepRecord {
                    t: m.t,
                    h: *h,
                    inputs: m.inputs(),
                    hash: hash(o),
                })
                .collect(),
            full,
            blocks: block_hashes(&outs),
        }
    }

    /// The text of the trajectory.
    pub fn to_text(&self) -> String {
        let mut s = format!("{MAGIC}\ncase {}\n", self.case);
        for c in &self.comments {
            let _ = writeln!(s, "# {c}");
        }
        for (name, v) in &self.params {
            let _ = match v {
                ParamValue::Real(x) => writeln!(s, "param {name} r {}", hex(*x)),
                ParamValue::Integer(i) => writeln!(s, "param {name} i {i}"),
                ParamValue::Boolean(b) => writeln!(s, "param {name} b {}", u8::from(*b)),
            };
        }
        let g = &self.gains;
        let words = |xs: &[f64]| xs.iter().map(|x| hex(*x)).collect::<Vec<_>>().join(" ");
        let _ = writeln!(
            s,
            "gains {} {} {}",
            hex(g.mu_p),
            hex(g.mu_q),
            words(&g.mu_p_lpf)
        );
        let _ = writeln!(s, "init {} {}", hex(self.init_t), words(&self.init_inputs));
        let _ = writeln!(s, "out 0 {}", words(&self.init_outputs));
        for st in &self.steps {
            let _ = writeln!(
                s,
                "step {} {} {} {:016x}",
                hex(st.t),
                hex(st.h),
                words(&st.inputs),
                st.hash
            );
        }
        for (k, o) in &self.full {
            let _ = writeln!(s, "out {k} {}", words(o));
        }
        for (k0, k1, hs) in &self.blocks {
            let hs: Vec<String> = hs.iter().map(|h| format!("{h:016x}")).collect();
            let _ = writeln!(s, "block {k0} {k1} {}", hs.join(" "));
        }
        s
    }

    /// The trajectory of `text`, or why it is none (with the line number).
    pub fn parse(text: &str) -> Result<Trajectory, String> {
        let mut lines = text.lines().enumerate();
        match lines.next() {
            Some((_, l)) if l == MAGIC => {}
            _ => return Err(format!("line 1: not \"{MAGIC}\"")),
        }
        let mut t = Trajectory {
            case: String::new(),
            comments: vec![],
            params: vec![],
            gains: OperatorGains {
                mu_p: 0.0,
                mu_q: 0.0,
                mu_p_lpf: [0.0; MAX_LPF],
            },
            init_t: 0.0,
            init_inputs: [0.0; 10],
            init_outputs: [0.0; N_OUT],
            steps: vec![],
            full: vec![],
            blocks: vec![],
        };
        for (n, line) in lines {
            let at = |e: String| format!("line {}: {e}", n + 1);
            if let Some(c) = line.strip_prefix('#') {
                t.comments.push(c.trim_start().to_string());
                continue;
            }
            let w: Vec<&str> = line.split(' ').collect();
            let reals =
                |ws: &[&str]| -> Result<Vec<f64>, String> { ws.iter().map(|x| unhex(x)).collect() };
            let count = |k: usize| {
                if w.len() == k {
                    Ok(())
                } else {
                    Err(at(format!("{} words, expected {k}", w.len())))
                }
            };
            match w[0] {
                "case" => {
                    count(2)?;
                    t.case = w[1].to_string();
                }
                "param" => {
                    count(4)?;
                    let v = match w[2] {
                        "r" => ParamValue::Real(unhex(w[3]).map_err(at)?),
                        "i" => ParamValue::Integer(w[3].parse().map_err(|e| at(format!("{e}")))?),
                        "b" => ParamValue::Boolean(w[3] == "1"),
                        k => return Err(at(format!("type \"{k}\": r, i or b"))),
                    };
                    t.params.push((w[1].to_string(), v));
                }
                "gains" => {
                    count(3 + MAX_LPF)?;
                    let x = reals(&w[1..]).map_err(at)?;
                    t.gains.mu_p = x[0];
                    t.gains.mu_q = x[1];
                    t.gains.mu_p_lpf.copy_from_slice(&x[2..]);
                }
                "init" => {
                    count(12)?;
                    let x = reals(&w[1..]).map_err(at)?;
                    t.init_t = x[0];
                    t.init_inputs.copy_from_slice(&x[1..]);
                }
                "out" => {
                    count(2 + N_OUT)?;
                    let k: usize = w[1].parse().map_err(|e| at(format!("{e}")))?;
                    let mut o = [0.0; N_OUT];
                    o.copy_from_slice(&reals(&w[2..]).map_err(at)?);
                    if k == 0 {
                        t.init_outputs = o;
                    } else {
                        t.full.push((k, o));
                    }
                }
                "step" => {
                    count(14)?;
                    let x = reals(&w[1..13]).map_err(at)?;
                    let mut inputs = [0.0; 10];
                    inputs.copy_from_slice(&x[2..]);
                    t.steps.push(StepRecord {
                        t: x[0],
                        h: x[1],
                        inputs,
                        hash: u64::from_str_radix(w[13], 16).map_err(|e| at(format!("{e}")))?,
                    });
                }
                "block" => {
                    count(3 + N_OUT)?;
                    let k = |s: &str| s.parse::<usize>().map_err(|e| at(format!("{e}")));
                    let mut hs = [0u64; N_OUT];
                    for (h, s) in hs.iter_mut().zip(&w[3..]) {
                        *h = u64::from_str_radix(s, 16).map_err(|e| at(format!("{e}")))?;
                    }
                    t.blocks.push((k(w[1])?, k(w[2])?, hs));
                }
                other => return Err(at(format!("unknown line \"{other}\""))),
            }
        }
        if t.case.is_empty() || t.steps.is_empty() {
            return Err("no case or no steps".into());
        }
        Ok(t)
    }

    /// The measurement of step `k` (1-based).
    pub fn measurement(&self, k: usize) -> EmtMeasurement {
        let s = &self.steps[k - 1];
        EmtMeasurement::from_inputs(s.t, &s.inputs)
    }

    /// The measurement at initialization.
    pub fn init_measurement(&self) -> EmtMeasurement {
        EmtMeasurement::from_inputs(self.init_t, &self.init_inputs)
    }

    /// Whether a replay's commands (`init`, then one per step) are the recorded ones bit for
    /// bit; else the first step that differs and its outputs.
    pub fn compare(&self, init: &[f64; N_OUT], steps: &[[f64; N_OUT]]) -> Result<(), Mismatch> {
        let differing = |want: &[f64; N_OUT], got: &[f64; N_OUT]| -> Vec<(String, f64, f64)> {
            (0..N_OUT)
                .filter(|&j| want[j].to_bits() != got[j].to_bits())
                .map(|j| (OUTPUTS[j].to_string(), want[j], got[j]))
                .collect()
        };
        let d = differing(&self.init_outputs, init);
        if !d.is_empty() {
            return Err(Mismatch {
                case: self.case.clone(),
                step: 0,
                t: self.init_t,
                signals: d.iter().map(|x| x.0.clone()).collect(),
                values: d,
                within: (0, 0),
            });
        }
        if steps.len() != self.steps.len() {
            let k = steps.len().min(self.steps.len()) + 1;
            return Err(Mismatch {
                case: self.case.clone(),
                step: k,
                t: self.steps.get(k - 1).map_or(f64::NAN, |s| s.t),
                signals: vec![format!(
                    "the replay has {} steps, the trajectory {}",
                    steps.len(),
                    self.steps.len()
                )],
                values: vec![],
                within: (k, k),
            });
        }
        let Some(k) = (1..=steps.len()).find(|&k| hash(&steps[k - 1]) != self.steps[k - 1].hash)
        else {
            return Ok(());
        };
        let t = self.steps[k - 1].t;
        if let Some((_, want)) = self.full.iter().find(|(j, _)| *j == k) {
            let d = differing(want, &steps[k - 1]);
            return Err(Mismatch {
                case: self.case.clone(),
                step: k,
                t,
                signals: d.iter().map(|x| x.0.clone()).collect(),
                values: d,
                within: (k, k),
            });
        }
        let (k0, k1, want) = self
            .blocks
            .iter()
            .find(|(a, b, _)| (*a..=*b).contains(&k))
            .copied()
            .unwrap_or((k, k, [0; N_OUT]));
        let got = block_hashes(&steps[k0 - 1..k1]);
        let signals = (0..N_OUT)
            .filter(|&j| got.first().is_none_or(|g| g.2[j] != want[j]))
            .map(|j| OUTPUTS[j].to_string())
            .collect();
        Err(Mismatch {
            case: self.case.clone(),
            step: k,
            t,
            signals,
            values: vec![],
            within: (k, k1),
        })
    }
}

/// Per-output hashes over blocks of [`BLOCK`] steps of `outs` (step numbers from 1).
fn block_hashes(outs: &[[f64; N_OUT]]) -> Vec<(usize, usize, [u64; N_OUT])> {
    outs.chunks(BLOCK)
        .enumerate()
        .map(|(b, chunk)| {
            let mut hs = [0u64; N_OUT];
            for (j, h) in hs.iter_mut().enumerate() {
                *h = hash(chunk.iter().map(|o| &o[j]));
            }
            (b * BLOCK + 1, b * BLOCK + chunk.len(), hs)
        })
        .collect()
}

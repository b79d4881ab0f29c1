//! The grid's outputs: per DER slot, machine, PCC and POC, the power balance, and the
//! centre-of-inertia checks on the machines' angles.

use super::{Grid, FREQUENCY_BAND, LOSS_OF_SYNCHRONISM_ANGLE};
use crate::case::{BranchData, DerKind};
use crate::der::{DerInput, DerRt};
use crate::error::GridError;
use crate::machine::MachineRt;
use crate::machine::{rot, state};
use crate::numerics::{C64, CONST_POWER_V_MIN};
use serde::{Deserialize, Serialize};

/// Per-slot outputs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct DerOutput {
    /// Active power injected into the bus, pu on S_base.
    pub p: f64,
    /// Reactive power injected into the bus, pu on S_base.
    pub q: f64,
    /// Voltage magnitude of the slot's bus, pu.
    pub v: f64,
    /// Voltage angle of the slot's bus, rad, frame at f_nom, continuous (unwrapped).
    pub v_angle: f64,
}

/// PCC outputs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct PccOutput {
    /// Sum of the PCC slots' and branches' active injections, pu on S_base.
    pub p: f64,
    pub q: f64,
    /// PCC bus voltage magnitude, pu.
    pub v: f64,
    /// PCC frequency, pu (1 = f_nom): 1 + (1/ω_b) · s/(T_f s + 1) applied to the bus angle.
    pub f: f64,
    /// PCC bus angle, rad, continuous.
    pub angle: f64,
}

/// Per-machine outputs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct MachineOutput {
    /// Rotor speed, pu. After a trip the unit runs isolated: its rotor keeps being integrated
    /// with no electrical power, driven by its turbine under its own governor (a unit without
    /// governor has its turbine tripped with it). The governor models have no overspeed
    /// protection or intercept valves, so a reheat or hydro unit overspeeds well beyond what
    /// a real unit's protection would allow.
    pub omega: f64,
    /// Electrical active power at the terminal, pu on S_base.
    pub p: f64,
    pub q: f64,
    /// Air-gap power, pu on S_base (p, q, pe and efd are 0 after a trip).
    pub pe: f64,
    /// Mechanical power, pu on S_base (also after a trip).
    pub pm: f64,
    /// Field voltage, pu.
    pub efd: f64,
    /// Rotor angle, rad, frame at f_nom.
    pub delta: f64,
    /// Terminal voltage, pu.
    pub vt: f64,
    /// False once the machine has tripped; COI and totals count in-service machines only.
    pub in_service: bool,
}

/// All outputs at the current time.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Outputs {
    pub t: f64,
    pub der: Vec<DerOutput>,
    pub pcc: PccOutput,
    /// Per point of coupling (case `[[poc]]`): the power the area sends through its branches
    /// (positive: the area feeds the grid; at the POC bus or the area side, `Poc::side`), its bus voltage, frequency and angle.
    pub poc: Vec<PccOutput>,
    /// Per DVPP PCC (case `[[dvpp_pcc]]`): its slots' summed injection, its bus voltage,
    /// frequency and angle.
    pub dvpp_pcc: Vec<PccOutput>,
    /// Active and reactive power the loads inside the POC area draw (0 without POCs), pu.
    pub area_p_load: f64,
    pub area_q_load: f64,
    /// Inertia-weighted mean speed of the in-service machines, pu (PCC frequency if none).
    pub coi_f: f64,
    pub sg: Vec<MachineOutput>,
    /// Total generation: machine terminal powers + DER slot injections, pu on S_base.
    pub gen_p: f64,
    /// Total load: loads, event loads and shunt conductances, pu.
    pub load_p: f64,
    /// Series losses in lines and transformers, pu.
    pub loss_p: f64,
    /// gen_p − load_p − loss_p (zero up to the network tolerance).
    pub balance_p: f64,
    /// The bus fault's current and its bus voltage (all zero without a fault).
    pub fault: super::FaultOutput,
}

impl Grid {
    fn der_power(&self, d: &DerRt) -> C64 {
        let vb = self.sol.v[d.bus];
        match (d.input, d.limit.is_none()) {
            (DerInput::GridFollowing { p_ref, q_ref }, true) => C64::new(p_ref, q_ref),
            _ => vb * d.current(vb).conj(),
        }
    }

    /// All outputs at the current time (from the last network solution).
    /// Whether a voltage source is left: a machine in service or a grid-forming slot. Without
    /// one the network is de-energized (every bus voltage 0): a phasor network of current
    /// injections alone has no angle reference, and grid-following units, which only follow the
    /// voltage they measure, cannot hold one (they lose synchronism).
    pub fn energized(&self) -> bool {
        Self::has_voltage_source(&self.machines, &self.ders)
    }

    /// Whether a machine is in service or a grid-forming unit is connected.
    pub(super) fn has_voltage_source(machines: &[MachineRt], ders: &[DerRt]) -> bool {
        machines.iter().any(|m| m.in_service) || ders.iter().any(|d| d.kind == DerKind::GridForming)
    }

    pub fn outputs(&self) -> Outputs {
        let mut out = Outputs {
            t: self.t,
            ..Default::default()
        };
        let mut gen = 0.0;
        for (k, d) in self.ders.iter().enumerate() {
            let s = self.der_power(d);
            gen += s.re;
            out.der.push(DerOutput {
                p: s.re,
                q: s.im,
                v: dvpp_math::cabs(self.sol.v[d.bus]),
                v_angle: self.der_angle[k],
            });
        }
        let (mut hw, mut hs) = (0.0, 0.0);
        for m in &self.machines {
            let xm = m.own(&self.x);
            let vt = self.sol.v[m.bus];
            let mut o = MachineOutput {
                omega: xm[state::OMEGA],
                delta: xm[state::DELTA],
                vt: dvpp_math::cabs(vt),
                pm: m.pm_sys(&self.x, self.sb),
                in_service: m.in_service,
                ..Default::default()
            };
            if m.in_service {
                let r = rot(xm[state::DELTA]);
                let a = m.stator(xm, vt, r);
                let i = C64::new(a.id, a.iq) * r.conj();
                let s = vt * i.conj();
                o.p = s.re;
                o.q = s.im;
                o.pe = m.pe(&a);
                o.efd = m.efd(&self.x, dvpp_math::cabs(vt));
                gen += s.re;
                hw += m.h * xm[state::OMEGA];
                hs += m.h;
            }
            out.sg.push(o);
        }
        let mut load = 0.0;
        for i in 0..self.n {
            let vm2 = self.sol.v[i].norm_sqr();
            load += self.load_y[i].re * vm2;
            let s = self.load_s[i];
            load += if vm2.sqrt() >= CONST_POWER_V_MIN {
                s.re
            } else {
                s.re * vm2 / (CONST_POWER_V_MIN * CONST_POWER_V_MIN)
            };
        }
        for s in &self.case.shunts {
            if let Some(i) = self.case.buses.iter().position(|b| b.id == s.bus) {
                load += s.g * self.sol.v[i].norm_sqr();
            }
        }
        // A bus fault is a shunt too: its resistance's power while it is on.
        if let Some((i, y)) = self.fault_shunt() {
            load += y.re * self.sol.v[i].norm_sqr();
        }
        let mut loss = 0.0;
        for br in self.branches.iter().filter(|b| b.in_service) {
            let (sf, st) = self.branch_flows(br);
            loss += sf.re + st.re;
        }
        // PCC
        let mut sp = C64::new(0.0, 0.0);
        for &k in &self.pcc_slots {
            sp += self.der_power(&self.ders[k]);
        }
        for &(b, at) in &self.pcc_branches {
            let br = &self.branches[b];
            if br.in_service {
                let (sf, st) = self.branch_flows(br);
                sp += if at == br.from { sf } else { st };
            }
        }
        let f = 1.0 + (self.pcc_angle - self.x[self.pcc_state]) / (self.pcc_tf * self.wb);
        out.pcc = PccOutput {
            p: sp.re,
            q: sp.im,
            v: dvpp_math::cabs(self.sol.v[self.pcc_bus]),
            f,
            angle: self.pcc_angle,
        };
        for (k, p) in self.pocs.iter().enumerate() {
            let mut s = C64::new(0.0, 0.0);
            for &j in &p.slots {
                s += self.der_power(&self.ders[j]);
            }
            for &b in &p.branches {
                let br = &self.branches[b];
                if br.in_service {
                    let (sf, st) = self.branch_flows(br);
                    // flows leave each end into the branch: the area side's counts as it is,
                    // the POC bus's with its sign turned (what the branch delivers there)
                    let at_bus = p.bus == br.from;
                    s += match (p.area_side, at_bus) {
                        (true, true) => st,
                        (true, false) => sf,
                        (false, true) => -sf,
                        (false, false) => -st,
                    };
                }
            }
            let th = self.poc_angle[k];
            let measured = PccOutput {
                p: s.re,
                q: s.im,
                v: dvpp_math::cabs(self.sol.v[p.bus]),
                f: 1.0 + (th - self.x[self.pcc_state + 1 + k]) / (p.tf * self.wb),
                angle: th,
            };
            if k < self.case.pocs.len() {
                out.poc.push(measured);
            } else {
                out.dvpp_pcc.push(measured);
            }
        }
        for &i in &self.area {
            let vm2 = self.sol.v[i].norm_sqr();
            let s = self.load_s[i];
            let sc = if vm2.sqrt() >= CONST_POWER_V_MIN {
                s
            } else {
                s * vm2 / (CONST_POWER_V_MIN * CONST_POWER_V_MIN)
            };
            let sl = self.load_y[i].conj() * vm2 + sc;
            out.area_p_load += sl.re;
            out.area_q_load += sl.im;
        }
        out.coi_f = if hs > 0.0 { hw / hs } else { f };
        out.gen_p = gen;
        out.load_p = load;
        out.loss_p = loss;
        out.balance_p = gen - load - loss;
        out.fault = self.fault_output();
        out
    }

    /// Centre-of-inertia angle, rad, frame at f_nom: the mean rotor angle of the in-service
    /// machines weighted by their inertia constants on S_base (the weights of `coi_f`); None
    /// without machines in service.
    pub fn coi_angle(&self) -> Option<f64> {
        let (mut hd, mut hs) = (0.0, 0.0);
        for m in self.machines.iter().filter(|m| m.in_service) {
            hd += m.h * m.own(&self.x)[state::DELTA];
            hs += m.h;
        }
        (hs > 0.0).then(|| hd / hs)
    }

    /// Centre-of-inertia frequency, pu: the inertia-weighted mean speed of the in-service
    /// machines (the `coi_f` output); None without machines in service.
    pub fn coi_frequency(&self) -> Option<f64> {
        let (mut hw, mut hs) = (0.0, 0.0);
        for m in self.machines.iter().filter(|m| m.in_service) {
            hw += m.h * m.own(&self.x)[state::OMEGA];
            hs += m.h;
        }
        (hs > 0.0).then(|| hw / hs)
    }

    /// The centre-of-inertia frequency within [`FREQUENCY_BAND`] (nothing to check without
    /// machines in service).
    pub fn check_frequency(&self) -> Result<(), GridError> {
        let Some(f) = self.coi_frequency() else {
            return Ok(());
        };
        let (lo, hi) = FREQUENCY_BAND;
        if f < lo || f > hi || f.is_nan() {
            return Err(GridError::FrequencyCollapse {
                t: self.t,
                f,
                f_nom: self.case.f_nom,
            });
        }
        Ok(())
    }

    /// Loss of synchronism: every in-service machine's rotor angle and every grid-forming slot's
    /// internal voltage angle θ (both in the frame rotating at f_nom, as the COI angle) must lie
    /// within [`LOSS_OF_SYNCHRONISM_ANGLE`] of the centre-of-inertia angle. The first unit
    /// beyond it (machines first) is returned as [`GridError::LossOfSynchronism`]. Without
    /// machines in service there is no centre of inertia and nothing to check. Reads the states
    /// only.
    pub fn check_synchronism(&self) -> Result<(), GridError> {
        let Some(coi) = self.coi_angle() else {
            return Ok(());
        };
        let lost = |unit: String, angle: f64| GridError::LossOfSynchronism {
            t: self.t,
            unit,
            angle,
        };
        for (j, m) in self.machines.iter().enumerate() {
            if !m.in_service {
                continue;
            }
            let rel = m.own(&self.x)[state::DELTA] - coi;
            // a NaN angle counts as lost too
            if rel.abs() > LOSS_OF_SYNCHRONISM_ANGLE || rel.is_nan() {
                let name = match &self.case.machines[j].name {
                    Some(n) => format!("machine {n}"),
                    None => format!("machine {}", j + 1),
                };
                return Err(lost(name, rel));
            }
        }
        // Grid-forming slots are not checked: their angle is an input, and the grid cannot tell
        // a unit that slips from an input held by a master (the FMU run alone, a held θ against
        // machines that settle off nominal frequency, drifts by design).
        Ok(())
    }

    /// Current bus voltages (complex, frame at f_nom).
    pub fn bus_voltages(&self) -> Vec<(f64, f64)> {
        self.sol
            .v
            .iter()
            .map(|&v| (dvpp_math::cabs(v), dvpp_math::carg(v)))
            .collect()
    }
    /// Complex powers entering a branch at its `from` and `to` ends (current bus voltages).
    pub(super) fn branch_flows(&self, br: &BranchData) -> (C64, C64) {
        let ys = C64::new(1.0, 0.0) / C64::new(br.r, br.x);
        let hb = C64::new(0.0, br.b / 2.0);
        let (vf, vt) = (self.sol.v[br.from], self.sol.v[br.to]);
        let t = br.tap;
        let i_f = (ys / (t * t) + hb) * vf - ys / t * vt;
        let i_t = (ys + hb) * vt - ys / t * vf;
        (vf * i_f.conj(), vt * i_t.conj())
    }
}

//! The test bench's circuit (faults balanced and unbalanced, a line and a parallel line from the source bus, the source's breaker, grounded units) in the αβ0 frame, discretized exactly per topology.
//!
//! The plant's network ([`crate::network`]) is balanced and three-wire, so its α and β axes
//! are two copies of one circuit. The bench adds what breaks that: a fault between phases and
//! ground, units whose zero sequence has a path to ground, a source bus behind the Thevenin impedance. The
//! circuit is written in the amplitude-invariant αβ0 components: every element but a fault is
//! the same in each phase, so it is one branch per axis (α, β and, where a zero-sequence path
//! exists, 0); a fault is a set of abc branches (phase to ground, phase to phase), which couple
//! the axes at the faulted node. Powers in pu keep the plant's convention
//! `p = (2/3)(v_a i_a + v_b i_b + v_c i_c) = v_α i_α + v_β i_β + 2 v_0 i_0`: each branch carries
//! an axis weight (1 on α and β, 2 on 0, 2/3 for an abc branch) in its energies.
//!
//! The node voltages (the PCC, and the source bus when a line is declared) join only inductive
//! branches and are eliminated as in the plant: the derivative of KCL, weighted by the axis
//! weights, gives `Y V = -Σ_b (c_b w_b/L_b) a_b (d_bᵀ z - R_b i_b)` with the symmetric positive
//! semi-definite `Y = Σ_b c_b w_b a_b a_bᵀ/L_b` (`a_b`: how the node voltages drive branch `b`,
//! `d_b`: how the states do, `c_b`: its current scale on `S_base`). A component no branch reaches
//! (the zero sequence of a node with nothing grounded on it) is null in `Y` and held at 0: it
//! carries no current. Over a step `z(t+h) = exp(M h) z(t)` with the energy integrals of Van
//! Loan's block exponential, as in [`crate::network`].
//!
//! A switching acts at a step boundary. A branch that closes starts with zero current. A branch
//! that opens (a fault cleared, the source's breaker, the parallel line taken out) loses its
//! current at once; the currents left must satisfy KCL again, and the ideal breaker's voltage
//! impulse sets them: the jump of each inductor current is `a_bᵀ λ/L_b` with `λ` such that KCL
//! holds (flux linkage is conserved around every loop that stays closed). The magnetic energy
//! this removes is the switching account, so the energy balance closes.

use crate::network::{exact_discretization, Branch, UnitData};
use crate::steady::C;
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

const SQRT3: f64 = 1.732_050_807_568_877_2;

/// The α and β coefficients of phase a, b, c: `v_x = c_α v_α + c_β v_β + v_0`.
const PHASE: [[f64; 2]; 3] = [[1.0, 0.0], [-0.5, 0.5 * SQRT3], [-0.5, -0.5 * SQRT3]];

/// The kind of a fault (`fault.type`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum FaultKind {
    /// All three phases to ground, each through the fault impedance.
    ThreePhase,
    /// Phase a to ground.
    Slg,
    /// Phase b to phase c.
    Ll,
    /// Phases b and c to ground, each through the fault impedance.
    Llg,
}

impl FaultKind {
    /// The abc branches of the fault: per branch, the phase incidence (+1 where its current
    /// leaves the node, -1 where it returns; a branch to ground has one +1).
    fn branches(self) -> Vec<[f64; 3]> {
        match self {
            FaultKind::ThreePhase => vec![[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            FaultKind::Slg => vec![[1.0, 0.0, 0.0]],
            FaultKind::Ll => vec![[0.0, 1.0, -1.0]],
            FaultKind::Llg => vec![[0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        }
    }
}

/// A unit's grounding (`der[k].grounding`): where zero-sequence current can flow.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Grounding {
    /// Nowhere: a three-wire unit behind an ungrounded transformer (0).
    ThreeWire,
    /// Through the whole unit: YNyn transformer, the filter capacitors' star point and the
    /// converter's dc midpoint grounded (1); the modulation's zero sequence drives it.
    Star,
    /// In the transformer alone: its MV star grounded, its LV side a delta (Dyn seen from the
    /// grid, 2): zero-sequence current flows from the PCC through `R_t + jX_t` and circulates in
    /// the delta; none reaches the filter or the converter.
    Delta,
}

/// A fault: its kind, where, and its impedance (`z.l` as reactance at `ω_b`, pu on `S_base`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Fault {
    pub kind: FaultKind,
    /// At the source bus (behind the Thevenin impedance) rather than the PCC.
    pub at_source_bus: bool,
    pub z: Branch,
}

/// The bench's circuit data, fixed at initialization.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BenchData {
    pub units: Vec<UnitData>,
    /// Per unit: where its zero-sequence current can flow.
    pub grounding: Vec<Grounding>,
    pub loads: Vec<Branch>,
    /// The Thevenin impedance behind the source `e` (to the source bus, or to the PCC without a
    /// line).
    pub thevenin: Option<Branch>,
    /// A line from the source bus to the PCC.
    pub line: Option<Branch>,
    /// A switchable line beside the line (or beside the Thevenin impedance without a line).
    pub parallel: Option<Branch>,
    pub fault: Option<Fault>,
    pub s_base: f64,
    pub omega_b: f64,
}

/// Which branches are connected during a step.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
pub struct BenchTopo {
    /// Bit `j`: load `j` is connected.
    pub loads: u64,
    /// The source's breaker is closed (the Thevenin branch connected).
    pub thevenin: bool,
    /// The parallel line is in service.
    pub parallel: bool,
    /// Bit `j`: the fault's branch `j` is connected (its phases in [`FaultKind`]'s order).
    pub fault: u8,
    /// The converter voltage's α, β turn at `ω_b` over a step instead of being held.
    pub rotating_hold: bool,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
enum Role {
    Unit,
    Load(usize),
    Thevenin,
    Line,
    Parallel,
    Fault(usize),
}

/// An inductive branch: `(L/ω_b) i' = dᵀ z - R i + aᵀ V`.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct Ind {
    z: usize,
    r: f64,
    l: f64,
    /// Current scale on `S_base` (the unit's rating over `S_base`, 1 for the network).
    c: f64,
    /// Axis weight in powers and energies.
    w: f64,
    drive: Vec<(usize, f64)>,
    volt: Vec<(usize, f64)>,
    role: Role,
}

/// A filter capacitor: `(C/ω_b) v' = i_in - i_out`.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct Cap {
    z: usize,
    c: f64,
    i_in: usize,
    i_out: usize,
    /// Its unit's rating, MVA, times the axis weight.
    sw: f64,
}

/// Where one unit's states are, per axis α, β, 0 (`None` on 0 for a three-wire unit).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct UnitIdx {
    pub i_f: [Option<usize>; 3],
    pub v_c: [Option<usize>; 3],
    pub i_g: [Option<usize>; 3],
    /// The converter voltage (held input states).
    pub u: [Option<usize>; 3],
}

/// Indices of the energy forms after the `N` converter forms.
pub const FORM_AC_LOSS: usize = 0;
pub const FORM_THEVENIN: usize = 1;
pub const FORM_LOADS: usize = 2;
pub const FORM_FAULT: usize = 3;

/// The bench's circuit: its data and the branches it makes.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Bench {
    pub data: BenchData,
    #[serde(skip)]
    built: Built,
}

#[derive(Debug, Clone, Default)]
struct Built {
    inds: Vec<Ind>,
    caps: Vec<Cap>,
    /// Circuit states (the augmented state adds `e` and the converter voltages).
    nx: usize,
    n: usize,
    /// Node-voltage components: PCC α, β, 0, then the source bus's.
    nv: usize,
    units: Vec<UnitIdx>,
    loads: Vec<[usize; 2]>,
    th: Option<[usize; 3]>,
    line: Option<[usize; 3]>,
    par: Option<[usize; 3]>,
    /// Fault branches: state index and phase incidence.
    fault: Vec<(usize, [f64; 3])>,
    e: usize,
}

/// The PCC's node-voltage components start at 0, the source bus's at 3.
const PCC: usize = 0;
const BUS: usize = 3;

impl Bench {
    pub fn new(data: BenchData) -> Self {
        let mut b = Bench {
            data,
            built: Built::default(),
        };
        b.build();
        b
    }

    /// Rebuild the branches (after a restored FMU state, which stores the data alone).
    pub fn ensure_built(&mut self) {
        if self.built.n == 0 {
            self.build();
        }
    }

    fn build(&mut self) {
        let d = &self.data;
        let counter = std::cell::Cell::new(0usize);
        let next = || {
            counter.set(counter.get() + 1);
            counter.get() - 1
        };
        let axes = |g: Grounding| if g == Grounding::Star { 3 } else { 2 };
        // Circuit states, axis by axis.
        let mut units = vec![
            UnitIdx {
                i_f: [None; 3],
                v_c: [None; 3],
                i_g: [None; 3],
                u: [None; 3],
            };
            d.units.len()
        ];
        let mut loads = vec![[0usize; 2]; d.loads.len()];
        let (mut th, mut line, mut par) = ([0usize; 3], [0usize; 3], [0usize; 3]);
        for axis in 0..3 {
            for (k, u) in units.iter_mut().enumerate() {
                if axis < axes(d.grounding[k]) {
                    u.i_f[axis] = Some(next());
                    u.v_c[axis] = Some(next());
                    u.i_g[axis] = Some(next());
                } else if axis == 2 && d.grounding[k] == Grounding::Delta {
                    u.i_g[axis] = Some(next());
                }
            }
            if axis < 2 {
                for l in loads.iter_mut() {
                    l[axis] = next();
                }
            }
            if d.thevenin.is_some() {
                th[axis] = next();
            }
            if d.line.is_some() {
                line[axis] = next();
            }
            if d.parallel.is_some() {
                par[axis] = next();
            }
        }
        let fault: Vec<(usize, [f64; 3])> = d
            .fault
            .map(|f| f.kind.branches())
            .unwrap_or_default()
            .into_iter()
            .map(|inc| (next(), inc))
            .collect();
        let n_circuit = counter.get();
        let e = next();
        next();
        for (k, u) in units.iter_mut().enumerate() {
            for axis in 0..axes(d.grounding[k]) {
                u.u[axis] = Some(next());
            }
        }
        let n = counter.get();
        let has_bus = d.line.is_some();
        let nv = if has_bus { 6 } else { 3 };
        let th_node = if has_bus { BUS } else { PCC };
        let mut inds = Vec::new();
        let mut caps = Vec::new();
        let aw = |axis: usize| if axis == 2 { 2.0 } else { 1.0 };
        for (u, ix) in d.units.iter().zip(&units) {
            let c = u.s / d.s_base;
            if let (None, Some(g)) = (ix.v_c[2], ix.i_g[2]) {
                // The delta's zero sequence: the MV winding's leakage to ground.
                inds.push(Ind {
                    z: g,
                    r: u.r_t,
                    l: u.l_t,
                    c,
                    w: aw(2),
                    drive: vec![],
                    volt: vec![(PCC + 2, -1.0)],
                    role: Role::Unit,
                });
            }
            for axis in 0..3 {
                let (Some(f), Some(v), Some(g), Some(uu)) =
                    (ix.i_f[axis], ix.v_c[axis], ix.i_g[axis], ix.u[axis])
                else {
                    continue;
                };
                inds.push(Ind {
                    z: f,
                    r: u.r_f,
                    l: u.l_f,
                    c,
                    w: aw(axis),
                    drive: vec![(uu, 1.0), (v, -1.0)],
                    volt: vec![],
                    role: Role::Unit,
                });
                caps.push(Cap {
                    z: v,
                    c: u.c_f,
                    i_in: f,
                    i_out: g,
                    sw: u.s * aw(axis),
                });
                inds.push(Ind {
                    z: g,
                    r: u.r_t,
                    l: u.l_t,
                    c,
                    w: aw(axis),
                    drive: vec![(v, 1.0)],
                    volt: vec![(PCC + axis, -1.0)],
                    role: Role::Unit,
                });
            }
        }
        for (j, (l, ix)) in d.loads.iter().zip(&loads).enumerate() {
            for (axis, &z) in ix.iter().enumerate() {
                inds.push(Ind {
                    z,
                    r: l.r,
                    l: l.l,
                    c: 1.0,
                    w: 1.0,
                    drive: vec![],
                    volt: vec![(PCC + axis, 1.0)],
                    role: Role::Load(j),
                });
            }
        }
        let source = |axis: usize| {
            if axis < 2 {
                vec![(e + axis, 1.0)]
            } else {
                vec![]
            }
        };
        for axis in 0..3 {
            if let Some(b) = d.thevenin {
                inds.push(Ind {
                    z: th[axis],
                    r: b.r,
                    l: b.l,
                    c: 1.0,
                    w: aw(axis),
                    drive: source(axis),
                    volt: vec![(th_node + axis, -1.0)],
                    role: Role::Thevenin,
                });
            }
            let bus_to_pcc = vec![(BUS + axis, 1.0), (PCC + axis, -1.0)];
            if let Some(b) = d.line {
                inds.push(Ind {
                    z: line[axis],
                    r: b.r,
                    l: b.l,
                    c: 1.0,
                    w: aw(axis),
                    drive: vec![],
                    volt: bus_to_pcc.clone(),
                    role: Role::Line,
                });
            }
            if let Some(b) = d.parallel {
                let (drive, volt) = if has_bus {
                    (vec![], bus_to_pcc)
                } else {
                    (source(axis), vec![(PCC + axis, -1.0)])
                };
                inds.push(Ind {
                    z: par[axis],
                    r: b.r,
                    l: b.l,
                    c: 1.0,
                    w: aw(axis),
                    drive,
                    volt,
                    role: Role::Parallel,
                });
            }
        }
        if let Some(f) = d.fault {
            let node = if f.at_source_bus { BUS } else { PCC };
            for (j, &(z, inc)) in fault.iter().enumerate() {
                // The branch's voltage Σ_x inc_x v_x in αβ0 components.
                let mut volt = Vec::new();
                let (mut a, mut b, mut o) = (0.0, 0.0, 0.0);
                for (x, s) in inc.iter().enumerate() {
                    a += s * PHASE[x][0];
                    b += s * PHASE[x][1];
                    o += s;
                }
                for (i, v) in [a, b, o].into_iter().enumerate() {
                    if v != 0.0 {
                        volt.push((node + i, v));
                    }
                }
                inds.push(Ind {
                    z,
                    r: f.z.r,
                    l: f.z.l,
                    c: 1.0,
                    w: 2.0 / 3.0,
                    drive: vec![],
                    volt,
                    role: Role::Fault(j),
                });
            }
        }
        self.built = Built {
            inds,
            caps,
            nx: n_circuit,
            n,
            nv,
            units,
            loads,
            th: d.thevenin.map(|_| th),
            line: d.line.map(|_| line),
            par: d.parallel.map(|_| par),
            fault,
            e,
        };
    }

    /// Circuit states.
    pub fn nx(&self) -> usize {
        self.built.nx
    }
    /// Size of the augmented state.
    pub fn n(&self) -> usize {
        self.built.n
    }
    /// Index of `e_α` (`e_β` follows).
    pub fn e(&self) -> usize {
        self.built.e
    }
    pub fn unit(&self, k: usize) -> &UnitIdx {
        &self.built.units[k]
    }
    pub fn load(&self, j: usize) -> [usize; 2] {
        self.built.loads[j]
    }
    /// Unit `k`'s rating over `S_base`.
    pub fn c(&self, k: usize) -> f64 {
        self.data.units[k].s / self.data.s_base
    }

    fn on(&self, b: &Ind, topo: &BenchTopo) -> bool {
        match b.role {
            Role::Unit | Role::Line => true,
            Role::Load(j) => topo.loads >> j & 1 == 1,
            Role::Thevenin => topo.thevenin,
            Role::Parallel => topo.parallel && (self.data.line.is_some() || topo.thevenin),
            Role::Fault(j) => topo.fault >> j & 1 == 1,
        }
    }

    /// `Y` of the connected branches.
    fn y(&self, topo: &BenchTopo) -> DMatrix<f64> {
        let nv = self.built.nv;
        let mut y = DMatrix::zeros(nv, nv);
        for b in self.built.inds.iter().filter(|b| self.on(b, topo)) {
            let w = b.c * b.w / b.l;
            for &(p, cp) in &b.volt {
                for &(q, cq) in &b.volt {
                    y[(p, q)] += w * cp * cq;
                }
            }
        }
        y
    }

    /// The node voltages as a linear map of the augmented state, `V = G z` (PCC α, β, 0, then
    /// the source bus's).
    pub fn node_map(&self, topo: &BenchTopo) -> DMatrix<f64> {
        let (nv, n) = (self.built.nv, self.built.n);
        let mut rhs = DMatrix::zeros(nv, n);
        for b in self.built.inds.iter().filter(|b| self.on(b, topo)) {
            let w = b.c * b.w / b.l;
            for &(p, cp) in &b.volt {
                for &(j, c) in &b.drive {
                    rhs[(p, j)] -= w * cp * c;
                }
                rhs[(p, b.z)] += w * cp * b.r;
            }
        }
        solve_psd(&self.y(topo), &rhs)
    }

    /// The PCC voltage (α, β, 0) of an augmented state.
    pub fn vpcc(&self, topo: &BenchTopo, z: &DVector<f64>) -> [f64; 3] {
        let v = self.node_map(topo) * z;
        [v[PCC], v[PCC + 1], v[PCC + 2]]
    }

    /// The augmented continuous-time matrix `M`, `z' = M z`.
    pub fn continuous(&self, topo: &BenchTopo) -> DMatrix<f64> {
        let (n, wb) = (self.built.n, self.data.omega_b);
        let g = self.node_map(topo);
        let mut m = DMatrix::zeros(n, n);
        for b in self.built.inds.iter().filter(|b| self.on(b, topo)) {
            let k = wb / b.l;
            for &(j, c) in &b.drive {
                m[(b.z, j)] += k * c;
            }
            m[(b.z, b.z)] -= k * b.r;
            for &(p, cp) in &b.volt {
                for j in 0..n {
                    m[(b.z, j)] += k * cp * g[(p, j)];
                }
            }
        }
        for c in &self.built.caps {
            let k = wb / c.c;
            m[(c.z, c.i_in)] += k;
            m[(c.z, c.i_out)] -= k;
        }
        let mut rotate = |i: usize| {
            m[(i, i + 1)] = -wb;
            m[(i + 1, i)] = wb;
        };
        rotate(self.built.e);
        if topo.rotating_hold {
            for u in &self.built.units {
                if let Some(i) = u.u[0] {
                    rotate(i);
                }
            }
        }
        m
    }

    /// The symmetric matrices of the energy rates (MW): each unit's converter power, the
    /// resistive losses of filters, transformers, Thevenin impedance and lines, the source's
    /// power `e·i` (Thevenin branch, and the parallel line when it hangs on `e`), the loads'
    /// power, the fault's.
    pub fn energy_rates(&self, topo: &BenchTopo) -> Vec<DMatrix<f64>> {
        let n = self.built.n;
        let sb = self.data.s_base;
        let sym = |q: &mut DMatrix<f64>, i: usize, j: usize, w: f64| {
            q[(i, j)] += w / 2.0;
            q[(j, i)] += w / 2.0;
        };
        let mut out = Vec::new();
        for (k, ix) in self.built.units.iter().enumerate() {
            let mut q = DMatrix::zeros(n, n);
            for axis in 0..3 {
                if let (Some(u), Some(f)) = (ix.u[axis], ix.i_f[axis]) {
                    let w = if axis == 2 { 2.0 } else { 1.0 };
                    sym(&mut q, u, f, self.data.units[k].s * w);
                }
            }
            out.push(q);
        }
        let mut loss = DMatrix::zeros(n, n);
        let mut source = DMatrix::zeros(n, n);
        let mut loads = DMatrix::zeros(n, n);
        let mut fault = DMatrix::zeros(n, n);
        for b in self.built.inds.iter().filter(|b| self.on(b, topo)) {
            let rw = sb * b.c * b.w * b.r;
            let q = match b.role {
                Role::Unit | Role::Thevenin | Role::Line | Role::Parallel => &mut loss,
                Role::Load(_) => &mut loads,
                Role::Fault(_) => &mut fault,
            };
            sym(q, b.z, b.z, rw);
            for &(j, c) in &b.drive {
                if j == self.built.e || j == self.built.e + 1 {
                    sym(&mut source, j, b.z, sb * b.w * c);
                }
            }
        }
        out.extend([loss, source, loads, fault]);
        out
    }

    /// Magnetic and electric energy stored in the ac circuit, MJ.
    pub fn stored(&self, x: &[f64]) -> f64 {
        let mut w = 0.0;
        for b in &self.built.inds {
            w += self.data.s_base * b.c * b.w * b.l * x[b.z] * x[b.z];
        }
        for c in &self.built.caps {
            w += c.sw * c.c * x[c.z] * x[c.z];
        }
        w / (2.0 * self.data.omega_b)
    }

    /// Switch the circuit from topology `from` to `to` at a step boundary: the currents of the
    /// branches that open drop to zero and the inductor currents left jump to satisfy KCL with
    /// the flux linkages of closed loops kept. Returns the magnetic energy this removes, MJ.
    pub fn switch(&self, from: &BenchTopo, to: &BenchTopo, x: &mut [f64]) -> f64 {
        let w0 = self.stored(x);
        let mut opened = false;
        for b in &self.built.inds {
            if self.on(b, from) && !self.on(b, to) {
                x[b.z] = 0.0;
                opened = true;
            }
        }
        if !opened {
            return 0.0;
        }
        let nv = self.built.nv;
        let mut kcl = DMatrix::zeros(nv, 1);
        for b in self.built.inds.iter().filter(|b| self.on(b, to)) {
            for &(p, cp) in &b.volt {
                kcl[(p, 0)] -= b.c * b.w * cp * x[b.z];
            }
        }
        let lambda = solve_psd(&self.y(to), &kcl);
        for b in self.built.inds.iter().filter(|b| self.on(b, to)) {
            let mut s = 0.0;
            for &(p, cp) in &b.volt {
                s += cp * lambda[(p, 0)];
            }
            x[b.z] += s / b.l;
        }
        w0 - self.stored(x)
    }

    /// The Thevenin branch's, the line's and the parallel line's currents (α, β, 0), zero where
    /// not declared.
    pub fn grid_currents(&self, x: &[f64]) -> [[f64; 3]; 3] {
        let get = |ix: Option<[usize; 3]>| ix.map_or([0.0; 3], |i| i.map(|i| x[i]));
        [
            get(self.built.th),
            get(self.built.line),
            get(self.built.par),
        ]
    }

    /// The grid's current into the PCC (α, β, 0): through the line and the parallel line when a
    /// line is declared, else through the Thevenin branch and the parallel line.
    pub fn grid_current(&self, x: &[f64]) -> [f64; 3] {
        let [th, line, par] = self.grid_currents(x);
        let first = if self.data.line.is_some() { line } else { th };
        [0, 1, 2].map(|a| first[a] + par[a])
    }

    /// The fault's branches: each one's current (as its state), in [`FaultKind`]'s order.
    pub fn fault_branch_currents(&self, x: &[f64]) -> Vec<f64> {
        self.built.fault.iter().map(|(z, _)| x[*z]).collect()
    }

    /// All of the fault's branches (the bits of [`BenchTopo::fault`]).
    pub fn fault_all(&self) -> u8 {
        ((1u16 << self.built.fault.len()) - 1) as u8
    }

    /// The fault's current per phase, leaving the faulted node (pu on `S_base`).
    pub fn fault_current(&self, x: &[f64]) -> [f64; 3] {
        let mut i = [0.0; 3];
        for &(z, inc) in &self.built.fault {
            for (ix, s) in i.iter_mut().zip(inc) {
                *ix += s * x[z];
            }
        }
        i
    }

    /// Set a circuit state from the balanced steady state's phasors (α = Re, β = Im at the
    /// run's start), zero sequence 0.
    pub fn put(x: &mut [f64], ix: [Option<usize>; 3], c: C) {
        if let (Some(a), Some(b)) = (ix[0], ix[1]) {
            x[a] = c.re;
            x[b] = c.im;
        }
    }

    /// The Thevenin, line and parallel-line indices (α, β, 0).
    pub fn grid_index(&self) -> [Option<[usize; 3]>; 3] {
        [self.built.th, self.built.line, self.built.par]
    }

    /// The exact discretization at step `h` for `topo` (refused as in [`crate::network`]).
    pub fn discretize(&self, topo: &BenchTopo, h: f64) -> Result<BenchDiscrete, String> {
        let (phi, forms) = exact_discretization(
            self.continuous(topo) * h,
            self.energy_rates(topo),
            h,
        )
        .map_err(|norm| {
            format!(
                "the test bench's circuit cannot be discretized at h = {h} s: |M h| = {norm:e} (the step spans too many time constants of the fastest mode: a fault's R/X or a parameter is extreme)"
            )
        })?;
        Ok(BenchDiscrete {
            h,
            topo: *topo,
            phi,
            forms,
        })
    }
}

/// The bench's circuit sampled at one step for one topology.
#[derive(Debug, Clone)]
pub struct BenchDiscrete {
    pub h: f64,
    pub topo: BenchTopo,
    pub phi: DMatrix<f64>,
    pub forms: Vec<DMatrix<f64>>,
}

/// The bench's discretizations in use, most recent first.
#[derive(Debug, Clone, Default)]
pub struct BenchCache {
    entries: Vec<BenchDiscrete>,
}

impl BenchCache {
    pub fn get(
        &mut self,
        bench: &Bench,
        topo: &BenchTopo,
        h: f64,
    ) -> Result<&BenchDiscrete, String> {
        match self
            .entries
            .iter()
            .position(|d| d.h == h && d.topo == *topo)
        {
            Some(i) => {
                let d = self.entries.remove(i);
                self.entries.insert(0, d);
            }
            None => {
                self.entries.insert(0, bench.discretize(topo, h)?);
                self.entries.truncate(6);
            }
        }
        Ok(&self.entries[0])
    }
}

/// Solve `Y V = B` for a symmetric positive semi-definite `Y` by elimination with diagonal
/// pivoting; the components of `Y`'s null space (a node floating in one sequence) are set to 0.
fn solve_psd(y: &DMatrix<f64>, b: &DMatrix<f64>) -> DMatrix<f64> {
    let m = y.nrows();
    let scale = (0..m).map(|i| y[(i, i)]).fold(0.0f64, f64::max);
    let (mut a, mut r) = (y.clone(), b.clone());
    let mut left: Vec<usize> = (0..m).collect();
    let mut order = Vec::new();
    while let Some((pos, &p)) = left
        .iter()
        .enumerate()
        .max_by(|x, y| a[(*x.1, *x.1)].total_cmp(&a[(*y.1, *y.1)]))
    {
        if a[(p, p)] <= 1e-12 * scale || scale <= 0.0 {
            break;
        }
        left.remove(pos);
        order.push(p);
        for &i in &left {
            let f = a[(i, p)] / a[(p, p)];
            if f != 0.0 {
                for j in 0..m {
                    a[(i, j)] -= f * a[(p, j)];
                }
                for c in 0..r.ncols() {
                    r[(i, c)] -= f * r[(p, c)];
                }
            }
        }
    }
    let mut v = DMatrix::zeros(m, b.ncols());
    for &p in order.iter().rev() {
        for c in 0..b.ncols() {
            let mut s = r[(p, c)];
            for q in 0..m {
                if q != p {
                    s -= a[(p, q)] * v[(q, c)];
                }
            }
            v[(p, c)] = s / a[(p, p)];
        }
    }
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_floating_pair_is_pinned_and_the_rest_solved() {
        // Nodes 0 and 1 joined only to each other; node 2 grounded.
        let y = DMatrix::from_row_slice(3, 3, &[2.0, -2.0, 0.0, -2.0, 2.0, 0.0, 0.0, 0.0, 4.0]);
        let b = DMatrix::from_row_slice(3, 1, &[1.0, -1.0, 8.0]);
        let v = solve_psd(&y, &b);
        assert!((&y * &v - &b).amax() < 1e-12, "{v}");
        assert_eq!(v[(2, 0)], 2.0);
    }
}

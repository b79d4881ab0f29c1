//! The units of a bundling: the grid with the power flow the others start from, the DERs and
//! the operators, each configured and bundled into its FMU.

use der_model::ports as der;
use grid_model::ports as grid;
use model_description::ModelDescription;
use operator_model::ports as op;
use operator_model::{Form, Role};
use std::path::{Path, PathBuf};
use toml::{Table, Value};

use super::split::split_case;
use super::{
    plain_name, real, start_of, Build, Bundler, DerSpec, DvppSpec, Scenario, GRID, OPERATOR,
};
use dvpp_catalog::Fmu;

fn config_text(header: &str, model: Table, start: &Table) -> Result<String, String> {
    let mut doc = Table::new();
    doc.insert("model".into(), Value::Table(model));
    doc.insert("start".into(), Value::Table(start.clone()));
    let body = toml::to_string(&doc).map_err(|e| e.to_string())?;
    Ok(format!("# {header}\n{body}"))
}

/// The operator role of a DER from its p-f ADPF kind (`adpf.p.kind`).
fn role_of(md: &ModelDescription, der: &str) -> Result<Role, String> {
    let kind = start_of(md, der::ADPF_P_KIND).ok_or(format!("DER '{der}': no adpf.p.kind"))?;
    let kind = der_model::AdpfKind::from_code(kind as i32)
        .map_err(|e| format!("DER '{der}': adpf.p.kind {e}"))?;
    Ok(match kind {
        der_model::AdpfKind::Static | der_model::AdpfKind::LowPass => Role::LowPass,
        der_model::AdpfKind::HighPass => Role::HighPass,
        der_model::AdpfKind::BandPass => Role::BandPass,
        der_model::AdpfKind::Complement => Role::Complement,
    })
}

/// The `[model]` of a DER's FMU: its preset, resized to the slot's rating (its available power
/// and dispatch scale with it).
fn der_model(spec: &DerSpec, rating_mva: f64) -> Table {
    let mut model = Table::new();
    if let Some(p) = &spec.preset {
        model.insert("preset".into(), Value::String(p.clone()));
        model.insert("rating".into(), real(rating_mva));
    }
    model
}

/// A value of the operator's configuration (`Role`, `Form`) as its TOML string.
fn toml_of<T: serde::Serialize>(x: T) -> Result<Value, String> {
    Value::try_from(x).map_err(|e| e.to_string())
}

/// One bundling: the scenario, where it goes, and the bundler that makes each FMU.
pub(super) struct Job<'a, 'b> {
    pub(super) path: &'a Path,
    pub(super) name: String,
    pub(super) sc: Scenario,
    /// Each DER's named DVPP (index into `sc.dvpps`), all `None` with one DVPP or none.
    pub(super) member: Vec<Option<usize>>,
    pub(super) out_dir: &'a Path,
    pub(super) bundle_one: &'a mut Bundler<'b>,
}

/// A bundled component: its name, model description and start values.
pub(super) struct Unit {
    pub(super) name: String,
    pub(super) md: ModelDescription,
    pub(super) start: Table,
}

/// The grid step's result: the case and the power-flow point the other units start from.
pub(super) struct GridUnit {
    /// The grid FMU (none in an EMT-level system, where the case is the plant's data).
    pub(super) unit: Option<Unit>,
    pub(super) case: grid_model::Case,
    pub(super) pf: grid_model::Outputs,
}

/// A bundled DER and what its wiring depends on.
pub(super) struct DerUnit {
    pub(super) unit: Unit,
    /// 1-based slot in the grid.
    pub(super) slot: usize,
    /// 1-based entry in its DVPP's operator, and that operator's component name.
    pub(super) entry: usize,
    pub(super) operator: String,
    pub(super) forming: bool,
    /// An EMT-level controller on the plant's unit `slot` (else a phasor DER on the grid's slot).
    pub(super) emt: bool,
    pub(super) role: Role,
    /// A complement: the operator's low-pass gains it reads (1-based, in the operator's order).
    pub(super) closes: Vec<usize>,
}

/// What a DER is built for: its slot in the grid case or unit in the plant.
pub(super) struct Slot {
    pub(super) rating_mva: f64,
    /// The slot's impedance (phasor DERs), pu on the rating.
    pub(super) r: f64,
    pub(super) x: Option<f64>,
    pub(super) forming: bool,
    /// The power-flow point `(p, q, v, v_angle)` at the slot (phasor DERs).
    pub(super) point: Option<(f64, f64, f64, f64)>,
}

impl Job<'_, '_> {
    /// `e` prefixed with the scenario file.
    pub(super) fn here(&self, e: String) -> String {
        format!("{}: {e}", self.path.display())
    }

    /// Bundle the FMU of `(package, id)` as `component` with the given `[model]` and start values.
    pub(super) fn build(
        &mut self,
        fmu: &'static Fmu,
        component: &str,
        model: Table,
        start: &Table,
        files: Vec<PathBuf>,
    ) -> Result<ModelDescription, String> {
        (self.bundle_one)(&Build {
            fmu,
            staging: format!("{}-{component}", self.name),
            config: config_text(&self.sc.description, model, start)?,
            files,
            out: self.out_dir.join(format!("{component}.fmu")),
        })
    }

    /// DER names are component names: unique, not those of the grid or the operator, plain.
    pub(super) fn check_der_names(&self) -> Result<(), String> {
        let ders = &self.sc.der;
        for d in ders {
            if [GRID, OPERATOR, super::emt::PLANT].contains(&d.name.as_str())
                || d.name.starts_with("operator_")
                || ders.iter().filter(|x| x.name == d.name).count() > 1
                || !plain_name(&d.name)
            {
                return Err(self.here(format!(
                    "DER name '{}' must be unique, not 'grid', 'plant', 'operator' or 'operator_…', and made of letters, digits and _",
                    d.name
                )));
            }
        }
        Ok(())
    }

    /// The DVPPs: (name, operator component, DER indices); one unnamed DVPP without named ones.
    pub(super) fn groups(&self) -> Vec<(Option<String>, String, Vec<usize>)> {
        if self.sc.dvpps.is_empty() {
            return vec![(None, OPERATOR.into(), (0..self.sc.der.len()).collect())];
        }
        self.sc
            .dvpps
            .iter()
            .enumerate()
            .map(|(g, (name, _))| {
                let members = (0..self.sc.der.len())
                    .filter(|&k| self.member[k] == Some(g))
                    .collect();
                (Some(name.clone()), format!("operator_{name}"), members)
            })
            .collect()
    }

    /// The spec of DVPP `g` of [`Job::groups`].
    fn dvpp_spec(&self, g: usize) -> Option<&DvppSpec> {
        if self.sc.dvpps.is_empty() {
            self.sc.dvpp.as_ref()
        } else {
            self.sc.dvpps.get(g).map(|(_, d)| d)
        }
    }

    /// The DVPP (index of [`Job::groups`]) of DER `k`.
    fn group_of(&self, k: usize) -> usize {
        self.member[k].unwrap_or(0)
    }

    /// The grid: its configuration, and the power-flow point the other units start from; its
    /// FMU bundled if `bundle` (a phasor system).
    pub(super) fn grid(&mut self, bundle: bool) -> Result<GridUnit, String> {
        let here = |e: String| self.here(e);
        let spec = &self.sc.grid;
        let mut model = Table::new();
        let mut files = Vec::new();
        match (&spec.case, &spec.case_file) {
            (Some(c), None) => {
                model.insert("case".into(), Value::String(c.clone()));
            }
            (None, Some(f)) => {
                let file = self.path.parent().unwrap_or(Path::new(".")).join(f);
                let base = file
                    .file_name()
                    .and_then(|s| s.to_str())
                    .ok_or(here(format!("case_file {}: not a file", f.display())))?;
                model.insert("case_file".into(), Value::String(base.into()));
                files.push(file);
            }
            _ => return Err(here("[grid] needs one of `case` or `case_file`".into())),
        }
        if let Some(t) = spec.pcc_f_filter_t {
            model.insert("pcc_f_filter_t".into(), real(t));
        }
        if !spec.event.is_empty() {
            let events = spec.event.iter().cloned().map(Value::Table).collect();
            model.insert("event".into(), Value::Array(events));
        }
        let staging = self.out_dir.join(".grid-resources");
        let _ = std::fs::remove_dir_all(&staging);
        std::fs::create_dir_all(&staging).map_err(|e| e.to_string())?;
        for f in &files {
            std::fs::copy(f, staging.join(f.file_name().expect("file")))
                .map_err(|e| here(format!("case_file {}: {e}", f.display())))?;
        }
        let config: grid_model::GridConfig = Value::Table(model.clone())
            .try_into()
            .map_err(|e| here(format!("[grid]: {e}")))?;
        let mut case = config.load_case(Some(&staging)).map_err(here)?;
        let _ = std::fs::remove_dir_all(&staging);
        let eps = self.sc.dvpp.as_ref().and_then(|d| d.eps);
        if let Some(eps) = eps {
            let scale = self.sc.dvpp.as_ref().and_then(|d| d.rating_scale);
            case = split_case(&case, eps, scale.unwrap_or(1.0));
        }
        let rewritten = self.extend_case(&mut case).map_err(here)?;
        if eps.is_some() || rewritten {
            // The case as the scenario makes it (split, fleets, the DVPPs' PCCs), with the
            // scenario's events and filter already in it, goes to the grid FMU as its case file.
            let file = self.out_dir.join(format!(".{}-case.toml", self.name));
            let text = toml::to_string(&case).map_err(|e| here(format!("split case: {e}")))?;
            std::fs::write(&file, text).map_err(|e| here(format!("{}: {e}", file.display())))?;
            model = Table::new();
            model.insert(
                "case_file".into(),
                Value::String(format!(".{}-case.toml", self.name)),
            );
            files = vec![file];
        }
        apply_rx_starts(&mut case, &self.sc.grid.start).map_err(here)?;
        let pf = grid_model::Grid::new(&case)
            .map_err(|e| here(format!("grid: {e}")))?
            .outputs();
        let start = self.sc.grid.start.clone();
        let unit = if bundle {
            let md = self.build(&dvpp_catalog::GRID, GRID, model, &start, files.clone())?;
            Some(Unit {
                name: GRID.into(),
                md,
                start,
            })
        } else {
            None
        };
        if eps.is_some() || rewritten {
            let _ = std::fs::remove_file(&files[0]);
        }
        Ok(GridUnit { unit, case, pf })
    }

    /// The case as the scenario extends it: without its own slots (`case_slots = false`), the
    /// fleets' slots appended (and summed into the one DVPP's `[pcc]`), one `[[dvpp_pcc]]` per
    /// named DVPP. Returns whether anything changed.
    fn extend_case(&self, case: &mut grid_model::Case) -> Result<bool, String> {
        let mut changed = false;
        if !self.sc.grid.case_slots {
            if self.sc.fleet.is_empty() {
                return Err("[grid] case_slots = false leaves no DER slot: add a [[fleet]]".into());
            }
            case.ders.clear();
            if let Some(pcc) = &mut case.pcc {
                pcc.slots.clear();
                pcc.branches.clear();
            }
            changed = true;
        }
        let fleet = self.sc.fleet_slots(case)?;
        if !fleet.is_empty() {
            let first = case.ders.len() + 1;
            let n = fleet.len();
            case.ders.extend(fleet);
            if self.sc.dvpps.is_empty() {
                if let Some(pcc) = &mut case.pcc {
                    pcc.slots.extend(first..first + n);
                }
            }
            changed = true;
        }
        if case.ders.len() != self.sc.der.len() {
            return Err(format!(
                "the grid case has {} DER slots but the scenario lists {} DERs",
                case.ders.len(),
                self.sc.der.len()
            ));
        }
        if !self.sc.dvpps.is_empty() {
            if !case.pocs.is_empty() {
                return Err(
                    "named DVPPs measure at their own PCCs; a case with points of coupling ([[poc]]) needs a single [dvpp]"
                        .into(),
                );
            }
            let f_filter_t = self
                .sc
                .grid
                .pcc_f_filter_t
                .or(case.pcc.as_ref().map(|p| p.f_filter_t))
                .unwrap_or(0.02);
            for (g, (name, members)) in self
                .groups()
                .into_iter()
                .map(|(n, _, m)| (n.expect("named"), m))
                .enumerate()
            {
                let first = members
                    .first()
                    .ok_or(format!("[dvpp.{name}]: no DER belongs to it"))?;
                let bus = self.sc.dvpps[g].1.pcc_bus.unwrap_or(case.ders[*first].bus);
                if !case.buses.iter().any(|b| b.id == bus) {
                    return Err(format!(
                        "[dvpp.{name}] pcc_bus = {bus} is not a bus of the grid case"
                    ));
                }
                case.dvpp_pccs.push(grid_model::case::DvppPcc {
                    name: name.clone(),
                    bus,
                    slots: members.iter().map(|k| k + 1).collect(),
                    f_filter_t,
                });
            }
            changed = true;
        }
        if changed {
            case.validate()
                .map_err(|e| format!("the scenario's grid case: {e}"))?;
        }
        Ok(changed)
    }

    /// The rotation's R/X of DVPP `g` from its `rot_rx` (None: classical).
    fn rot_rx(&self, g: usize) -> Result<Option<f64>, String> {
        match self.dvpp_spec(g).and_then(|d| d.rot_rx) {
            Some(rx) if !(rx.is_finite() && rx >= 0.0) => Err(self.here(format!(
                "[dvpp] rot_rx = {rx}: the R/X ratio is finite and >= 0"
            ))),
            rx => Ok(rx),
        }
    }

    /// `T_des` of DVPP `g`, shared by its operator and its DERs.
    fn tdes(&self, g: usize) -> Table {
        let mut tdes = Table::new();
        if let Some(d) = self.dvpp_spec(g) {
            tdes.insert(der::S_DVPP.into(), real(d.s_dvpp));
            tdes.insert(der::TDES_H.into(), real(d.h));
            tdes.insert(der::TDES_D.into(), real(d.d));
            tdes.insert(der::TDES_DQ.into(), real(d.dq));
        }
        tdes
    }

    /// The slots of a phasor grid case, with their power-flow point.
    pub(super) fn slots(grid: &GridUnit) -> Vec<Slot> {
        grid.case
            .ders
            .iter()
            .zip(&grid.pf.der)
            .map(|(slot, o)| Slot {
                rating_mva: slot.rating_mva,
                r: slot.r,
                x: slot.x,
                forming: slot.kind == grid_model::DerKind::GridForming,
                point: Some((o.p, o.q, o.v, o.v_angle)),
            })
            .collect()
    }

    /// The DER FMU of the system's level.
    fn der_fmu(&self) -> &'static Fmu {
        if self.sc.emt.is_some() {
            &dvpp_catalog::DER_EMT
        } else {
            &dvpp_catalog::DER
        }
    }

    /// The DERs: preset, mode from the slot kind, (phasor) the power-flow point as input start
    /// values; then every complement unit again, with the time constants of the low-pass units
    /// it closes.
    pub(super) fn ders(&mut self, slots: &[Slot]) -> Result<Vec<DerUnit>, String> {
        let mut ders = Vec::with_capacity(self.sc.der.len());
        let groups = self.groups();
        let mut entry = vec![0; self.sc.der.len()];
        for (_, _, members) in &groups {
            for (i, &k) in members.iter().enumerate() {
                entry[k] = i + 1;
            }
        }
        let emt = self.sc.emt.is_some();
        for (k, &entry) in entry.iter().enumerate() {
            let g = self.group_of(k);
            let spec = &self.sc.der[k];
            let slot = &slots[k];
            let model = der_model(spec, slot.rating_mva);
            let mut start = self.tdes(g);
            if let Some(rx) = self.rot_rx(g)? {
                start.insert(der::ROT_RX.into(), real(rx));
            }
            let forming = slot.forming;
            let mode = if forming {
                der_model::Mode::GridForming
            } else {
                der_model::Mode::GridFollowing
            };
            start.insert(der::MODE.into(), Value::Integer(mode.code().into()));
            start.insert(der::S_RATED.into(), real(slot.rating_mva));
            if emt {
                // The controller measures its operating point; it prepares its first output for
                // the system's step.
                start.insert("t_s".into(), real(self.sc.experiment.step));
            } else {
                // The slot's impedance and power-flow point, so that E∠θ starts behind the
                // grid's own impedance.
                let (p, q, v, v_angle) = slot
                    .point
                    .ok_or("a phasor DER needs its slot's power-flow point")?;
                for (n, x) in [
                    (der::R_F, slot.r),
                    (der::P, p),
                    (der::Q, q),
                    (der::V, v),
                    (der::V_ANGLE, v_angle),
                ] {
                    start.insert(n.into(), real(x));
                }
                // A grid-following slot may leave its impedance out (the unit injects current).
                if let Some(x) = slot.x {
                    start.insert(der::X_F.into(), real(x));
                }
            }
            start.extend(spec.start.clone());
            let name = spec.name.clone();
            let md = self.build(self.der_fmu(), &name, model, &start, Vec::new())?;
            let role = role_of(&md, &name)?;
            ders.push(DerUnit {
                unit: Unit { name, md, start },
                slot: k + 1,
                entry,
                operator: groups[g].1.clone(),
                forming,
                emt,
                role,
                closes: Vec::new(),
            });
        }
        // A complement unit closes the low-pass units of its DVPP (with a complement per form,
        // a hybrid DVPP: those of its own form): their time constants, and which of its
        // operator's low-pass gains it reads.
        for (name, _, members) in &groups {
            self.close_complements(&mut ders, slots, name.as_deref(), members)?;
        }
        Ok(ders)
    }

    /// The complement units among `members` (DVPP `name`) closing that DVPP's low-pass units.
    fn close_complements(
        &mut self,
        ders: &mut [DerUnit],
        slots: &[Slot],
        name: Option<&str>,
        members: &[usize],
    ) -> Result<(), String> {
        let lpf: Vec<(bool, f64, i64)> = members
            .iter()
            .map(|&k| &ders[k])
            .filter(|d| d.role == Role::LowPass)
            .map(|d| {
                let tau = start_of(&d.unit.md, der::ADPF_P_TAU).unwrap_or(0.0);
                let order = start_of(&d.unit.md, der::ADPF_P_ORDER).unwrap_or(1.0);
                (d.forming, tau, order as i64)
            })
            .collect();
        let per_form = members
            .iter()
            .filter(|&&k| ders[k].role == Role::Complement)
            .count()
            > 1;
        for &k in members {
            let d = &mut ders[k];
            if d.role != Role::Complement {
                continue;
            }
            let closed: Vec<(usize, f64, i64)> = lpf
                .iter()
                .enumerate()
                .filter(|(_, u)| !per_form || u.0 == d.forming)
                .map(|(j, &(_, tau, order))| (j + 1, tau, order))
                .collect();
            if closed.len() > der_model::MAX_LPF {
                return Err(self.here(format!(
                    "DER '{}' (the complement of DVPP {}) would close {} low-pass units; a complement closes at most {} (a fleet's units are best given static ADPFs, which need no complement)",
                    d.unit.name,
                    name.unwrap_or("of the scenario"),
                    closed.len(),
                    der_model::MAX_LPF
                )));
            }
            d.closes = closed.iter().map(|c| c.0).collect();
            let mut extra = Table::new();
            extra.insert(
                der::ADPF_P_N_LPF.into(),
                Value::Integer(closed.len() as i64),
            );
            for (j, &(_, tau, order)) in closed.iter().enumerate() {
                extra.insert(der::adpf_p_lpf_tau(j + 1), real(tau));
                extra.insert(der::adpf_p_lpf_order(j + 1), Value::Integer(order));
            }
            // The scenario's own values win.
            for (key, v) in extra {
                d.unit.start.entry(key).or_insert(v);
            }
            let model = der_model(&self.sc.der[k], slots[k].rating_mva);
            d.unit.md = self.build(
                self.der_fmu(),
                &d.unit.name,
                model,
                &d.unit.start,
                Vec::new(),
            )?;
        }
        Ok(())
    }

    /// The operator of DVPP `g`: one entry per DER of it (role, form, rating), the power-flow
    /// point as start values.
    pub(super) fn operator(
        &mut self,
        grid: &GridUnit,
        ders: &[DerUnit],
        g: usize,
    ) -> Result<Unit, String> {
        let (name, component, members) = self.groups().swap_remove(g);
        let mut entries = Vec::new();
        let mut start = self.tdes(g);
        for d in members.iter().map(|&k| &ders[k]) {
            let md = &d.unit.md;
            let mut e = Table::new();
            e.insert("name".into(), Value::String(d.unit.name.clone()));
            e.insert("role".into(), toml_of(d.role)?);
            let form = if d.forming {
                Form::GridForming
            } else {
                Form::GridFollowing
            };
            e.insert("form".into(), toml_of(form)?);
            let s_rated =
                start_of(md, der::S_RATED).ok_or(format!("DER '{}': no S_rated", d.unit.name))?;
            e.insert("s_rated".into(), real(s_rated));
            entries.push(Value::Table(e));
            let (k, slot) = (d.entry, d.slot);
            let avail = start_of(md, der::P_AVAIL0).unwrap_or(0.0);
            start.insert(op::der_p_avail(k), real(avail));
            start.insert(op::der_p(k), real(grid.pf.der[slot - 1].p));
            start.insert(op::der_p_set(k), real(grid.pf.der[slot - 1].p));
            start.insert(op::der_q(k), real(grid.pf.der[slot - 1].q));
        }
        let pcc = match &name {
            None => &grid.pf.pcc,
            Some(n) => grid
                .case
                .dvpp_pccs
                .iter()
                .position(|p| &p.name == n)
                .and_then(|i| grid.pf.dvpp_pcc.get(i))
                .ok_or(format!("the grid case has no [[dvpp_pcc]] '{n}'"))?,
        };
        for (n, x) in [
            (op::PCC_P, pcc.p),
            (op::PCC_Q, pcc.q),
            (op::PCC_F, pcc.f),
            (op::PCC_V, pcc.v),
        ] {
            start.insert(n.into(), real(x));
        }
        // A DVPP area with points of coupling: ref.df is matched at them, on the POC powers
        // rotated by the scenario's R/X.
        let pocs = grid.case.pocs.len();
        let rot_rx = self.rot_rx(g)?.unwrap_or(0.0);
        if pocs > 0 {
            for (k, o) in grid.pf.poc.iter().enumerate() {
                for (n, x) in [
                    (op::poc_p(k + 1), o.p),
                    (op::poc_q(k + 1), o.q),
                    (op::poc_f(k + 1), o.f),
                    (op::poc_v(k + 1), o.v),
                ] {
                    start.insert(n, real(x));
                }
            }
            start.insert(op::ROT_RX.into(), real(rot_rx));
            start.insert(op::AREA_P_LOAD.into(), real(grid.pf.area_p_load));
            start.insert(op::AREA_Q_LOAD.into(), real(grid.pf.area_q_load));
        }
        start.extend(
            self.sc
                .operator
                .as_ref()
                .map_or(Table::new(), |o| o.start.clone()),
        );
        let mut model = Table::new();
        model.insert("ders".into(), Value::Array(entries));
        if pocs > 0 {
            model.insert("pocs".into(), Value::Integer(pocs as i64));
            model.insert("rot_rx".into(), real(rot_rx));
        }
        let md = self.build(
            &dvpp_catalog::OPERATOR,
            &component,
            model,
            &start,
            Vec::new(),
        )?;
        Ok(Unit {
            name: component,
            md,
            start,
        })
    }
}

/// The grid's R/X start values (`mv.rx`, `mv.line[k].rx` > 0) applied to `case`, so that the
/// power flow the other units start from is the one the grid FMU solves at initialization.
fn apply_rx_starts(case: &mut grid_model::Case, start: &Table) -> Result<(), String> {
    let value = |key: &str| -> Result<Option<f64>, String> {
        match start.get(key) {
            None => Ok(None),
            Some(Value::Float(x)) => Ok(Some(*x)),
            Some(Value::Integer(x)) => Ok(Some(*x as f64)),
            Some(v) => Err(format!("[grid.start] '{key}' = {v}: expected a number")),
        }
    };
    let lines = case.mv_line_indices();
    if let Some(rx) = value(grid::MV_RX)? {
        case.mv
            .as_mut()
            .ok_or(format!(
                "[grid.start] '{}': the case has no [mv]",
                grid::MV_RX
            ))?
            .rx = rx;
    }
    for (k, &i) in lines.iter().enumerate() {
        if let Some(rx) = value(&grid::mv_line_rx(k + 1))? {
            case.lines[i].rx = (rx > 0.0).then_some(rx);
        }
    }
    Ok(())
}

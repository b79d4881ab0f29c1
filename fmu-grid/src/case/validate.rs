//! Validation of a case, element by element: each element type checks itself against what it
//! refers to in the case ([`Context`]); [`Case::validate`] runs them in turn.

use super::{
    check_range, impedance_ok, nonneg, pos, BranchData, Bus, BusKind, Case, CaseError, DerKind,
    DerSlot, DvppPcc, Event, Line, Load, MvLines, Pcc, Poc, Shunt, Transformer, RX_MAX,
};
use std::cell::OnceCell;
use std::collections::{BTreeSet, VecDeque};

/// What an element's validation sees of the case: the case, its bus ids and (once the
/// branches are known to be valid) its branches.
pub(crate) struct Context<'a> {
    case: &'a Case,
    ids: BTreeSet<u32>,
    branches: OnceCell<Vec<BranchData>>,
}

impl Context<'_> {
    /// `element` refers to a defined bus.
    fn bus_ok(&self, element: String, bus: u32) -> Result<(), CaseError> {
        if self.ids.contains(&bus) {
            Ok(())
        } else {
            Err(CaseError::UnknownBus { element, bus })
        }
    }

    /// The case's branches (call only once the lines and transformers are valid).
    fn branches(&self) -> &[BranchData] {
        self.branches.get_or_init(|| self.case.branches())
    }

    /// `k` is a DER slot (1-based).
    fn slot_ok(&self, element: &str, k: usize) -> Result<(), CaseError> {
        if k == 0 || k > self.case.ders.len() {
            return Err(CaseError::UnknownReference {
                element: element.into(),
                name: format!("slot {k}"),
            });
        }
        Ok(())
    }

    /// A branch joins two known, different buses through a positive impedance.
    fn branch(&self, el: &str, from: u32, to: u32, r: f64, x: f64) -> Result<(), CaseError> {
        self.bus_ok(el.to_owned(), from)?;
        self.bus_ok(el.to_owned(), to)?;
        if from == to {
            return Err(CaseError::Inconsistent(format!(
                "{el} connects a bus to itself"
            )));
        }
        if !impedance_ok(r, x) {
            return Err(CaseError::NonPositiveImpedance {
                element: el.to_owned(),
                r,
                x,
            });
        }
        Ok(())
    }

    /// The branch named `name` touches bus `bus` (id); `unknown` and `apart` make the errors.
    fn branch_touches(
        &self,
        name: &str,
        bus: u32,
        unknown: impl FnOnce() -> CaseError,
        apart: impl FnOnce() -> CaseError,
    ) -> Result<(), CaseError> {
        let at = self.case.bus_index()[&bus];
        match self.branches().iter().find(|b| b.name == name) {
            None => Err(unknown()),
            Some(b) if b.from != at && b.to != at => Err(apart()),
            _ => Ok(()),
        }
    }
}

impl Bus {
    fn validate(&self) -> Result<(), CaseError> {
        let el = format!("bus {}", self.id);
        let v = self.v_set;
        check_range(&el, "v_set", v, v > 0.5 && v < 1.5, "0.5 < v_set < 1.5")
    }

    /// A PV or slack bus needs a source to hold its voltage.
    fn validate_source(&self, cx: &Context) -> Result<(), CaseError> {
        if self.kind != BusKind::Pq {
            let has_src = cx.case.machines.iter().any(|m| m.bus == self.id)
                || cx.case.ders.iter().any(|d| d.bus == self.id);
            if !has_src {
                return Err(CaseError::Inconsistent(format!(
                    "bus {} is {:?} but has no machine or DER slot",
                    self.id, self.kind
                )));
            }
        }
        Ok(())
    }
}

impl Line {
    fn validate(&self, i: usize, cx: &Context) -> Result<(), CaseError> {
        let el = format!("line {} ({}-{})", i + 1, self.from, self.to);
        cx.branch(&el, self.from, self.to, self.r, self.x)?;
        nonneg(&el, "b", self.b)?;
        if let Some(rx) = self.rx {
            check_range(&el, "rx", rx, (0.0..=RX_MAX).contains(&rx), "0 <= rx <= 20")?;
        }
        Ok(())
    }
}

impl Transformer {
    fn validate(&self, i: usize, cx: &Context) -> Result<(), CaseError> {
        let el = format!("transformer {} ({}-{})", i + 1, self.from, self.to);
        cx.branch(&el, self.from, self.to, self.r, self.x)?;
        if let Some(tap) = self.tap {
            check_range(&el, "tap", tap, tap > 0.5 && tap < 1.5, "0.5 < tap < 1.5")?;
        }
        Ok(())
    }
}

impl Shunt {
    fn validate(&self, i: usize, cx: &Context) -> Result<(), CaseError> {
        cx.bus_ok(format!("shunt {}", i + 1), self.bus)
    }
}

impl Load {
    fn validate(&self, i: usize, cx: &Context) -> Result<(), CaseError> {
        let el = format!("load {} (bus {})", i + 1, self.bus);
        cx.bus_ok(el.clone(), self.bus)?;
        check_range(&el, "p_mw", self.p_mw, true, "finite")?;
        check_range(&el, "q_mvar", self.q_mvar, true, "finite")
    }
}

impl DerSlot {
    fn validate(&self, k: usize, cx: &Context) -> Result<(), CaseError> {
        let d = self;
        let el = format!("der slot {} (bus {})", k + 1, d.bus);
        cx.bus_ok(el.clone(), d.bus)?;
        pos(&el, "rating_mva", d.rating_mva)?;
        // a grid-following slot's impedance is informational and may be zero or left out
        let x = match (d.kind, d.x) {
            (DerKind::GridForming, None) => {
                return Err(CaseError::Inconsistent(format!(
                    "{el}: a grid_forming slot needs `x` (the reactance behind its source)"
                )))
            }
            (_, x) => x,
        };
        let z_ok = match x {
            Some(x) => {
                impedance_ok(d.r, x) || (d.kind == DerKind::GridFollowing && d.r == 0.0 && x == 0.0)
            }
            None => true, // grid-following without impedance data
        };
        let x = x.unwrap_or(0.0);
        if !z_ok {
            return Err(CaseError::NonPositiveImpedance {
                element: el,
                r: d.r,
                x,
            });
        }
        let limit = 1.5 * d.rating_mva;
        check_range(
            &el,
            "p_mw",
            d.p_mw,
            d.p_mw.abs() <= limit,
            "|p| <= 1.5 rating",
        )?;
        check_range(
            &el,
            "q_mvar",
            d.q_mvar,
            d.q_mvar.abs() <= limit,
            "|q| <= 1.5 rating",
        )
    }
}

impl Pcc {
    fn validate(&self, cx: &Context) -> Result<(), CaseError> {
        cx.bus_ok("pcc".into(), self.bus)?;
        pos("pcc", "f_filter_t", self.f_filter_t)?;
        for &k in &self.slots {
            cx.slot_ok("pcc", k)?;
        }
        for pb in &self.branches {
            cx.bus_ok("pcc branch".into(), pb.at_bus)?;
            cx.branch_touches(
                &pb.branch,
                pb.at_bus,
                || CaseError::UnknownReference {
                    element: "pcc".into(),
                    name: pb.branch.clone(),
                },
                || {
                    CaseError::Inconsistent(format!(
                        "pcc branch {} does not touch bus {}",
                        pb.branch, pb.at_bus
                    ))
                },
            )?;
        }
        Ok(())
    }
}

impl DvppPcc {
    fn validate(&self, k: usize, cx: &Context) -> Result<(), CaseError> {
        let p = self;
        let el = format!("dvpp_pcc {} '{}'", k + 1, p.name);
        let plain = !p.name.is_empty()
            && p.name
                .chars()
                .all(|c| c.is_ascii_alphanumeric() || c == '_');
        if !plain || cx.case.dvpp_pccs[..k].iter().any(|q| q.name == p.name) {
            return Err(CaseError::Inconsistent(format!(
                "{el}: names are unique and made of letters, digits and _"
            )));
        }
        cx.bus_ok(el.clone(), p.bus)?;
        pos(&el, "f_filter_t", p.f_filter_t)?;
        if p.slots.is_empty() {
            return Err(CaseError::Inconsistent(format!("{el} lists no slot")));
        }
        for &k in &p.slots {
            cx.slot_ok(&el, k)?;
        }
        Ok(())
    }
}

impl Poc {
    fn validate(&self, k: usize, cx: &Context) -> Result<(), CaseError> {
        let el = format!("poc {}", k + 1);
        cx.bus_ok(el.clone(), self.bus)?;
        pos(&el, "f_filter_t", self.f_filter_t)?;
        if self.branches.is_empty() {
            return Err(CaseError::Inconsistent(format!("{el} lists no branch")));
        }
        for name in &self.branches {
            cx.branch_touches(
                name,
                self.bus,
                || CaseError::UnknownReference {
                    element: el.clone(),
                    name: name.clone(),
                },
                || {
                    CaseError::Inconsistent(format!(
                        "{el}: branch {name} does not touch bus {}",
                        self.bus
                    ))
                },
            )?;
        }
        Ok(())
    }
}

impl MvLines {
    fn validate(&self, cx: &Context) -> Result<(), CaseError> {
        let rx = self.rx;
        check_range(
            "mv",
            "rx",
            rx,
            (0.0..=RX_MAX).contains(&rx),
            "0 <= rx <= 20",
        )?;
        let mut seen = BTreeSet::new();
        for name in &self.lines {
            if !cx.case.lines.iter().any(|l| &cx.case.line_name(l) == name) {
                return Err(CaseError::UnknownReference {
                    element: "mv".into(),
                    name: name.clone(),
                });
            }
            if !seen.insert(name) {
                return Err(CaseError::DuplicateName(format!("mv line {name}")));
            }
        }
        Ok(())
    }
}

impl Event {
    fn validate(&self, i: usize, cx: &Context) -> Result<(), CaseError> {
        let el = format!("event {}", i + 1);
        nonneg(&el, "time", self.time())?;
        match self {
            Event::LoadStep {
                bus,
                dp_mw,
                dq_mvar,
                ..
            } => {
                cx.bus_ok(el.clone(), *bus)?;
                check_range(&el, "dp_mw", *dp_mw, true, "finite")?;
                check_range(&el, "dq_mvar", *dq_mvar, true, "finite")?;
            }
            Event::GeneratorTrip { machine, .. } => {
                if *machine == 0 || *machine > cx.case.machines.len() {
                    return Err(CaseError::UnknownReference {
                        element: el,
                        name: format!("machine {machine}"),
                    });
                }
            }
            Event::LineTrip { branch, .. } => {
                if !cx.branches().iter().any(|b| &b.name == branch) {
                    return Err(CaseError::UnknownReference {
                        element: el,
                        name: branch.clone(),
                    });
                }
            }
        }
        Ok(())
    }
}

impl Case {
    /// Check the case (the first problem found is returned): its base values, then each element in turn (buses, the single slack,
    /// branches and their unique names, shunts, loads, machines, DER slots, the sources of PV
    /// and slack buses, PCC, DVPP PCCs, POCs, MV lines, events), then that every bus is
    /// connected to the slack bus through in-service branches.
    pub fn validate(&self) -> Result<(), CaseError> {
        pos("case", "base_mva", self.base_mva)?;
        pos("case", "f_nom", self.f_nom)?;
        let mut total = 0.0;
        for (k, st) in self.ufls.iter().enumerate() {
            let el = format!("ufls stage {}", k + 1);
            let f = st.f_hz;
            check_range(
                &el,
                "f_hz",
                f,
                f > 0.5 * self.f_nom && f < self.f_nom,
                "0.5 f_nom < f_hz < f_nom",
            )?;
            check_range(
                &el,
                "shed",
                st.shed,
                st.shed > 0.0 && st.shed <= 1.0,
                "0 < shed <= 1",
            )?;
            check_range(
                &el,
                "delay",
                st.delay,
                (0.0..=60.0).contains(&st.delay),
                "0 <= delay <= 60 s",
            )?;
            total += st.shed;
        }
        check_range("ufls", "sum of shed", total, total <= 1.0, "<= 1")?;
        if self.buses.is_empty() {
            return Err(CaseError::NoBus);
        }
        let mut ids = BTreeSet::new();
        for b in &self.buses {
            if !ids.insert(b.id) {
                return Err(CaseError::DuplicateBus(b.id));
            }
            b.validate()?;
        }
        let cx = Context {
            case: self,
            ids,
            branches: OnceCell::new(),
        };
        let slack = self.slack()?;
        for (i, l) in self.lines.iter().enumerate() {
            l.validate(i, &cx)?;
        }
        for (i, t) in self.transformers.iter().enumerate() {
            t.validate(i, &cx)?;
        }
        let mut names = BTreeSet::new();
        for br in cx.branches() {
            if !names.insert(br.name.clone()) {
                return Err(CaseError::DuplicateName(br.name.clone()));
            }
        }
        for (i, s) in self.shunts.iter().enumerate() {
            s.validate(i, &cx)?;
        }
        for (i, l) in self.loads.iter().enumerate() {
            l.validate(i, &cx)?;
        }
        for (j, m) in self.machines.iter().enumerate() {
            let el = format!("machine {} (bus {})", j + 1, m.bus);
            cx.bus_ok(el.clone(), m.bus)?;
            m.validate(&el)?;
        }
        for (k, d) in self.ders.iter().enumerate() {
            d.validate(k, &cx)?;
        }
        for b in &self.buses {
            b.validate_source(&cx)?;
        }
        if let Some(p) = &self.pcc {
            p.validate(&cx)?;
        }
        for (k, p) in self.dvpp_pccs.iter().enumerate() {
            p.validate(k, &cx)?;
        }
        for (k, p) in self.pocs.iter().enumerate() {
            p.validate(k, &cx)?;
        }
        if let Some(mv) = &self.mv {
            mv.validate(&cx)?;
        }
        for (i, e) in self.events.iter().enumerate() {
            e.validate(i, &cx)?;
        }
        self.connected(slack, cx.branches())
    }

    /// The id of the single slack bus.
    fn slack(&self) -> Result<u32, CaseError> {
        let slacks: Vec<u32> = self
            .buses
            .iter()
            .filter(|b| b.kind == BusKind::Slack)
            .map(|b| b.id)
            .collect();
        match slacks[..] {
            [] => Err(CaseError::Slack("no slack bus defined".into())),
            [s] => Ok(s),
            _ => Err(CaseError::Slack(format!(
                "more than one slack bus: {slacks:?}"
            ))),
        }
    }

    /// Every bus is reached from the slack bus through in-service branches.
    fn connected(&self, slack: u32, branches: &[BranchData]) -> Result<(), CaseError> {
        let n = self.buses.len();
        let mut adj = vec![Vec::new(); n];
        for br in branches.iter().filter(|b| b.in_service) {
            adj[br.from].push(br.to);
            adj[br.to].push(br.from);
        }
        let mut seen = vec![false; n];
        let s = self.bus_index()[&slack];
        seen[s] = true;
        let mut q = VecDeque::from([s]);
        while let Some(u) = q.pop_front() {
            for &v in &adj[u] {
                if !seen[v] {
                    seen[v] = true;
                    q.push_back(v);
                }
            }
        }
        if let Some(i) = seen.iter().position(|&x| !x) {
            return Err(CaseError::IslandedBus(self.buses[i].id));
        }
        Ok(())
    }
}

//! The dependency graph of a system's connections: the order of each exchange (a connection
//! leaving a unit with direct feedthrough after the connections into it), algebraic loops
//! found and broken, and the units' order for Gauss-Seidel.

use super::unit::{Phase, Unit};
use std::collections::BTreeSet;

/// One connection, resolved: the output slot of its source unit, the input of its
/// destination, the SSP `LinearTransformation` and the value it carried last.
pub(crate) struct Link {
    src: usize,
    slot: usize,
    dst: usize,
    dst_index: u32,
    dst_vr: u32,
    ty: model_description::BaseType,
    factor: f64,
    offset: f64,
    last: Option<f64>,
    label: String,
    /// Whether the destination input feeds through to an output of its unit, per phase
    /// (initialization, step): setting it makes the unit's outputs stale.
    feeds: [bool; 2],
}

/// The ends of a [`Link`]: source unit and output slot, destination unit and input variable.
pub(crate) struct Ends {
    pub(crate) src: usize,
    pub(crate) slot: usize,
    pub(crate) dst: usize,
    pub(crate) dst_var: super::unit::Var,
}

impl Link {
    /// The connection `label` between `ends`, with the transformation `(factor, offset)`; the
    /// destination unit `to` says whether its input feeds through.
    pub(crate) fn new(ends: Ends, (factor, offset): (f64, f64), label: String, to: &Unit) -> Link {
        let Ends {
            src,
            slot,
            dst,
            dst_var,
        } = ends;
        let dst_index = dst_var.index();
        let feeds = [Phase::Init, Phase::Step].map(|p| to.feeds_through(p, dst_index));
        Link {
            src,
            slot,
            dst,
            dst_index,
            dst_vr: dst_var.vr(),
            ty: dst_var.ty(),
            factor,
            offset,
            last: None,
            label,
            feeds,
        }
    }

    /// The source unit.
    pub(crate) fn src(&self) -> usize {
        self.src
    }

    /// The source's output slot (see [`Unit::values`]).
    pub(crate) fn slot(&self) -> usize {
        self.slot
    }

    /// The destination unit.
    pub(crate) fn dst(&self) -> usize {
        self.dst
    }

    /// `a.x -> b.y`.
    pub(crate) fn label(&self) -> &str {
        &self.label
    }

    /// Whether setting the destination input makes its unit's outputs stale in `phase`.
    pub(crate) fn feeds(&self, phase: Phase) -> bool {
        self.feeds[phase as usize]
    }

    /// The value at the destination of `raw` at the source.
    pub(crate) fn transform(&self, raw: f64) -> f64 {
        self.factor * raw + self.offset
    }

    /// The value carried at the last exchange (`None`: none since the start or a restore).
    pub(crate) fn last(&self) -> Option<f64> {
        self.last
    }

    /// Forget the last value: the next exchange sets the input again.
    pub(crate) fn forget(&mut self) {
        self.last = None;
    }

    /// Carry `v` (bit for bit unchanged: `false`, nothing to set) and queue it at the
    /// destination `unit`.
    pub(crate) fn carry(&mut self, v: f64, unit: &mut Unit, phase: Phase) -> bool {
        if self.last.map(f64::to_bits) == Some(v.to_bits()) {
            return false;
        }
        self.set(v, unit, phase);
        true
    }

    /// Queue `v` at the destination `unit` whether or not it changed.
    pub(crate) fn set(&mut self, v: f64, unit: &mut Unit, phase: Phase) {
        self.last = Some(v);
        unit.push(self.dst_vr, self.ty, v, self.feeds(phase));
    }

    fn dst_index(&self) -> u32 {
        self.dst_index
    }
}

/// Order links so that a link leaving unit U after a dependency on one of U's inputs comes
/// after the link into that input; cycles are broken at their first link in SSD order.
pub(crate) fn order_links(
    units: &[Unit],
    links: &[Link],
    phase: Phase,
    warnings: &mut Vec<String>,
) -> Vec<usize> {
    let n = links.len();
    // preds[b] = links a whose end input feeds (through unit b.src) the start of b.
    let preds: Vec<Vec<usize>> = (0..n)
        .map(|b| {
            let lb = &links[b];
            let out_index = units[lb.src].output_index(lb.slot);
            let deps = units[lb.src].deps(phase).get(&out_index);
            (0..n)
                .filter(|&a| {
                    links[a].dst == lb.src
                        && deps.is_some_and(|d| d.contains(&links[a].dst_index()))
                })
                .collect()
        })
        .collect();
    let mut done = vec![false; n];
    let mut ignored: Vec<BTreeSet<usize>> = vec![BTreeSet::new(); n];
    let mut order = Vec::with_capacity(n);
    while order.len() < n {
        let ready = (0..n)
            .find(|&b| !done[b] && preds[b].iter().all(|&a| done[a] || ignored[b].contains(&a)));
        if let Some(b) = ready {
            done[b] = true;
            order.push(b);
            continue;
        }
        // Every remaining link waits on another: walk back from one until a link repeats.
        let mut path = vec![(0..n).find(|&b| !done[b]).expect("a remaining link")];
        let cycle = loop {
            let b = *path.last().expect("non-empty");
            let a = preds[b]
                .iter()
                .copied()
                .find(|&a| !done[a] && !ignored[b].contains(&a))
                .expect("a waiting link has a pending predecessor");
            if let Some(pos) = path.iter().position(|&x| x == a) {
                break path[pos..].to_vec();
            }
            path.push(a);
        };
        // Break at the cycle's first link in SSD order: it stops waiting on its predecessor.
        let first = *cycle.iter().min().expect("non-empty cycle");
        let pos = cycle.iter().position(|&x| x == first).expect("member");
        let pred = cycle[(pos + 1) % cycle.len()];
        ignored[first].insert(pred);
        let mut names: Vec<&str> = cycle
            .iter()
            .rev()
            .map(|&i| links[i].label.as_str())
            .collect();
        names.dedup();
        let what = match phase {
            Phase::Init => "initialization",
            Phase::Step => "steps",
        };
        let msg = format!(
            "algebraic loop (direct feedthrough cycle) during {what}: {}; broken at {} (it carries the value from before each exchange)",
            names.join(" -> "),
            links[first].label
        );
        eprintln!("cosim: warning: {msg}");
        warnings.push(msg);
    }
    order
}

/// Gauss-Seidel order of the units: a unit after the units feeding it; cycles in SSD order.
pub(crate) fn order_units(n: usize, links: &[Link]) -> Vec<usize> {
    let mut done = vec![false; n];
    let mut order = Vec::with_capacity(n);
    while order.len() < n {
        let ready = (0..n).find(|&u| {
            !done[u]
                && links
                    .iter()
                    .all(|l| l.dst != u || l.src == u || done[l.src])
        });
        // In a cycle the first remaining unit in SSD order goes first.
        let u = ready.unwrap_or_else(|| (0..n).find(|&u| !done[u]).expect("a remaining unit"));
        done[u] = true;
        order.push(u);
    }
    order
}

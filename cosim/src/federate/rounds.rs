//! The rounds of a federation's exchanges: the master's exchange order split so that a value
//! between two components is read at its source in one round and set at its destination in a
//! later one, the rounds each federate must be granted, and the outputs each component
//! publishes.

use crate::master::{Event, Phase, System};
use std::collections::{BTreeMap, BTreeSet};

/// An exchange split into rounds: the events of each round in the master's order, and the
/// connections whose value arrives (is taken from HELICS) at the start of each round.
#[derive(Debug, Default)]
pub(super) struct Schedule {
    rounds: Vec<Vec<Event>>,
    receive: Vec<Vec<usize>>,
    /// The rounds this federate must be granted: those in which it takes a value from or
    /// publishes one to another federate, and the last (so that no publication of the next
    /// exchange overtakes a read of this one). It skips the others: a round costs a message
    /// only from the federates that take part in it.
    granted: Vec<bool>,
}

impl Schedule {
    /// The events of each round.
    pub(super) fn rounds(&self) -> &[Vec<Event>] {
        &self.rounds
    }

    /// The HELICS time grants of an exchange for this federate (at least one: the federates
    /// go in step).
    pub(super) fn grants(&self) -> usize {
        self.granted[1..].iter().filter(|&&g| g).count().max(1)
    }

    /// The rounds, the connections arriving at the start of each round, the rounds granted.
    pub(super) fn into_parts(self) -> (Vec<Vec<Event>>, Vec<Vec<usize>>, Vec<bool>) {
        (self.rounds, self.receive, self.granted)
    }

    /// Mark the rounds a federate of the units `mine` must be granted ([`Schedule::granted`]).
    pub(super) fn grant_for(&mut self, sys: &System, mine: &[bool]) {
        let links = sys.core().links();
        let remote = |i: usize| mine[links[i].src()] != mine[links[i].dst()];
        let last = self.rounds.len() - 1;
        self.granted = (0..self.rounds.len())
            .map(|j| {
                j == last
                    || self.receive[j]
                        .iter()
                        .any(|&i| remote(i) && mine[links[i].dst()])
                    || self.rounds[j].iter().any(|e| match *e {
                        Event::Produce(i) => remote(i) && mine[links[i].src()],
                        Event::Local(_) | Event::Consume(_) => false,
                    })
            })
            .collect();
    }
}

/// The rounds of one exchange walking `order`: a connection between two components is read at
/// its source in the source's current round and set at its destination one round later at the
/// earliest; a source publishes an output once per round (a second read of it after an input
/// that feeds through was set waits for the next round).
pub(super) fn schedule(sys: &System, order: &[usize], phase: Phase) -> Schedule {
    let n = sys.units();
    let mut round = vec![0usize; n];
    let mut published: Vec<Option<usize>> = vec![None; n];
    let mut dirty = vec![false; n];
    let mut s = Schedule::default();
    let put = |s: &mut Schedule, r: usize, e: Event| {
        while s.rounds.len() <= r {
            s.rounds.push(Vec::new());
            s.receive.push(Vec::new());
        }
        s.rounds[r].push(e);
    };
    for &i in order {
        let l = &sys.core().links()[i];
        let (src, dst) = (l.src(), l.dst());
        if src == dst {
            put(&mut s, round[src], Event::Local(i));
        } else {
            if published[src] == Some(round[src]) && dirty[src] {
                round[src] += 1;
            }
            let p = round[src];
            published[src] = Some(p);
            dirty[src] = false;
            put(&mut s, p, Event::Produce(i));
            round[dst] = round[dst].max(p + 1);
            put(&mut s, round[dst], Event::Consume(i));
            s.receive[p + 1].push(i);
        }
        if l.feeds(phase) {
            dirty[dst] = true;
        }
    }
    if s.rounds.is_empty() {
        s.rounds.push(Vec::new());
        s.receive.push(Vec::new());
    }
    s
}

/// The outputs of each component that a component other than itself reads, in slot order:
/// the same for every federate, whatever the grouping.
pub(super) fn packed_slots(sys: &System) -> BTreeMap<usize, BTreeMap<usize, usize>> {
    let mut slots: BTreeMap<usize, BTreeSet<usize>> = BTreeMap::new();
    for l in sys.core().links().iter().filter(|l| l.src() != l.dst()) {
        slots.entry(l.src()).or_default().insert(l.slot());
    }
    slots
        .into_iter()
        .map(|(u, s)| (u, s.into_iter().enumerate().map(|(k, s)| (s, k)).collect()))
        .collect()
}

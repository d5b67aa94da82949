//! Membrane-structure genetic algorithm (MSGA), dissertation sections 2.4.2 and 3.1.1.
//!
//! # Structure (dissertation Fig. 3.3)
//! Five membranes: the skin (0) contains membranes 1, 2 and 3; membrane 3 contains 4. The
//! elementary membranes are 1, 2 and 4, as in the dissertation. Each membrane holds `objects`
//! objects (40; 200 in all) and evolves them with its own rules and its own ChaCha stream
//! (stream `1 + membrane`).
//!
//! # Evolution rules, one step per round
//! 1. *Selection* (eq. 3.4): a mating pool of `objects` parents drawn by roulette wheel
//!    ([`Roulette`], fitness-proportional with linear windowing).
//! 2. *Crossover* (eq. 3.6): consecutive pool pairs, with probability `pc`, become
//!    `a V1 + (1-a) V2` and `(1-a) V1 + a V2`, `a ~ U(0, 1)`.
//! 3. *Mutation* (eq. 3.5): each gene, with probability `pm`, is replaced by a uniform draw
//!    from its interval.
//! 4. *Shift* (eq. 3.7): with probability `ps` an object swaps two of its genes (clipped to
//!    the destination's interval when the bounds differ).
//! 5. The candidates are evaluated, and the dissertation's replacement rule of eq. 3.4 is applied
//!    slot by slot: object `i` is replaced by candidate `i` when the candidate is at least
//!    as good (`f_n <= f_i`), so a membrane never loses its best object.
//!
//! # Communication rule
//! After each evolution step every membrane sends copies of its best `exchange` share
//! (30 %, 12 objects) to each neighbour in the tree (its parent and its children) over a
//! channel, and takes in what its neighbours sent after the same step (`migration_lag =
//! 0`, the dissertation's rule) or after their previous step (`migration_lag = 1`, so that no
//! membrane waits for a neighbour's current step; see below). A receiver takes the incoming
//! objects in a fixed order (parent first, then children by label); each one that is not
//! already present and beats the receiver's current worst object replaces that worst
//! object. The dissertation does not say who receives the best objects; exchanging along the tree
//! edges in both directions lets good objects reach the skin, which the dissertation names as the
//! output, while inner membranes keep evolving their own lines. The harness records the
//! best of every evaluation, so the reported result is the best object found anywhere,
//! which the skin holds one or two rounds later.
//!
//! # Threads and determinism
//! With `threads = true` each membrane runs on its own OS thread: the coordinator grants
//! each membrane its evaluations two rounds ahead, the membrane evolves and evaluates on its
//! thread, reports back, and exchanges migrants with its neighbours directly over channels.
//! No coordinator round is a barrier: a membrane waits only for its neighbours' migrants.
//! With the dissertation's rule that still couples neighbours every step, so membranes drift at
//! most the tree's diameter apart; with `migration_lag = 1` a membrane that finishes a
//! step early starts its next one at once and only waits if a neighbour has not yet
//! finished the step before, which keeps two cores busier. Results stay deterministic
//! either way: each membrane draws only from its own stream, each edge's channel carries
//! exactly one message per step in order (so "the step `t - lag` message" is a fixed
//! message, whenever it arrives), grant quotas depend on counts only, and the coordinator
//! commits the evaluations in round and membrane order; results are bit-identical to the
//! single-thread driver (`threads = false`, same lag) and independent of scheduling
//! (tested with random pauses).
//!
//! Every evaluation computed is counted. A round's membranes evaluate at once, so when a
//! stop value is reached inside a round the rest of that round has been computed too: both
//! drivers count the whole round (`evaluations` is what was spent; the trace's hit stays at
//! the evaluation that reached the value). With a stop value the coordinator grants one
//! round at a time, so no round after it is ever computed.

use super::operators::{Mutation, Roulette, arithmetic_crossover, ranking};
use crate::base::TrialSeed;
use crate::harness::{Evaluated, Evaluator, Grant, Optimizer, OptimizerConfig};
use crate::objective::Bounds;
use crossbeam_channel::{Receiver, Sender, unbounded};
use rand::RngExt;
use rand_chacha::ChaCha8Rng;
use std::thread::JoinHandle;

/// Parent of each membrane in the dissertation's structure (Fig. 3.3); `None` is the skin.
pub const SEED_STRUCTURE: [Option<usize>; 5] = [None, Some(0), Some(0), Some(0), Some(3)];

/// MSGA settings; defaults are the dissertation's Table 3.1.
#[derive(Debug, Clone)]
pub struct MsgaConfig {
    /// Parent of each membrane (`None` for the skin).
    pub structure: Vec<Option<usize>>,
    /// Objects per membrane.
    pub objects: usize,
    pub pm: f64,
    pub pc: f64,
    pub ps: f64,
    /// Share of a membrane's objects sent to each neighbour after every evolution step.
    pub exchange: f64,
    /// One OS thread per membrane (true) or all membranes in the calling thread (false).
    pub threads: bool,
    /// Evolution steps late that migrants are taken in (0: the dissertation's rule; 1: the
    /// previous step's, so membranes need not wait for each other).
    pub migration_lag: usize,
}

impl Default for MsgaConfig {
    fn default() -> Self {
        MsgaConfig {
            structure: SEED_STRUCTURE.to_vec(),
            objects: 40,
            pm: 0.1,
            pc: 0.9,
            ps: 0.05,
            exchange: 0.3,
            threads: true,
            migration_lag: 0,
        }
    }
}

impl MsgaConfig {
    /// Neighbours of each membrane: parent first, then children in label order.
    fn neighbours(&self) -> Vec<Vec<usize>> {
        let m = self.structure.len();
        (0..m)
            .map(|i| {
                let mut v: Vec<usize> = self.structure[i].into_iter().collect();
                v.extend((0..m).filter(|&j| self.structure[j] == Some(i)));
                v
            })
            .collect()
    }

    /// Number of migrants a membrane sends to each neighbour.
    fn migrant_count(&self) -> usize {
        ((self.exchange * self.objects as f64).ceil() as usize).min(self.objects)
    }
}

impl OptimizerConfig for MsgaConfig {
    fn batch_size(&self) -> usize {
        self.objects * self.structure.len()
    }

    fn start(&self, bounds: &Bounds, budget: u64, seed: &TrialSeed) -> Box<dyn Optimizer> {
        let membranes: Vec<Membrane> = (0..self.structure.len())
            .map(|id| Membrane::new(self, bounds, seed.rng(1 + id as u64)))
            .collect();
        if self.threads {
            Box::new(Threaded::spawn(
                membranes,
                self.neighbours(),
                self.objects,
                budget,
                self.migration_lag,
            ))
        } else {
            Box::new(Sequential {
                membranes,
                neighbours: self.neighbours(),
                objects: self.objects,
                lag: self.migration_lag,
                sent: std::collections::VecDeque::new(),
            })
        }
    }
}

/// Objects sent from one membrane to a neighbour, with their values.
#[derive(Debug, Clone)]
struct Migrants {
    points: Vec<f64>,
    values: Vec<f64>,
}

/// One membrane: a region with its objects, its rules and its random stream.
struct Membrane {
    bounds: Bounds,
    objects: usize,
    pm: f64,
    pc: f64,
    ps: f64,
    migrants: usize,
    rng: ChaCha8Rng,
    pop: Vec<f64>,
    fit: Vec<f64>,
    cand: Vec<f64>,
    wheel: Roulette,
    initialized: bool,
    /// Crossover children, reused across rounds.
    c1: Vec<f64>,
    c2: Vec<f64>,
}

impl Membrane {
    fn new(cfg: &MsgaConfig, bounds: &Bounds, rng: ChaCha8Rng) -> Self {
        let d = bounds.dim();
        Membrane {
            bounds: bounds.clone(),
            objects: cfg.objects,
            pm: cfg.pm,
            pc: cfg.pc,
            ps: cfg.ps,
            migrants: cfg.migrant_count(),
            rng,
            pop: vec![0.0; cfg.objects * d],
            fit: vec![f64::INFINITY; cfg.objects],
            cand: vec![0.0; cfg.objects * d],
            wheel: Roulette::default(),
            initialized: false,
            c1: vec![0.0; d],
            c2: vec![0.0; d],
        }
    }

    /// The candidates of this round: the initial objects, then offspring of the rules.
    fn propose(&mut self) -> &[f64] {
        let d = self.bounds.dim();
        if !self.initialized {
            for x in self.cand.chunks_exact_mut(d) {
                self.bounds.sample(&mut self.rng, x);
            }
            return &self.cand;
        }
        // Selection: roulette mating pool.
        self.wheel.rebuild(&self.fit);
        for i in 0..self.objects {
            let p = self.wheel.pick(&mut self.rng);
            self.cand[i * d..(i + 1) * d].copy_from_slice(&self.pop[p * d..(p + 1) * d]);
        }
        // Crossover of consecutive pairs.
        let (c1, c2) = (&mut self.c1, &mut self.c2);
        for pair in self.cand.chunks_exact_mut(2 * d) {
            if self.rng.random::<f64>() < self.pc {
                let a: f64 = self.rng.random();
                let (p1, p2) = pair.split_at(d);
                arithmetic_crossover(a, p1, p2, c1, c2);
                pair[..d].copy_from_slice(c1);
                pair[d..].copy_from_slice(c2);
            }
        }
        for x in self.cand.chunks_exact_mut(d) {
            // Mutation.
            Mutation::Uniform.apply(x, &self.bounds, self.pm, &mut self.rng);
            // Shift: swap two genes.
            if d >= 2 && self.rng.random::<f64>() < self.ps {
                let a = self.rng.random_range(0..d);
                let b = (a + 1 + self.rng.random_range(0..d - 1)) % d;
                x.swap(a, b);
                self.bounds.clamp(x);
            }
        }
        &self.cand
    }

    /// Applies the replacement rule with the candidates' values.
    fn accept(&mut self, values: &[f64]) {
        let d = self.bounds.dim();
        if !self.initialized {
            self.pop.copy_from_slice(&self.cand);
            self.fit.copy_from_slice(values);
            self.initialized = true;
            return;
        }
        for (i, &v) in values.iter().enumerate() {
            if v <= self.fit[i] {
                self.fit[i] = v;
                self.pop[i * d..(i + 1) * d].copy_from_slice(&self.cand[i * d..(i + 1) * d]);
            }
        }
    }

    /// Copies of the best objects, to send to a neighbour.
    fn migrants(&self) -> Migrants {
        let d = self.bounds.dim();
        let mut m = Migrants {
            points: Vec::with_capacity(self.migrants * d),
            values: Vec::with_capacity(self.migrants),
        };
        for &i in ranking(&self.fit).iter().take(self.migrants) {
            m.points.extend_from_slice(&self.pop[i * d..(i + 1) * d]);
            m.values.push(self.fit[i]);
        }
        m
    }

    /// Takes in migrants: each new one that beats the current worst object replaces it.
    fn receive(&mut self, incoming: &[Migrants]) {
        let d = self.bounds.dim();
        for batch in incoming {
            for (x, &v) in batch.points.chunks_exact(d).zip(&batch.values) {
                let present = self.pop.chunks_exact(d).any(|p| p == x);
                if present {
                    continue;
                }
                // The worst object: highest value, the last index among equals (as the
                // last entry of `ranking`).
                let worst = (0..self.fit.len())
                    .reduce(|w, i| {
                        if self.fit[i].total_cmp(&self.fit[w]).is_ge() {
                            i
                        } else {
                            w
                        }
                    })
                    .expect("membrane has objects");
                if v < self.fit[worst] {
                    self.fit[worst] = v;
                    self.pop[worst * d..(worst + 1) * d].copy_from_slice(x);
                }
            }
        }
    }
}

/// All membranes in the calling thread, in label order.
struct Sequential {
    membranes: Vec<Membrane>,
    neighbours: Vec<Vec<usize>>,
    objects: usize,
    lag: usize,
    /// Every membrane's migrants of the last `lag + 1` evolution steps, oldest first.
    sent: std::collections::VecDeque<Vec<Migrants>>,
}

impl Optimizer for Sequential {
    fn step(&mut self, ev: &mut Evaluator) {
        let evolution = self.membranes[0].initialized;
        // Grants, committed after the round as on threads: a round is computed whole and
        // counted whole, so a stop inside it costs what it costs the threaded driver.
        let mut round = Vec::with_capacity(self.membranes.len());
        for m in &mut self.membranes {
            let evaluated = ev.grant(self.objects).evaluate(m.propose());
            m.accept(evaluated.values());
            round.push(evaluated);
        }
        for evaluated in round {
            ev.commit(evaluated);
        }
        if evolution {
            self.sent
                .push_back(self.membranes.iter().map(Membrane::migrants).collect());
            if self.sent.len() > self.lag {
                let due = self.sent.pop_front().expect("sent is not empty");
                for (m, nb) in self.membranes.iter_mut().zip(&self.neighbours) {
                    let incoming: Vec<Migrants> = nb.iter().map(|&j| due[j].clone()).collect();
                    m.receive(&incoming);
                }
            }
        }
    }
}

/// Rounds granted beyond the one being collected: membranes may drift this far apart
/// (a membrane also stays within `migration_lag + 1` steps of each neighbour, whose
/// migrants it waits for).
const AHEAD: usize = 2;

/// One OS thread per membrane; the coordinator only grants and commits evaluations.
struct Threaded {
    commands: Vec<Sender<Grant>>,
    reports: Vec<Receiver<Evaluated>>,
    handles: Vec<JoinHandle<()>>,
    objects: usize,
    /// Rounds granted and not yet collected.
    open: usize,
    /// This optimizer's own budget: less than the evaluator's when a polish follows.
    budget: u64,
    /// Evaluations granted so far (committed or open).
    granted: u64,
}

impl Threaded {
    fn spawn(
        membranes: Vec<Membrane>,
        neighbours: Vec<Vec<usize>>,
        objects: usize,
        budget: u64,
        lag: usize,
    ) -> Self {
        let m = membranes.len();
        // One channel per directed edge of the membrane tree.
        let mut inbox: Vec<Vec<Option<Receiver<Migrants>>>> =
            (0..m).map(|_| (0..m).map(|_| None).collect()).collect();
        let mut outbox: Vec<Vec<Sender<Migrants>>> = (0..m).map(|_| Vec::new()).collect();
        for (i, nb) in neighbours.iter().enumerate() {
            for &j in nb {
                let (tx, rx) = unbounded();
                outbox[i].push(tx);
                inbox[j][i] = Some(rx);
            }
        }
        let mut commands = Vec::with_capacity(m);
        let mut reports = Vec::with_capacity(m);
        let mut handles = Vec::with_capacity(m);
        for (id, mut membrane) in membranes.into_iter().enumerate() {
            let (cmd_tx, cmd_rx) = unbounded::<Grant>();
            let (rep_tx, rep_rx) = unbounded::<Evaluated>();
            let to: Vec<Sender<Migrants>> = std::mem::take(&mut outbox[id]);
            let from: Vec<Receiver<Migrants>> = neighbours[id]
                .iter()
                .map(|&j| inbox[id][j].take().expect("edge channel"))
                .collect();
            let handle = std::thread::Builder::new()
                .name(format!("msga-membrane-{id}"))
                .spawn(move || {
                    let mut sent = 0usize;
                    while let Ok(grant) = cmd_rx.recv() {
                        let evolution = membrane.initialized;
                        let evaluated = grant.evaluate(membrane.propose());
                        membrane.accept(evaluated.values());
                        if rep_tx.send(evaluated).is_err() {
                            return;
                        }
                        if evolution {
                            let out = membrane.migrants();
                            for tx in &to {
                                // A neighbour gone means the trial is over.
                                let _ = tx.send(out.clone());
                            }
                            sent += 1;
                            if sent > lag {
                                // Each edge carries one message per step, in order: this
                                // reads the neighbours' step `lag` steps back.
                                let Ok(incoming) = from
                                    .iter()
                                    .map(|rx| rx.recv())
                                    .collect::<Result<Vec<Migrants>, _>>()
                                else {
                                    return;
                                };
                                membrane.receive(&incoming);
                            }
                        }
                    }
                })
                .expect("spawn membrane thread");
            commands.push(cmd_tx);
            reports.push(rep_rx);
            handles.push(handle);
        }
        Threaded {
            commands,
            reports,
            handles,
            objects,
            open: 0,
            budget,
            granted: 0,
        }
    }
}

impl Optimizer for Threaded {
    fn step(&mut self, ev: &mut Evaluator) {
        let grant_round = |ev: &mut Evaluator, granted: &mut u64| {
            for tx in &self.commands {
                let grant = ev.grant(self.objects);
                *granted += grant.quota() as u64;
                tx.send(grant).expect("membrane thread stopped");
            }
        };
        let commit_round = |ev: &mut Evaluator| {
            for rx in &self.reports {
                let evaluated = rx.recv().expect("membrane thread panicked");
                ev.commit(evaluated);
            }
        };
        // Grants go out `AHEAD` rounds before their round is collected, so that a membrane
        // done early starts its next steps at once instead of waiting for the slowest (the
        // quotas depend on counts only, so the results do not change). A round is granted
        // only if the rounds before it leave the optimizer's own budget unspent, the
        // condition under which the caller steps again (a polish may take over at that
        // budget, and must find no evaluations still reserved).
        // A trial that can end inside a round (a stop value) is granted one round at a
        // time: a round's membranes run at once, so the rest of the round that ends it is
        // computed (and counted) whatever the driver, but no round after it.
        let ahead = if ev.can_stop_early() { 0 } else { AHEAD };
        while self.open == 0 || (self.open <= ahead && self.granted < self.budget) {
            grant_round(ev, &mut self.granted);
            self.open += 1;
        }
        commit_round(ev);
        self.open -= 1;
        if ev.done() {
            // Stopped early (a stop value reached): rounds granted ahead were computed, and
            // committed they are counted as spent (with a stop value there are none).
            while self.open > 0 {
                commit_round(ev);
                self.open -= 1;
            }
        }
    }
}

impl Drop for Threaded {
    fn drop(&mut self) {
        // Closing the command channels ends every membrane loop after its current round.
        self.commands.clear();
        for h in self.handles.drain(..) {
            let _ = h.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn seed_structure_has_elementary_membranes_1_2_4() {
        let cfg = MsgaConfig::default();
        let nb = cfg.neighbours();
        assert_eq!(
            nb,
            vec![vec![1, 2, 3], vec![0], vec![0], vec![0, 4], vec![3]]
        );
        let elementary: Vec<usize> = (0..5)
            .filter(|&i| !cfg.structure.contains(&Some(i)))
            .collect();
        assert_eq!(elementary, vec![1, 2, 4]);
        assert_eq!(cfg.migrant_count(), 12);
        assert_eq!(cfg.batch_size(), 200);
    }

    #[test]
    fn receive_replaces_worst_and_skips_duplicates() {
        let cfg = MsgaConfig {
            objects: 3,
            ..MsgaConfig::default()
        };
        let b = Bounds::uniform(1, 0.0, 10.0).unwrap();
        let mut m = Membrane::new(&cfg, &b, TrialSeed::from_u64(0).rng(1));
        m.pop = vec![1.0, 2.0, 3.0];
        m.fit = vec![1.0, 2.0, 3.0];
        m.initialized = true;
        m.receive(&[Migrants {
            points: vec![1.0, 0.5, 9.0],
            values: vec![1.0, 0.5, 9.0],
        }]);
        // 1.0 is a duplicate, 0.5 replaces the worst (3.0), 9.0 beats nothing.
        assert_eq!(m.pop, vec![1.0, 2.0, 0.5]);
        assert_eq!(m.fit, vec![1.0, 2.0, 0.5]);
    }
}

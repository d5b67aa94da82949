//! One model fitted to several records at once (a device recorded several times, at several
//! rates): the actuator's parameters are shared, what belongs to a record is its own. Each
//! record is simulated by the one-record structure at its own sampling interval
//! ([`Structure::at_interval`], [`Structure::carry`]); its initial hysteretic state, its
//! sub-sample timing (when its interval is not the first record's) and its linear nuisances
//! (offset, drift, initial creep states: [`Structure::record_coefs`]) are parameters of
//! their own. The least squares then sees one system: the shared columns stacked, each
//! record's nuisance columns zero outside its rows.

use super::{ParamSpec, Status, Structure};
use std::sync::Arc;

/// Most records one structure is fitted to (the names of the further records' parameters
/// are static).
pub const MAX_RECORDS: usize = 8;

const G0: [&str; MAX_RECORDS - 1] = [
    "g0_frac@2",
    "g0_frac@3",
    "g0_frac@4",
    "g0_frac@5",
    "g0_frac@6",
    "g0_frac@7",
    "g0_frac@8",
];

const TIMING: [&str; MAX_RECORDS - 1] = [
    "timing_samples@2",
    "timing_samples@3",
    "timing_samples@4",
    "timing_samples@5",
    "timing_samples@6",
    "timing_samples@7",
    "timing_samples@8",
];

/// Whether two sampling intervals are one (within 1e-6: the step fitted to jittered or
/// rounded time stamps differs from the true one by parts in 10^9).
pub fn same_interval(a: f64, b: f64) -> bool {
    ((a - b) / b).abs() <= 1e-6
}

/// A parameter's or coefficient's name without the record it belongs to (`d0@2` is `d0`).
pub(super) fn base_name(name: &str) -> &str {
    name.split('@').next().unwrap_or(name)
}

/// The records of a jointly fitted structure, with the layout of the joint vectors worked
/// out once (the columns are assembled on every evaluation of a fit).
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Records {
    /// Samples and sampling interval of each record, in order (at least two).
    parts: Vec<(usize, f64)>,
    /// Samples in all.
    total: usize,
    /// Each record's one-record structure, the first at the first record's interval.
    single: Vec<Structure>,
    /// Where the one-record structures hold their initial state and timing.
    slots: (Option<usize>, usize),
    /// Per further record, where its initial state (a Bouc-Wen core's; operators start
    /// demagnetised) and (at another interval) its timing sit in the joint shape vector.
    states: Vec<(Option<usize>, Option<usize>)>,
    /// The one-record structure's coefficients that belong to a record.
    own: Vec<usize>,
    /// Every coefficient's name, the further records' own with `@k`.
    names: Vec<String>,
    /// Positions of the shape-independent coefficients (each record's offset and drift).
    fixed: Vec<usize>,
}

impl Structure {
    /// This structure fitted jointly to records of `parts` = (samples, sampling interval)
    /// each, concatenated in that order: one record gives the one-record structure at its
    /// interval. At most [`MAX_RECORDS`] (callers check: more is a programming error).
    pub fn on_records(&self, parts: &[(usize, f64)]) -> Structure {
        assert!(
            !parts.is_empty() && parts.len() <= MAX_RECORDS,
            "1 to {MAX_RECORDS} records, not {}",
            parts.len()
        );
        let base = self.single().at_interval(parts[0].1);
        if parts.len() == 1 {
            return base;
        }
        let single: Vec<Structure> = parts.iter().map(|&(_, dt)| base.at_interval(dt)).collect();
        let slot = |name: &str| base.specs.iter().position(|s| s.name == name);
        let slots = (
            slot("g0_frac"),
            slot("timing_samples").expect("every structure has a timing"),
        );
        let mut specs = base.specs.clone();
        let mut states = Vec::new();
        for (k, &(_, dt)) in parts.iter().enumerate().skip(1) {
            let mut add = |from: usize, name: &'static str| {
                specs.push(ParamSpec {
                    name,
                    ..base.specs[from].clone()
                });
                specs.len() - 1
            };
            let g0 = slots.0.map(|s| add(s, G0[k - 1]));
            let timing = (!same_interval(dt, parts[0].1)).then(|| add(slots.1, TIMING[k - 1]));
            states.push((g0, timing));
        }
        let one_names = base.own_linear_names();
        let own = base.record_coefs();
        let mut names: Vec<String> = one_names.iter().map(|n| n.to_string()).collect();
        for r in 2..=parts.len() {
            names.extend(own.iter().map(|&j| format!("{}@{r}", one_names[j])));
        }
        let mut records = Records {
            parts: parts.to_vec(),
            total: parts.iter().map(|p| p.0).sum(),
            single,
            slots,
            states,
            own,
            names,
            fixed: Vec::new(),
        };
        let one_fixed = base.fixed_indices();
        records.fixed = (0..parts.len())
            .flat_map(|r| one_fixed.iter().map(move |&j| (r, j)))
            .map(|(r, j)| records.coef_at(r, j))
            .collect();
        records.fixed.sort_unstable();
        Structure {
            specs,
            records: Some(Arc::new(records)),
            ..base
        }
    }

    /// The records this structure is fitted to (samples, interval); one record: `None`.
    pub fn records(&self) -> Option<&[(usize, f64)]> {
        self.records.as_ref().map(|r| r.parts.as_slice())
    }

    /// The one-record structure (the first record's, at its interval).
    pub fn single(&self) -> Structure {
        match &self.records {
            Some(r) => r.single[0].clone(),
            None => self.clone(),
        }
    }

    /// `other` (built from this structure's parts) on this structure's records.
    pub(super) fn same_records(&self, other: Structure) -> Structure {
        match &self.records {
            Some(r) => other.on_records(&r.parts),
            None => other,
        }
    }
}

impl Records {
    fn base(&self) -> &Structure {
        &self.single[0]
    }

    /// Where record `r`'s coefficient `j` (of the one-record structure) sits in the joint
    /// coefficient vector: the actuator's and the first record's at `j`, the further
    /// records' own after all of the one-record ones, record by record.
    fn coef_at(&self, r: usize, j: usize) -> usize {
        match self.own.iter().position(|&k| k == j) {
            Some(p) if r > 0 => self.one_coefs() + (r - 1) * self.own.len() + p,
            _ => j,
        }
    }

    /// Coefficients of the one-record structure (the first ones of the joint vector).
    fn one_coefs(&self) -> usize {
        self.names.len() - (self.parts.len() - 1) * self.own.len()
    }

    pub(super) fn names(&self) -> &[String] {
        &self.names
    }

    /// Record `r`'s shape vector: the shared parameters carried to its interval, its own
    /// initial state and timing.
    fn theta_of(&self, theta: &[f64], r: usize) -> Vec<f64> {
        let shared = &theta[..self.base().specs.len().min(theta.len())];
        if r == 0 {
            return shared.to_vec();
        }
        let mut th = self.base().carry(shared, &self.single[r]);
        let (g0, timing) = self.states[r - 1];
        if let (Some(slot), Some(g0)) = (self.slots.0, g0) {
            th[slot] = theta[g0];
        }
        if let Some(t) = timing {
            th[self.slots.1] = theta[t];
        }
        th
    }

    /// Every coefficient's column over the concatenated records; an input that is not
    /// the records' (another length) is simulated by the first record's model.
    pub(super) fn columns(&self, theta: &[f64], u: &[f64]) -> (Vec<Vec<f64>>, Status) {
        if u.len() != self.total {
            return self.base().columns(&self.theta_of(theta, 0), u);
        }
        let mut cols = vec![vec![0.0; self.total]; self.names.len()];
        let mut status = Status::Ok;
        let mut from = 0;
        for (r, &(len, _)) in self.parts.iter().enumerate() {
            let (c, s) = self.single[r].columns(&self.theta_of(theta, r), &u[from..from + len]);
            for (j, col) in c.into_iter().enumerate() {
                cols[self.coef_at(r, j)][from..from + len].copy_from_slice(&col);
            }
            if let (Status::Ok, Status::Unstable { at }) = (status, s) {
                status = Status::Unstable { at: from + at };
            }
            from += len;
        }
        (cols, status)
    }

    /// Positions of the shape-independent columns (each record's offset and drift).
    pub(super) fn fixed_indices(&self) -> Vec<usize> {
        self.fixed.clone()
    }

    /// The columns at [`Self::fixed_indices`], in that order.
    pub(super) fn fixed_columns(&self) -> Vec<Vec<f64>> {
        let fixed_at = self.base().fixed_indices();
        let mut placed: Vec<(usize, Vec<f64>)> = Vec::new();
        let mut from = 0;
        for (r, &(len, _)) in self.parts.iter().enumerate() {
            for (&j, col) in fixed_at.iter().zip(self.single[r].fixed_columns(len)) {
                let mut full = vec![0.0; self.total];
                full[from..from + len].copy_from_slice(&col);
                placed.push((self.coef_at(r, j), full));
            }
            from += len;
        }
        placed.sort_by_key(|p| p.0);
        placed.into_iter().map(|p| p.1).collect()
    }

    /// The shape-dependent columns: [`Self::columns`] without the fixed ones.
    pub(super) fn varying_columns(&self, theta: &[f64], u: &[f64]) -> (Vec<Vec<f64>>, Status) {
        if u.len() != self.total {
            return self.base().varying_columns(&self.theta_of(theta, 0), u);
        }
        let (cols, status) = self.columns(theta, u);
        let varying = cols
            .into_iter()
            .enumerate()
            .filter(|(i, _)| self.fixed.binary_search(i).is_err())
            .map(|(_, c)| c)
            .collect();
        (varying, status)
    }

    /// Every record's creep states bounded as the first record's ([`Structure::state_bounds`]).
    pub(super) fn state_bounds(&self, theta: &[f64], range: f64) -> Vec<(usize, f64)> {
        let first = self.base().state_bounds(&self.theta_of(theta, 0), range);
        (0..self.parts.len())
            .flat_map(|r| first.iter().map(move |&(j, b)| (r, j, b)))
            .map(|(r, j, b)| (self.coef_at(r, j), b))
            .collect()
    }

    /// The first record's parameters, then each further record's own by name (`g0_frac@2`,
    /// `d0@2`, ...).
    pub(super) fn named_params(&self, theta: &[f64], coef: &[f64]) -> Vec<(String, f64)> {
        let nl = self.one_coefs();
        let mut v = self
            .base()
            .named_params(&self.theta_of(theta, 0), &coef[..nl.min(coef.len())]);
        for (k, &(g0, timing)) in self.states.iter().enumerate() {
            if let Some(g0) = g0 {
                v.push((G0[k].to_string(), theta[g0]));
            }
            if let Some(t) = timing {
                v.push((TIMING[k].to_string(), theta[t]));
            }
        }
        for (name, &c) in self.names.iter().zip(coef).skip(nl) {
            v.push((name.clone(), c));
        }
        v
    }
}

#[cfg(test)]
mod tests {
    use super::super::tests::theta_with;
    use super::super::{Context, Effect, Form, Placement};
    use super::*;

    fn sine(n: usize, hz: f64, dt: f64, amp: f64) -> Vec<f64> {
        (0..n)
            .map(|k| 2.0 + amp * (2.0 * std::f64::consts::PI * hz * k as f64 * dt).sin())
            .collect()
    }

    /// Two records, 1 kHz and 400 Hz; a structure with creep and a drift on both, its joint
    /// shape and coefficients (record 2: its own initial state, timing, offset, drift and
    /// creep states).
    fn two_records() -> (Vec<f64>, Vec<f64>, Structure, Vec<f64>, Vec<f64>) {
        let (dt1, dt2) = (1e-3, 2.5e-3);
        let u1 = sine(1500, 2.0, dt1, 1.8);
        let u2 = sine(800, 0.7, dt2, 1.2);
        let ctx = Context::from_training(&u1, dt1);
        let one = Structure::with_forms(
            &[
                (Effect::Creep, Form::KelvinVoigt),
                (Effect::OffsetDrift, Form::Polynomial),
            ],
            Some(1.0),
            ctx,
            Placement::After,
        );
        let st = one.on_records(&[(u1.len(), dt1), (u2.len(), dt2)]);
        let theta = theta_with(
            &st,
            &[
                ("log10_s", -0.4),
                ("w", 0.6),
                ("g0_frac", -0.2),
                ("creep_g", 0.1),
                ("creep_log10_tau_s", -1.0),
                ("creep_g2", 0.05),
                ("creep_log10_tau2_s", 0.3),
                ("g0_frac@2", 0.3),
                ("timing_samples@2", -0.5),
            ],
        );
        let names = st.linear_names();
        let coef: Vec<f64> = names
            .iter()
            .map(|n| match n.as_str() {
                "d_e" => 0.15,
                "alpha" => 0.05,
                "d0" => 0.01,
                "d0@2" => -0.2,
                "drift_a1" => 0.003,
                "drift_a2@2" => -0.004,
                "creep_x0_fast@2" => 0.002,
                _ => 0.0,
            })
            .collect();
        (u1, u2, st, theta, coef)
    }

    /// The joint model is each record's own model on its samples: the first record's with
    /// the shared parameters, the second's carried to its interval with its initial state,
    /// timing and nuisance coefficients.
    #[test]
    fn a_joint_structure_is_each_record_simulated_on_its_own() {
        let (u1, u2, st, theta, coef) = two_records();
        let names = st.linear_names();
        assert_eq!(
            names[names.len() - 5..],
            [
                "d0@2",
                "drift_a1@2",
                "drift_a2@2",
                "creep_x0_fast@2",
                "creep_x0_slow@2"
            ]
        );
        let u: Vec<f64> = u1.iter().chain(&u2).copied().collect();
        let (joint, status) = st.simulate(&theta, &coef, &u);
        assert_eq!(status, Status::Ok);
        let one = st.single();
        let nb = one.specs().len();
        let nl = one.linear_names().len();
        let (first, _) = one.simulate(&theta[..nb], &coef[..nl], &u1);
        // Equal but for the order of the sums (the other record's zero columns).
        let worst = |a: &[f64], b: &[f64]| {
            assert_eq!(a.len(), b.len());
            a.iter()
                .zip(b)
                .map(|(x, y)| (x - y).abs())
                .fold(0.0, f64::max)
        };
        assert!(worst(&joint[..u1.len()], &first) < 1e-14);
        let second_st = one.at_interval(2.5e-3);
        let mut th2 = one.carry(&theta[..nb], &second_st);
        let at = |n: &str| second_st.specs().iter().position(|s| s.name == n).unwrap();
        th2[at("g0_frac")] = 0.3;
        th2[at("timing_samples")] = -0.5;
        let mut c2 = coef[..nl].to_vec();
        for (j, name) in names[..nl].iter().enumerate() {
            if let Some(k) = names.iter().position(|n| *n == format!("{name}@2")) {
                c2[j] = coef[k];
            }
        }
        let (second, _) = second_st.simulate(&th2, &c2, &u2);
        assert!(worst(&joint[u1.len()..], &second) < 1e-14);
        // The carried creep time constants are the same seconds at 400 Hz.
        assert_eq!(th2[at("creep_log10_tau_s")], -1.0);
    }

    /// An operator core has no initial state to fit (its plays start demagnetised): two
    /// records at one interval join with no shape parameter of their own, and each is its
    /// own model (the CubeSpec mirror's two amplitudes under `--model auto` panicked here).
    #[test]
    fn a_joint_pi_core_is_each_record_simulated_on_its_own() {
        let dt = 1e-3;
        let (u1, u2) = (sine(1500, 2.0, dt, 1.8), sine(900, 0.7, dt, 1.2));
        let core = crate::physics::structure::PiCore::new(6, &[&u1, &u2]);
        let one = Structure::new(
            &[Effect::Creep],
            None,
            Context::from_training(&u1, dt).with_pi(Some(core)),
        );
        let st = one.on_records(&[(u1.len(), dt), (u2.len(), dt)]);
        assert_eq!(st.specs().len(), one.specs().len(), "nothing per record");
        let theta: Vec<f64> = st.specs().iter().map(|s| s.neutral).collect();
        let names = st.linear_names();
        let coef: Vec<f64> = (0..names.len()).map(|j| 0.1 * (j as f64 + 1.0)).collect();
        let u: Vec<f64> = u1.iter().chain(&u2).copied().collect();
        let (joint, status) = st.simulate(&theta, &coef, &u);
        assert_eq!(status, Status::Ok);
        let nl = one.linear_names().len();
        let mut c2 = coef[..nl].to_vec();
        for (j, name) in names[..nl].iter().enumerate() {
            if let Some(k) = names.iter().position(|n| *n == format!("{name}@2")) {
                c2[j] = coef[k];
            }
        }
        for (part, c, out) in [
            (&u1, &coef[..nl], &joint[..u1.len()]),
            (&u2, &c2[..], &joint[u1.len()..]),
        ] {
            let (alone, _) = one.simulate(&theta, c, part);
            let worst = alone
                .iter()
                .zip(out)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            assert!(worst < 1e-12, "{worst}");
        }
    }

    /// At the true shape the least squares returns every record's own offset, drift and
    /// creep states and the shared gains; the projected solve the fits use agrees with the
    /// direct one. The nuisances count once per record in the information criteria.
    #[test]
    fn each_record_keeps_its_own_nuisances_in_one_least_squares() {
        let (u1, u2, st, theta, coef) = two_records();
        let u: Vec<f64> = u1.iter().chain(&u2).copied().collect();
        let (y, _) = st.simulate(&theta, &coef, &u);
        let fit = st.fit_linear(&theta, &u, &y);
        let reference = st.fit_linear_reference(&theta, &u, &y);
        assert!(fit.cost < 1e-20, "{}", fit.cost);
        for ((a, b), want) in fit.coef.iter().zip(&reference.coef).zip(&coef) {
            assert!((a - want).abs() < 1e-7, "{a} against {want}");
            assert!((a - b).abs() < 1e-7, "{a} against {b}");
        }
        let own: Vec<String> = st
            .record_coefs()
            .iter()
            .map(|&j| st.linear_names()[j].clone())
            .collect();
        assert_eq!(own.len(), 10, "{own:?}");
        assert!(own.contains(&"d0@2".to_string()) && !own.contains(&"d_e".to_string()));
        let one = st.single();
        assert_eq!(st.n_params(), one.n_params() + 2 + 5);
        // A record's offset is not another's: one shared offset fits worse.
        let mut shared = y.clone();
        for v in &mut shared[u1.len()..] {
            *v += 0.21;
        }
        assert!(st.fit_linear(&theta, &u, &shared).cost < 1e-20);
        let joined = one.fit_linear(&theta[..one.specs().len()], &u, &y);
        assert!(joined.cost > 1e-4, "{}", joined.cost);
    }

    /// Derived structures keep the records; named parameters name each record's own.
    #[test]
    fn derived_structures_keep_their_records() {
        let (u1, _, st, theta, coef) = two_records();
        let more = st.extended(Effect::Delay);
        assert_eq!(more.records(), st.records());
        assert!(more.specs().iter().any(|s| s.name == "g0_frac@2"));
        assert_eq!(more.without(Effect::Delay), st);
        let named = st.named_params(&theta, &coef);
        let get = |n: &str| named.iter().find(|p| p.0 == n).map(|p| p.1);
        assert_eq!(get("g0_frac@2"), Some(0.3));
        assert_eq!(get("d0@2"), Some(-0.2));
        assert_eq!(get("d0"), Some(0.01));
        // One record: the one-record structure itself.
        assert_eq!(st.single().on_records(&[(u1.len(), 1e-3)]), st.single());
        assert_eq!(st.single().records(), None);
    }
}

//! The regressor columns of a shape: the model simulated with its linear coefficients left
//! free, for variable projection.

use super::*;
use crate::physics::prandtl_ishlinskii::play;
use crate::physics::preisach::{Preisach, PreisachGrid, PreisachStepper};

/// A linear-in-weights core's operator outputs, sample by sample: the plays' outputs
/// (starting at 0) or the relays' states (0/1, demagnetised at the first input).
enum Core {
    Plays { r: Vec<f64>, z: Vec<f64> },
    Relays(PreisachStepper),
}

impl Core {
    fn new(pi: &PiCore) -> Core {
        match pi.kind {
            CoreKind::Plays => {
                let r = pi.thresholds();
                let z = vec![0.0; r.len()];
                Core::Plays { r, z }
            }
            CoreKind::Relays => {
                let grid = pi.grid();
                let weights = vec![0.0; grid.relays()];
                Core::Relays(
                    Preisach {
                        grid,
                        weights,
                        offset: 0.0,
                    }
                    .stepper(),
                )
            }
        }
    }

    /// Applies drive `v` with the plays' thresholds scaled by `width` (1: the
    /// rate-independent core; relays take no width); `out` gets one output per operator
    /// (relays in [`PreisachGrid::index`] order).
    fn step(&mut self, v: f64, width: f64, out: &mut [f64]) {
        match self {
            Core::Plays { r, z } => {
                for ((zi, &ri), o) in z.iter_mut().zip(r.iter()).zip(out.iter_mut()) {
                    *zi = play(ri * width, *zi, v);
                    *o = *zi;
                }
            }
            Core::Relays(st) => {
                st.step(v);
                for (i, &on) in st.interface().iter().enumerate() {
                    for j in 0..=i {
                        out[PreisachGrid::index(i, j)] = if j < on { 1.0 } else { 0.0 };
                    }
                }
            }
        }
    }
}

impl Structure {
    /// Simulates the regressor columns on input `u`: `[v, 1, -(1+ρr) α-free g]` after the
    /// post-hysteresis filters, plus the drift columns; column-major, `cols[j][k]`.
    pub(super) fn columns(&self, theta: &[f64], u: &[f64]) -> (Vec<Vec<f64>>, Status) {
        if let Some(r) = &self.records {
            return r.columns(theta, u);
        }
        let (varying, status) = self.varying_columns(theta, u);
        (self.assemble(varying, u.len()), status)
    }

    /// The columns that depend on the shape, in coefficient order without
    /// [`Self::fixed_columns`]: `[v, g, creep states]` (or `[y, creep states]` in the
    /// feedback placement).
    pub(super) fn varying_columns(&self, theta: &[f64], u: &[f64]) -> (Vec<Vec<f64>>, Status) {
        if let Some(r) = &self.records {
            return r.varying_columns(theta, u);
        }
        let n = u.len();
        let sh = self.shape(theta);
        if self.placement == Placement::Feedback {
            return self.columns_feedback(&sh, u);
        }
        let ctx = &self.ctx;
        let dt = ctx.dt;
        let mut cv = vec![0.0; n];
        let mut cg = vec![0.0; n];
        let mut status = Status::Ok;
        if n == 0 {
            return (vec![cv, cg], status);
        }
        let finite_shape = sh.is_finite();
        let u = &if finite_shape {
            shift(u, sh.input_shift(self), sh.curvature.clamp(0.0, 1.0))
        } else {
            u.to_vec()
        };
        // Direction asymmetry: the hysteretic slope is 1 + a on rising drive, 1 - a falling.
        let up = self.kernel(&sh, 1.0 + sh.dir_a);
        let down = if sh.dir_a != 0.0 {
            self.kernel(&sh, 1.0 - sh.dir_a)
        } else {
            up
        };
        let drive = sh.drive(ctx.u_ref);
        let mut lag =
            (self.has(Effect::InputLag) && sh.lag > 0.0).then(|| LowPass::new(sh.lag, dt));
        let mut lag2 = (self.has(Effect::InputLag) && sh.lag2_hz.is_finite())
            .then(|| Mode::new(sh.lag2_hz, sh.lag2_zeta.max(0.0), dt));
        let mut rate =
            (self.has(Effect::RateDependence) && sh.rho != 0.0).then(|| LowPass::new(sh.tau_r, dt));
        let exp_tau = lag.as_ref().map(|_| sh.lag);
        let blocks = self.after_blocks(&sh, exp_tau);
        // Initial state: every block at rest at the first sample.
        let u0 = u[0];
        if let Some(l) = &mut lag {
            l.settle(u0);
        }
        if let Some(l) = &mut lag2 {
            l.settle(u0);
        }
        let v0 = drive(u0);
        // Previous inputs of the linear blocks, for the hold (`block_hold`): the drive
        // into the lag (either form: a second-order lag fed at the interval's end runs a
        // sample ahead of a D/A, which the timing's half sample cannot undo; blind seed
        // 20261161 case 1 was fitted 2x the first-order lag's cost at the true cut-off);
        // without a lag, the hysteresis output into creep and modes (with a lag, their
        // inputs are continuous and the exponential hold is exact).
        let hold = sh.block_hold.clamp(0.0, 1.0);
        let mut prev_u = u0;
        let no_lag = lag.is_none() && lag2.is_none();
        let mut drives = u.iter().map(|&x0| {
            let mut x = x0;
            if let Some(l) = &mut lag {
                x = l.step(held(hold, x, &mut prev_u));
            }
            if let Some(l) = &mut lag2 {
                x = l.step(held(hold, x, &mut prev_u));
            }
            drive(x)
        });
        // The rate's memory starts at the rate the record starts with: a record cut from a
        // running excitation starts in motion, and memory at rest would add a start-up
        // transient of the rate time constant that a drift or creep then soaks up.
        let rate0 = (u.get(1).map_or(v0, |&x| drive(x)) - v0).abs() / dt;
        if let Some(r) = &mut rate {
            r.settle(rate0);
        }
        if let Some(pi) = self.ctx.pi {
            let mut core = Core::new(&pi);
            // The asymmetric PI's quadratic rides as one more operator output.
            let quadratic = self.pi_quadratic();
            let mut z = vec![0.0; self.pi_operators()];
            let ops = pi.columns();
            let u_ref = ctx.u_ref;
            let mut cols = vec![vec![0.0; n]; z.len()];
            let mut after: Vec<After> = Vec::with_capacity(z.len());
            let mut v_prev = v0;
            for k in 0..n {
                let v = drives.next().unwrap_or(v0);
                let mut finite = finite_shape;
                // The rate-dependent PI: weights (gain) or thresholds (width) scaled by
                // 1 + ρ·rate, the rate low-passed as in the Bouc-Wen core.
                let rr = rate.as_mut().map_or(0.0, |r| {
                    r.step(if k == 0 {
                        rate0
                    } else {
                        (v - v_prev).abs() / dt
                    }) / ctx.rate_ref
                });
                v_prev = v;
                let scale = (1.0 + sh.rho * rr).max(1e-6);
                let (gain, width) = if sh.rate_gain {
                    (scale, 1.0)
                } else {
                    (1.0, scale)
                };
                core.step(v, width, &mut z[..ops]);
                if quadratic {
                    z[ops] = v * v / u_ref;
                }
                for (i, &zi) in z.iter().enumerate() {
                    let zi = gain * zi;
                    if k == 0 {
                        after.push(blocks.start(zi, hold, no_lag));
                    }
                    let x = after[i].step(zi);
                    finite &= x.is_finite();
                    cols[i][k] = x;
                }
                if !finite {
                    status = Status::Unstable { at: k };
                    for c in &mut cols {
                        c[k..].fill(0.0);
                    }
                    break;
                }
            }
            cols.extend(self.state_columns(&sh, n));
            return (cols, status);
        }
        // The hysteretic state at the first sample; the linear blocks after it at rest there.
        let mut g = sh.g0.clamp(-1.0, 1.0) * sh.g0_scale(ctx.u_ref);
        let g_init = if g.is_finite() { g } else { 0.0 };
        let mut after_v = blocks.start(v0, hold, no_lag);
        let mut after_g = blocks.start(-g_init, hold, no_lag);
        let bound = 1e6 * (1.0 + ctx.u_ref) * (1.0 + u.iter().fold(0.0f64, |m, x| m.max(x.abs())));
        let mut v_prev = v0;
        for k in 0..n {
            let v = drives.next().unwrap_or(v0);
            let dv = v - v_prev;
            let rr = rate.as_mut().map_or(0.0, |r| {
                r.step(if k == 0 { rate0 } else { dv.abs() / dt }) / ctx.rate_ref
            });
            let advance = |g: f64, dv: f64| {
                if dv >= 0.0 {
                    up.advance(g, dv)
                } else {
                    down.advance(g, dv)
                }
            };
            let mut vv = v;
            if sh.rate_gain {
                vv *= 1.0 + sh.rho * rr;
                g = advance(g, dv);
            } else if rr != 0.0 {
                // The slope inside the equation scales with the rate: dg = dv (kα - c|g|^n).
                // With g = k^(1/n) g' that is the plain equation in g' over k^(1-1/n) dv, so
                // the state keeps the memory of earlier rates (the width is not rescaled at
                // once when the rate falls).
                let k = (1.0 + sh.rho * rr).max(1e-6);
                let kn = if sh.n == 1.0 { k } else { k.powf(1.0 / sh.n) };
                g = kn * advance(g / kn, dv * k / kn);
            } else {
                g = advance(g, dv);
            }
            v_prev = v;
            let (a, b) = (after_v.step(vv), after_g.step(-g));
            if !(finite_shape && a.is_finite() && b.is_finite() && g.abs() <= bound) {
                status = Status::Unstable { at: k };
                cv[k..].fill(0.0);
                cg[k..].fill(0.0);
                break;
            }
            cv[k] = a;
            cg[k] = b;
        }
        let mut cols = vec![cv, cg];
        cols.extend(self.state_columns(&sh, n));
        (cols, status)
    }

    /// The columns that do not depend on the shape: the constant and the drift (`t/T,
    /// (t/T)²`, or the spline's hat functions over the record's own length).
    pub(super) fn fixed_columns(&self, n: usize) -> Vec<Vec<f64>> {
        if let Some(r) = &self.records {
            return r.fixed_columns();
        }
        let dt = self.ctx.dt;
        let mut cols = vec![vec![1.0; n]];
        match self.form(Effect::OffsetDrift) {
            Some(Form::Spline) => cols.extend(spline_hats(n, spline_segments(&self.ctx))),
            Some(Form::Settling) | None => {}
            Some(_) => {
                let t: Vec<f64> = (0..n).map(|k| k as f64 * dt / self.ctx.t_ref).collect();
                let t2 = t.iter().map(|x| x * x).collect();
                cols.push(t);
                cols.push(t2);
            }
        }
        cols
    }

    /// Indices of [`Self::fixed_columns`] among the coefficients (the constant is always 1;
    /// the drift follows the hysteretic column after the hysteresis, the constant in the
    /// feedback placement).
    pub(super) fn fixed_indices(&self) -> Vec<usize> {
        if let Some(r) = &self.records {
            return r.fixed_indices();
        }
        let drift = self.fixed_columns(0).len() - 1;
        let first = match self.placement {
            Placement::After if self.ctx.pi.is_some() => 1 + self.pi_operators(),
            Placement::After => 3,
            Placement::Feedback => 2,
        };
        std::iter::once(1).chain(first..first + drift).collect()
    }

    /// All columns in coefficient order from the shape-dependent ones `varying`.
    pub(super) fn assemble(&self, varying: Vec<Vec<f64>>, n: usize) -> Vec<Vec<f64>> {
        let fixed_at = self.fixed_indices();
        let total = varying.len() + fixed_at.len();
        let mut fixed = self.fixed_columns(n).into_iter();
        let mut var = varying.into_iter();
        (0..total)
            .map(|i| {
                if fixed_at.contains(&i) {
                    fixed.next().expect("fixed column")
                } else {
                    var.next().expect("varying column")
                }
            })
            .collect()
    }

    /// Decays `e^(-t/τ)` from each record's start, shape-dependent columns after the drift:
    /// the creep elements' initial states, then a settling drift.
    pub(super) fn state_columns(&self, sh: &Shape, n: usize) -> Vec<Vec<f64>> {
        let dt = self.ctx.dt;
        let mut taus = match self.form(Effect::Creep) {
            Some(Form::Logarithmic) => log_creep_state_taus(&self.ctx).to_vec(),
            Some(_) => vec![sh.creep_tau, sh.creep_tau2],
            None => Vec::new(),
        };
        if self.form(Effect::OffsetDrift) == Some(Form::Settling) {
            taus.push(sh.drift_tau);
        }
        taus.into_iter()
            .map(|tau| {
                let r = (-dt / tau).exp();
                let col: Vec<f64> = std::iter::successors(Some(1.0), |p| Some(p * r))
                    .take(n)
                    .collect();
                if col.iter().all(|x| x.is_finite()) {
                    col
                } else {
                    vec![0.0; n]
                }
            })
            .collect()
    }

    /// [`Self::varying_columns`] for the feedback placement: `[creep(y), creep states]`, `y` the unit-free
    /// oscillator's displacement driven by the chain's output over `u_ref`.
    pub(super) fn columns_feedback(&self, sh: &Shape, u: &[f64]) -> (Vec<Vec<f64>>, Status) {
        let n = u.len();
        let ctx = &self.ctx;
        let dt = ctx.dt;
        let osc = Oscillator {
            omega: 2.0 * std::f64::consts::PI * sh.fb_hz,
            zeta: sh.fb_zeta,
            r: sh.fb_r,
            b: sh.fb_b,
            c: sh.fb_c,
            n: sh.n,
        };
        let finite = sh.is_finite();
        let tail = self.state_columns(sh, n);
        let failed = |at: usize| {
            let mut cols = vec![vec![0.0; n]];
            cols.extend(tail.iter().cloned());
            (cols, Status::Unstable { at })
        };
        if n == 0 || !finite {
            return failed(0);
        }
        // The command at the samples (timing, delay, a second-order lag), between them
        // (hold), a first-order lag on the fine grid.
        let mut x = shift(u, sh.input_shift(self), sh.curvature.clamp(0.0, 1.0));
        if self.has(Effect::InputLag) && sh.lag2_hz.is_finite() {
            let mut l = Mode::new(sh.lag2_hz, sh.lag2_zeta.max(0.0), dt);
            l.settle(x[0]);
            for v in &mut x {
                *v = l.step(*v);
            }
        }
        let m = osc.substeps(dt, ctx.min_substeps);
        let mut fine = upsample(&x, ctx.hold, m);
        if self.has(Effect::InputLag) && sh.lag > 0.0 {
            let mut lp = LowPass::new(sh.lag, dt / (2 * m) as f64);
            lp.settle(u[0]);
            let per = fine.per();
            for (i, v) in fine.values.iter_mut().enumerate() {
                // Each interval's first value is the previous one's last instant.
                *v = if i % per == 0 {
                    lp.output()
                } else {
                    lp.step(*v)
                };
            }
        }
        let clip = sh.drive(ctx.u_ref);
        let drive = |x: f64| clip(x) / ctx.u_ref;
        fine.map(drive);
        let y = match osc.respond(&fine, dt, drive(u[0]), sh.g0.clamp(-1.0, 1.0)) {
            Ok(y) => y,
            Err(at) => return failed(at),
        };
        let mut out = y;
        if let Some(form) = self.form(Effect::Creep) {
            let y = out.clone();
            for (g, tau) in sh.creep_elements(form, ctx) {
                if g != 0.0 {
                    let mut lp = LowPass::new(tau, dt);
                    lp.settle(y[0]);
                    for (o, &v) in out.iter_mut().zip(&y).skip(1) {
                        *o += g * lp.step(v);
                    }
                    out[0] += g * y[0];
                }
            }
        }
        if out.iter().any(|v| !v.is_finite()) {
            return failed(0);
        }
        let mut cols = vec![out];
        cols.extend(tail);
        (cols, Status::Ok)
    }
}

/// `x` held back by `hold` of a sample toward the previous input `prev` (a D/A that updates
/// at the sample), which becomes `x`.
fn held(hold: f64, x: f64, prev: &mut f64) -> f64 {
    let r = x - hold * (x - *prev);
    *prev = x;
    r
}

/// The linear blocks after the hysteresis (creep elements, modes) of one shape, before any
/// column has passed through them: the chain is linear after its core, so each regressor
/// column runs through its own copy ([`Self::start`]).
struct AfterBlocks {
    creep: Vec<(f64, LowPass)>,
    mode: Option<Mode>,
    mode2: Option<Mode>,
    share: f64,
    exp: bool,
    k_dc: f64,
}

/// One column's copy of [`AfterBlocks`], with its hold state.
struct After {
    creep: Vec<(f64, LowPass)>,
    mode: Option<Mode>,
    mode2: Option<Mode>,
    share: f64,
    exp: bool,
    /// Hold of the blocks' inputs (`block_hold`), without a lag before them.
    hold: Option<f64>,
    prev_in: f64,
    prev_mode: f64,
}

impl AfterBlocks {
    /// A copy at rest at the column's first value `x0` (the modes at the creep's DC gain
    /// times it); `hold` applies where `no_lag` (a lag's output is continuous).
    fn start(&self, x0: f64, hold: f64, no_lag: bool) -> After {
        let mut creep = self.creep.clone();
        for (_, c) in &mut creep {
            c.settle(x0);
        }
        let (mut mode, mut mode2) = (self.mode.clone(), self.mode2.clone());
        for m in mode.iter_mut().chain(mode2.iter_mut()) {
            m.settle(self.k_dc * x0);
        }
        After {
            creep,
            mode,
            mode2,
            share: self.share,
            exp: self.exp,
            hold: (no_lag && hold > 0.0).then_some(hold),
            prev_in: x0,
            prev_mode: self.k_dc * x0,
        }
    }
}

impl After {
    /// The blocks' output at the next sample, whose input is `x`.
    #[inline]
    fn step(&mut self, x: f64) -> f64 {
        let mut a = x;
        let a0 = match self.hold {
            Some(h) if !self.creep.is_empty() => held(h, a, &mut self.prev_in),
            _ => a,
        };
        for (gain, c) in &mut self.creep {
            let l = if self.exp { c.step_exp(a0) } else { c.step(a0) };
            a += *gain * l;
        }
        if let Some(h) = self.hold
            && (self.mode.is_some() || self.mode2.is_some())
        {
            a = held(h, a, &mut self.prev_mode);
        }
        let exp = self.exp;
        let step_mode = |m: &mut Mode, x: f64| if exp { m.step_exp(x) } else { m.step(x) };
        match (&mut self.mode, &mut self.mode2) {
            (Some(m), Some(m2)) => {
                let (a1, a2) = (step_mode(m, a), step_mode(m2, a));
                a = (1.0 - self.share) * a1 + self.share * a2;
            }
            (Some(m), None) | (None, Some(m)) => a = step_mode(m, a),
            (None, None) => {}
        }
        a
    }
}

impl Structure {
    /// The creep elements and modes of shape `sh`, discretised with the exponential hold
    /// `exp_tau` of a lag before them.
    fn after_blocks(&self, sh: &Shape, exp_tau: Option<f64>) -> AfterBlocks {
        let dt = self.ctx.dt;
        let creep: Vec<(f64, LowPass)> = match self.form(Effect::Creep) {
            Some(form) => sh
                .creep_elements(form, &self.ctx)
                .into_iter()
                .filter(|(g, _)| *g != 0.0)
                .map(|(g, tau)| {
                    let l = LowPass::new(tau, dt);
                    (
                        g,
                        match exp_tau {
                            Some(t) => l.with_exp_hold(t),
                            None => l,
                        },
                    )
                })
                .collect(),
            None => Vec::new(),
        };
        let mk_mode = |f: f64, zeta: f64| {
            let m = Mode::new(f, zeta.max(0.0), dt);
            match exp_tau {
                Some(t) => m.with_exp_hold(t),
                None => m,
            }
        };
        let mode = (self.has(Effect::Dynamics) && sh.mode_p > 0.0)
            .then(|| mk_mode(1.0 / (2.0 * std::f64::consts::PI * sh.mode_p), sh.zeta));
        let share = sh.mode2_share.clamp(0.0, 1.0);
        let mode2 = (self.has(Effect::Dynamics) && sh.mode2_hz.is_finite() && share > 0.0)
            .then(|| mk_mode(sh.mode2_hz, sh.mode2_zeta));
        AfterBlocks {
            k_dc: 1.0 + creep.iter().map(|c| c.0).sum::<f64>(),
            creep,
            mode,
            mode2,
            share,
            exp: exp_tau.is_some(),
        }
    }
}

/// The spline drift's hats at knots `1..=m` over `[0, n-1]` (the constant column spans knot
/// 0), one column of `n` samples each.
pub(super) fn spline_hats(n: usize, m: usize) -> Vec<Vec<f64>> {
    let width = (n.max(2) - 1) as f64 / m as f64;
    (1..=m)
        .map(|j| {
            let c = j as f64 * width;
            (0..n)
                .map(|k| (1.0 - (k as f64 - c).abs() / width).max(0.0))
                .collect()
        })
        .collect()
}

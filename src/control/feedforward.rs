//! Hysteresis compensation by feedforward (issue 19): the command is the inverse of a
//! hysteresis model identified on the twin, applied to the reference, optionally with the
//! incremental PID of eq. 4.9 on the tracking error added (`u = Γ̂⁻¹[y_d] + PID(e)`, the
//! common practice). The dissertation names this the main alternative to its feedback IMC.
//!
//! - `ff-pi`: a plain Prandtl-Ishlinskii model at its exact least-squares optimum
//!   ([`PiModel::fit`]), inverted analytically ([`PiModel::inverse`]): the inverse is again
//!   a PI model, run on the reference.
//! - `ff-bw`: a Bouc-Wen model (eq. 3.1-3.3) fitted by CMA-ES through the ordinary fitting
//!   objective ([`BoucWenFit`]), inverted numerically sample by sample ([`BoucWenInverse`]).
//!
//! The model is identified like the IMC's internal model ([`super::model`]): on a twin
//! recording of the same excitation, on the twin named by the run's `model_twin` (mismatch),
//! every random number from the trial's model seed.
//!
//! Timing: the command `u(k)` sets the reading `y(k+1)` (see [`super::closed_loop`]), so the
//! feedforward inverts the model at the *next* reference sample `y_d(k+1)`: the reference of
//! a feedforward is a known trajectory, and without this one-sample preview a perfect inverse
//! would still lag by 1 ms (0.016 mm peak on a 10 Hz, 0.25 mm sinusoid).

use super::model::rms_diff;
use super::pid::{IncrementalPid, PidGains};
use crate::base::TrialSeed;
use crate::base::error::{Error, Result};
use crate::data::recording::Recording;
use crate::harness::TrialRecord;
use crate::objective::Objective;
use crate::objective::hysteresis::{BoucWenFit, BoucWenScheme, FitData, FitView};
use crate::optimizer::cmaes::CmaesConfig;
use crate::physics::bouc_wen::{BoucWenKernel, BoucWenParams, BoucWenState};
use crate::physics::prandtl_ishlinskii::{PiForm, PiModel, PiStepper};
use crate::pipeline::runner::{TrialSpec, run_trial};
use serde::{Deserialize, Serialize};
use std::sync::Arc;

/// Bounds of every normalised Bouc-Wen parameter in the fit. The dissertation's [0, 1.5] does
/// not hold the twin: on data normalised by max|u| ≈ 4.7 V, `β` scales by max|u| and the
/// twin's command-scale 0.45 /V becomes 2.1.
pub const BW_BOUNDS: (f64, f64) = (0.0, 4.0);

/// Which model is inverted, with its own settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
pub enum InverseModelSpec {
    /// Plain PI with `operators` play operators (the linear term included), thresholds
    /// uniform over half the record's command range.
    Pi { operators: usize },
    /// Bouc-Wen fitted by CMA-ES with `budget` evaluations.
    BoucWen { budget: u64 },
}

/// Default CMA-ES evaluations of the Bouc-Wen fit (about 0.1 ms each on a 4 s record at 1 ms).
/// On the mode-free twin (CLI seeds 1-3) 3000 left one fit of three at 0.0087 mm free-run
/// RMSE against 3e-4 for the others; 6000 brought it to 0.0026.
pub const DEFAULT_BW_BUDGET: u64 = 6000;

/// Default gains of the PID added to a feedforward: integral action only. The inverse does
/// the tracking; the feedback only has to remove what the model misses (creep, offsets). The
/// PID tuned for feedback alone (0.3, 0.4, 0.2) rings with the 103 Hz mode after the
/// feedforward's first step (1-10 Hz sweep, mismatch, CLI seed 2: 0.0114 mm, against 0.0073
/// for the feedforward alone); ki = 0.05-0.3 with kp = kd = 0 gave 0.0032-0.0046 mm.
pub const FF_PID: PidGains = PidGains {
    kp: 0.0,
    ki: 0.1,
    kd: 0.0,
};

impl InverseModelSpec {
    /// The model and its fit, for reports.
    pub fn describe(&self) -> String {
        match self {
            InverseModelSpec::Pi { operators } => {
                format!(
                    "plain Prandtl-Ishlinskii ({operators} operators, least-squares optimum, analytic inverse)"
                )
            }
            InverseModelSpec::BoucWen { budget } => {
                format!("Bouc-Wen (CMA-ES, {budget} evaluations, numerical inverse)")
            }
        }
    }

    /// Sets the evaluations of an iterative fit (a closed-form fit has none).
    pub fn set_budget(&mut self, b: u64) {
        match self {
            InverseModelSpec::BoucWen { budget } => *budget = b,
            InverseModelSpec::Pi { .. } => {}
        }
    }

    /// `pi` or `bw`, as in the controller kinds `ff-pi` and `ff-bw`.
    pub fn short(&self) -> &'static str {
        match self {
            InverseModelSpec::Pi { .. } => "pi",
            InverseModelSpec::BoucWen { .. } => "bw",
        }
    }
}

/// How the inverted model is identified: the excitation, its length and the twin it is
/// recorded on (the IMC's [`super::model::ModelFitConfig`] defaults), and the model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InverseFitConfig {
    pub signal: String,
    pub duration: f64,
    pub twin: String,
    pub model: InverseModelSpec,
}

impl InverseFitConfig {
    /// The IMC's identification experiment with `model`.
    pub fn new(model: InverseModelSpec) -> Self {
        let imc = super::model::ModelFitConfig::default();
        InverseFitConfig {
            signal: imc.signal,
            duration: imc.duration,
            twin: imc.twin,
            model,
        }
    }

    /// The identification recording (the same experiment as the IMC's).
    fn recording(&self, noise_seed: u64) -> Result<Recording> {
        super::model::ModelFitConfig {
            signal: self.signal.clone(),
            duration: self.duration,
            twin: self.twin.clone(),
            ..super::model::ModelFitConfig::default()
        }
        .recording(noise_seed)
    }

    /// Fits the model and builds its inverse, every random number from `seed` (stream 0
    /// drives the optimizer; the recording's noise seed is drawn from stream 1, as for the
    /// IMC's internal model).
    pub fn fit(&self, seed: &TrialSeed) -> Result<FittedInverse> {
        use rand::RngExt;
        let noise_seed: u64 = seed.rng(1).random();
        let rec = self.recording(noise_seed)?;
        match &self.model {
            InverseModelSpec::Pi { operators } => fit_pi(&rec, *operators),
            InverseModelSpec::BoucWen { budget } => fit_bouc_wen(&rec, *budget, seed),
        }
    }
}

/// A fitted model ready to invert, with how well it reproduces its identification record.
#[derive(Debug, Clone)]
pub struct FittedInverse {
    pub model: InverseModel,
    /// Free-run RMSE (mm) of the model on its identification record.
    pub free_run_rmse: f64,
    /// Objective evaluations of the fit (0 for a closed-form fit).
    pub evaluations: u64,
    /// The model's parameters by name, physical units where they have them.
    pub params: Vec<(String, f64)>,
}

/// The model a feedforward inverts.
#[derive(Debug, Clone)]
pub enum InverseModel {
    /// The fitted model and its analytic inverse.
    Pi {
        model: PiModel,
        inverse: PiModel,
    },
    BoucWen(BoucWenModel),
}

impl InverseModel {
    /// What was fitted and how, for reports.
    pub fn describe(&self, evaluations: u64) -> String {
        match self {
            InverseModel::Pi { model, .. } => format!(
                "plain Prandtl-Ishlinskii ({} operators) at its least-squares optimum, inverted analytically",
                model.thresholds.len()
            ),
            InverseModel::BoucWen(_) => {
                format!("Bouc-Wen by CMA-ES ({evaluations} evaluations), inverted numerically")
            }
        }
    }
}

/// A Bouc-Wen model in the fit's normalised units with the scales back to volts and mm.
#[derive(Debug, Clone, PartialEq)]
pub struct BoucWenModel {
    pub params: BoucWenParams,
    /// Physical = normalised × scale.
    pub u_scale: f64,
    pub y_scale: f64,
}

impl BoucWenModel {
    /// The free run (mm) from rest at `u[0]`, one sample per command (V).
    pub fn simulate(&self, u: &[f64]) -> Vec<f64> {
        let k = BoucWenKernel::new(&self.params);
        let mut st = BoucWenState::new(u.first().copied().unwrap_or(0.0) / self.u_scale);
        u.iter()
            .map(|&x| st.step_with(&k, x / self.u_scale) * self.y_scale)
            .collect()
    }
}

/// Default play operators of `ff-pi` (the linear term included).
pub const DEFAULT_PI_OPERATORS: usize = 10;

/// The sample interval of the identification records and the loop (s).
const DT: f64 = super::run::DT;

/// Plain PI at its least-squares optimum on the record, and its analytic inverse. The
/// optimum can leave the linear weight at 0 (no inverse): that is refused with the cure.
fn fit_pi(rec: &Recording, operators: usize) -> Result<FittedInverse> {
    let thresholds = PiModel::uniform_thresholds(operators, &rec.u);
    let model = PiModel::fit(PiForm::Plain, thresholds, &rec.u, &rec.y, DT)
        .map_err(|e| Error::Input(format!("inverse model: PI fit: {e}")))?;
    let inverse = model.inverse().map_err(|e| {
        Error::Input(format!(
            "inverse model: the fitted PI model ({operators} operators) has no inverse: {e}; \
             try another `operators` count or identification signal"
        ))
    })?;
    let free = model.simulate(&rec.u, DT);
    let mut params = vec![("offset [mm]".to_string(), model.offset)];
    for (i, (r, w)) in model.thresholds.iter().zip(&model.weights).enumerate() {
        params.push((format!("r_{i} [V]"), *r));
        params.push((format!("w_{i} [mm/V]"), *w));
    }
    Ok(FittedInverse {
        free_run_rmse: rms_diff(&rec.y, &free),
        evaluations: 0,
        params,
        model: InverseModel::Pi { model, inverse },
    })
}

/// Bouc-Wen with an offset on the normalised record, by CMA-ES through the harness.
fn fit_bouc_wen(rec: &Recording, budget: u64, seed: &TrialSeed) -> Result<FittedInverse> {
    let (lo, hi) = BW_BOUNDS;
    let fit = Arc::new(BoucWenFit::new(
        std::slice::from_ref(rec),
        &[],
        true,
        true,
        lo,
        hi,
    )?);
    let objective: Arc<dyn Objective> = fit.clone();
    let record: TrialRecord = run_trial(TrialSpec {
        objective_id: "inverse-model",
        optimizer_id: "CMA-ES",
        trial: 0,
        objective,
        optimizer: &CmaesConfig::default(),
        budget,
        stop_value: None,
        stall: None,
        seed: *seed,
    });
    let p = &record.best_x;
    let scales = FitData::new(rec, true)?;
    let model = BoucWenModel {
        params: BoucWenParams {
            d_e: p[0],
            alpha: p[1],
            beta: p[2],
            gamma: p[3],
            n: p[4],
            d0: p[5],
        },
        u_scale: scales.u_scale,
        y_scale: scales.y_scale,
    };
    // Our free run must be the fit's (integrated as we do, with the exact kernel): a change
    // of the fit's parameter layout or scaling is caught here rather than silently
    // inverting another model.
    let free = model.simulate(&rec.u);
    let exact = BoucWenFit::new(std::slice::from_ref(rec), &[], true, true, lo, hi)?
        .with_scheme(BoucWenScheme::Accurate);
    let fits_own = exact
        .outputs(p, 0)
        .first()
        .map(|(_, y)| y.clone())
        .unwrap_or_default();
    let worst = free
        .iter()
        .zip(&fits_own)
        .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
    if fits_own.len() != free.len() || worst.is_nan() || worst > 1e-9 * model.y_scale {
        return Err(Error::Input(format!(
            "inverse model: the Bouc-Wen fit's layout or scaling changed (outputs differ by \
             {worst:.3e} mm); control::feedforward must follow objective::hysteresis"
        )));
    }
    Ok(FittedInverse {
        free_run_rmse: rms_diff(&rec.y, &free),
        evaluations: record.evaluations,
        params: fit.named_params(p),
        model: InverseModel::BoucWen(model),
    })
}

/// The numerical inverse of a Bouc-Wen model, one sample at a time: the command whose next
/// model output equals the target, then the model's state stepped with that command.
///
/// Each sample solves `f(u) = target` with `f(u) = d_e u + d0 - h(u)`, `h(u)` the state
/// advanced from the last command to `u`. `f` is continuous but need not be monotone: a
/// fitted `α` above `d_e` makes the output fall while `h` catches up, so `f` can have several
/// roots or a zero slope, where Newton's method jumps branches or divides by zero. A bracket
/// (a sign change of a continuous function) always holds a root; it is searched outward
/// from the last command with doubling steps, so the root nearest the last command is taken
/// and the command stays continuous; bisection then shrinks it to rounding. A target no
/// command within the rails reaches gets the command that comes closest.
#[derive(Debug, Clone)]
pub struct BoucWenInverse {
    kernel: BoucWenKernel,
    u_scale: f64,
    y_scale: f64,
    state: BoucWenState,
    /// Command range (normalised).
    lo: f64,
    hi: f64,
}

/// Smallest outward step of the bracket search (normalised command, about 5 µV).
const FIRST_STEP: f64 = 1e-6;
/// Bisection stops below this bracket width (normalised).
const ROOT_TOL: f64 = 1e-15;

impl BoucWenInverse {
    /// The inverse of `model`, commands limited to `±u_limit` V, at rest at command 0.
    pub fn new(model: &BoucWenModel, u_limit: f64) -> Self {
        BoucWenInverse {
            kernel: BoucWenKernel::new(&model.params),
            u_scale: model.u_scale,
            y_scale: model.y_scale,
            state: BoucWenState::new(0.0),
            lo: -u_limit / model.u_scale,
            hi: u_limit / model.u_scale,
        }
    }

    /// The model saw the command `u0` (V) from rest, as the plant did.
    pub fn start(&mut self, u0: f64) {
        self.state = BoucWenState::new(u0 / self.u_scale);
    }

    /// Model output (normalised) if the command moved to `u` now.
    fn output(&self, u: f64) -> f64 {
        let h = self.kernel.advance(self.state.h, u - self.state.u_prev);
        self.kernel.output(u, h)
    }

    /// The command (V) whose model output is `target` (mm); steps the model with it.
    pub fn command(&mut self, target: f64) -> f64 {
        let t = target / self.y_scale;
        let g = |u: f64| self.output(u) - t;
        let u0 = self.state.u_prev.clamp(self.lo, self.hi);
        let g0 = g(u0);
        let mut best = (g0.abs(), u0);
        let mut bracket = (g0 == 0.0).then_some((u0, u0));
        // Outward on both sides at once (last point, its g, direction, limit); the first
        // sign change found is the root nearest the last command.
        let mut sides = [(u0, g0, 1.0, self.hi), (u0, g0, -1.0, self.lo)];
        let mut step = FIRST_STEP;
        while bracket.is_none() && sides.iter().any(|s| s.0 != s.3) {
            for s in sides.iter_mut().filter(|s| s.0 != s.3) {
                let u = (u0 + s.2 * step).clamp(self.lo, self.hi);
                let gu = g(u);
                if gu.abs() < best.0 {
                    best = (gu.abs(), u);
                }
                if gu == 0.0 || gu.signum() != s.1.signum() {
                    bracket = Some((s.0.min(u), s.0.max(u)));
                    break;
                }
                (s.0, s.1) = (u, gu);
            }
            step *= 2.0;
        }
        let u = match bracket {
            Some((mut a, mut b)) => {
                let mut ga = g(a);
                while b - a > ROOT_TOL * (1.0 + a.abs().max(b.abs())) {
                    let m = 0.5 * (a + b);
                    let gm = g(m);
                    if gm == 0.0 {
                        (a, b) = (m, m);
                    } else if gm.signum() == ga.signum() {
                        (a, ga) = (m, gm);
                    } else {
                        b = m;
                    }
                }
                // The end nearer the target.
                if g(a).abs() <= g(b).abs() { a } else { b }
            }
            None => best.1,
        };
        self.state.step_with(&self.kernel, u);
        u * self.u_scale
    }
}

/// The feedforward controller: the model's inverse at the next reference sample, plus an
/// incremental PID on the error when one is given.
#[derive(Debug, Clone)]
pub struct Feedforward {
    inverse: InverseRunner,
    pid: Option<IncrementalPid>,
}

// One per loop, already boxed in `Controller::Feedforward`: its size costs nothing.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone)]
enum InverseRunner {
    /// The forward model only tells the inverse where the plant started.
    Pi {
        forward: PiStepper,
        inverse: PiStepper,
    },
    BoucWen(BoucWenInverse),
}

impl Feedforward {
    /// The inverse of `model` (commands within `±u_limit` V where the inverse is numerical),
    /// with the incremental PID `pid` (at rest, command 0) added when given.
    pub fn new(model: &InverseModel, pid: Option<PidGains>, u_limit: f64) -> Self {
        let inverse = match model {
            InverseModel::Pi { model, inverse } => InverseRunner::Pi {
                forward: model.stepper(DT),
                inverse: inverse.stepper(DT),
            },
            InverseModel::BoucWen(m) => InverseRunner::BoucWen(BoucWenInverse::new(m, u_limit)),
        };
        Feedforward {
            inverse,
            pid: pid.map(|g| IncrementalPid::new(g, 0.0)),
        }
    }

    /// The model saw the command applied before the loop starts.
    pub fn start(&mut self, u0: f64) {
        match &mut self.inverse {
            // Γ⁻¹[Γ[u0]] = u0: the inverse's operators now hold the plant's state.
            InverseRunner::Pi { forward, inverse } => {
                inverse.step(forward.step(u0));
            }
            InverseRunner::BoucWen(b) => b.start(u0),
        }
    }

    /// `u(k)` from the next reference sample `y_d(k+1)` and the error `e(k)`.
    pub fn command(&mut self, yd_next: f64, e: f64) -> f64 {
        let ff = match &mut self.inverse {
            InverseRunner::Pi { inverse, .. } => inverse.step(yd_next),
            InverseRunner::BoucWen(b) => b.command(yd_next),
        };
        ff + self.pid.as_mut().map_or(0.0, |p| p.step(e))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::control::closed_loop::{Controller, Guard, run_loop};
    use crate::control::plant::Plant;
    use crate::control::reference::Reference;
    use crate::control::run::{ControllerSpec, RunSpec};
    use crate::physics::twin::TwinConfig;

    /// The twin reduced to its Bouc-Wen hysteresis on the command scale, noise-free.
    const BW_TWIN: &str = "amp=off,saturation=off,mode=off,noise=off,quantization=off";

    fn sweep() -> Vec<f64> {
        Reference::sweep(2.0).sample(DT)
    }

    /// The feedforward alone on the 1 -> 2 Hz sweep.
    fn track(plant: &mut dyn Plant, model: &InverseModel) -> crate::control::LoopRun {
        let ff = Feedforward::new(model, None, 10.0);
        let mut c = Controller::Feedforward(Box::new(ff));
        run_loop(plant, &mut c, &sweep(), DT, &Guard::default())
    }

    /// Largest |e| after the first sample (the first reading precedes every command).
    fn worst(run: &crate::control::LoopRun) -> f64 {
        run.error()[1..].iter().fold(0.0f64, |m, e| m.max(e.abs()))
    }

    fn fitted(model: InverseModelSpec, twin: &str, seed: u64) -> FittedInverse {
        InverseFitConfig {
            twin: twin.into(),
            ..InverseFitConfig::new(model)
        }
        .fit(&TrialSeed::from_u64(seed))
        .unwrap()
    }

    #[test]
    fn the_pi_inverse_on_its_own_model_as_plant_tracks_to_rounding() {
        // Fitted on the default twin's record, then that very model is the plant.
        let f = fitted(InverseModelSpec::Pi { operators: 10 }, "", 3);
        let InverseModel::Pi { model, .. } = &f.model else {
            panic!("a PI fit")
        };
        assert!(model.weights.iter().filter(|w| **w > 0.0).count() > 2);
        let mut plant = model.stepper(DT);
        let run = track(&mut plant, &f.model);
        assert!(run.failure.is_none());
        // Measured 3.3e-16 mm (0.05-0.55 mm reference).
        assert!(worst(&run) < 1e-13, "{}", worst(&run));
    }

    /// A Bouc-Wen model stepped as a plant (from rest at 0 V).
    struct BwPlant(BoucWenModel, BoucWenState);

    impl Plant for BwPlant {
        fn step(&mut self, u: f64) -> f64 {
            let k = BoucWenKernel::new(&self.0.params);
            self.1.step_with(&k, u / self.0.u_scale) * self.0.y_scale
        }
    }

    #[test]
    fn the_bouc_wen_inverse_tracks_its_own_model_to_rounding_and_the_twin_closely() {
        // The twin's own hysteresis on the command scale, inverted exactly: the root find's
        // tolerance is all that is left.
        let cfg = TwinConfig::default();
        let exact = BoucWenModel {
            params: cfg.command_scale_bouc_wen(),
            u_scale: 1.0,
            y_scale: 1.0,
        };
        let mut plant = BwPlant(exact.clone(), BoucWenState::new(0.0));
        let model = InverseModel::BoucWen(exact);
        let run = track(&mut plant, &model);
        // Measured 3.3e-16 mm.
        assert!(worst(&run) < 1e-12, "{}", worst(&run));

        // Fitted by CMA-ES on a record of the hysteresis-only twin, run on that twin.
        let f = fitted(InverseModelSpec::BoucWen { budget: 6000 }, BW_TWIN, 1);
        let mut twin =
            crate::physics::twin::Twin::try_new(&TwinConfig::parse_overrides(BW_TWIN).unwrap(), 1)
                .unwrap();
        let run = track(&mut twin, &f.model);
        // Measured: fit 2.1e-5 mm free-run RMSE, tracking 2.6e-5 mm RMSE, 7.6e-5 max.
        // Measured: the fit recovers the twin's parameters (1.1e-6 mm free-run RMSE); the
        // loop tracks within 2.8e-6 mm, a tenth of the sensor's 20 nm resolution.
        assert!(f.free_run_rmse < 2e-5, "{}", f.free_run_rmse);
        assert!(worst(&run) < 2e-5, "{}", worst(&run));
    }

    /// A Bouc-Wen model whose output falls while `h` catches up (`α > d_e`): the inverse
    /// still finds a command whose output is the target wherever one exists.
    #[test]
    fn the_bracketed_inverse_holds_where_the_model_is_not_monotone() {
        let m = BoucWenModel {
            params: BoucWenParams {
                d_e: 0.5,
                alpha: 2.0,
                beta: 1.0,
                gamma: 1.0,
                n: 1.0,
                d0: 0.0,
            },
            u_scale: 1.0,
            y_scale: 1.0,
        };
        let mut inv = BoucWenInverse::new(&m, 10.0);
        inv.start(0.0);
        let mut probe = BoucWenInverse::new(&m, 10.0);
        probe.start(0.0);
        for k in 0..400 {
            let target = 0.8 * (k as f64 * 0.05).sin();
            let before = inv.state;
            let u = inv.command(target);
            probe.state = before;
            assert!((probe.output(u) - target).abs() < 1e-12, "k = {k}: u = {u}");
        }
    }

    #[test]
    fn integral_feedback_removes_what_the_feedforward_misses_under_mismatch() {
        // Identified without the mode and creep, run with both: creep is left to the PID.
        let run = |kind: &str, dur: f64| {
            RunSpec {
                controller: ControllerSpec::parse(kind, &[]).unwrap(),
                reference: Reference::parse("sweep-1-4hz", Some(dur)).unwrap(),
                plant: "creep=on".into(),
                model_twin: Some("mode=off".into()),
                guard: Guard::default(),
                transient: 0.5,
            }
            .fit_and_execute(&TrialSeed::from_u64(4), 11)
            .unwrap()
            .metrics
        };
        let steady = |kind: &str| run(kind, 2.0).rmse_steady_mm.unwrap();
        let (ff, both) = (steady("ff-pi"), steady("ff-pi+pid"));
        // Measured after 0.5 s: 0.0055 mm alone, 0.00092 with the PID (a sixth).
        assert!(both < 0.4 * ff, "ff {ff}, ff+pid {both}");
    }

    #[test]
    fn bad_parameters_say_what_is_valid() {
        let err = |kind: &str, k: &str, v: &str| {
            ControllerSpec::parse(kind, &[(k.into(), v.into())])
                .unwrap_err()
                .to_string()
        };
        let m = err("ff-pi", "operators", "0");
        assert!(
            m.contains("`operators` = `0`") && m.contains("[1, 4000]"),
            "{m}"
        );
        let m = err("ff-bw", "kp", "1");
        assert!(
            m.contains("unknown parameter `kp`")
                && m.contains("model_budget, model_signal, model_duration")
                && !m.contains("kd"),
            "{m}"
        );
        let m = err("ff-pi+pid", "model_budget", "5");
        assert!(m.contains("operators") && m.contains("kp, ki, kd"), "{m}");
        let m = err("ff-bw+pid", "model_duration", "-1");
        assert!(m.contains("must be > 0"), "{m}");
        // Every listed key is accepted, every other one refused.
        use crate::control::run::{FF_BW_KEYS, FF_PI_KEYS, PID_KEYS};
        let ident: &[(&str, &str)] = &[("model_signal", ""), ("model_duration", "")];
        let all = [FF_PI_KEYS, FF_BW_KEYS, PID_KEYS, ident].concat();
        for (kind, own) in [("ff-pi", FF_PI_KEYS), ("ff-bw", FF_BW_KEYS)] {
            for pid in [false, true] {
                let kind = format!("{kind}{}", if pid { "+pid" } else { "" });
                let pid_keys = if pid { PID_KEYS } else { &[] };
                let listed = [own, ident, pid_keys].concat();
                for (k, _) in &all {
                    let v = if *k == "model_signal" {
                        "sine:freq=1,amp=2,offset=2"
                    } else {
                        "2"
                    };
                    let ok = ControllerSpec::parse(&kind, &[(k.to_string(), v.into())]).is_ok();
                    assert_eq!(ok, listed.iter().any(|x| x.0 == *k), "{kind}: {k}");
                }
            }
        }
        let ControllerSpec::Feedforward(f) =
            ControllerSpec::parse("ff-bw+pid", &[("ki".into(), "0.2".into())]).unwrap()
        else {
            panic!("a feedforward")
        };
        assert_eq!(
            (f.pid.map(|g| (g.kp, g.ki)), &f.fit.model),
            (
                Some((0.0, 0.2)),
                &InverseModelSpec::BoucWen {
                    budget: DEFAULT_BW_BUDGET
                }
            )
        );
    }
}

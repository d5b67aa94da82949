//! `optbench control`: one closed-loop compensation run on the twin.

use crate::base::error::Result;
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct ControlArgs {
    /// Controller: imc-rbf (the dissertation's IMC with two RBF networks), pid (eq. 4.9), or
    /// feedforward by an inverted hysteresis model identified on the --model-twin:
    /// ff-pi (Prandtl-Ishlinskii, analytic inverse), ff-bw (Bouc-Wen, numerical inverse),
    /// alone or plus an integral-action PID on the error (ff-pi+pid, ff-bw+pid).
    #[arg(long, value_parser = crate::control::run::CONTROLLER_KINDS)]
    pub controller: String,
    /// Reference in mm: sweep-1-2hz, sweep-1-3hz, sweep-1-4hz, sweep-1-10hz (the dissertation's),
    /// or a signal spec such as "sine:freq=5,amp=0.2,offset=0.3" (with --duration).
    #[arg(long)]
    pub reference: String,
    /// Seconds of the reference (default: its own, 5 s for the sweeps).
    #[arg(long)]
    pub duration: Option<f64>,
    /// Twin overrides of the plant, e.g. "creep=on,mode.zeta=0.02".
    #[arg(long, default_value = "")]
    pub plant: String,
    /// Twin overrides the internal or inverted model is identified on (default: the plant's); e.g.
    /// --model-twin "mode=off" --plant "creep=on" for a model/plant mismatch.
    #[arg(long)]
    pub model_twin: Option<String>,
    /// Controller parameter, repeatable: --controller-param ki=0.4 --controller-param learning_rate=0.05
    /// (pid: kp, ki, kd; imc-rbf: learning_rate, momentum, error_scale, sensitivity,
    /// model_mode, model_budget, ...; ff-pi: operators, ff-bw: model_budget, both
    /// model_signal, model_duration, and with +pid kp, ki, kd (default 0, 0.1, 0); a wrong
    /// key lists the valid ones).
    #[arg(long = "controller-param", alias = "param", value_name = "KEY=VALUE")]
    pub params: Vec<String>,
    /// Seconds at the start counted as the transient (figures and the steady RMSE).
    #[arg(long, default_value_t = 1.0)]
    pub transient: f64,
    /// Seed of the model fit and the sensor noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output folder (default: results/control-CONTROLLER).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

pub fn run(a: ControlArgs) -> Result<()> {
    let out = a
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from("results").join(format!("control-{}", a.controller)));
    print!(
        "{}",
        crate::control::single::run(&crate::control::single::ControlRequest {
            controller: a.controller,
            params: a.params,
            reference: a.reference,
            duration: a.duration,
            plant: a.plant,
            model_twin: a.model_twin,
            transient: a.transient,
            seed: a.seed,
            out,
        })?
    );
    Ok(())
}

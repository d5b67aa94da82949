//! Parameter tables of the strong baselines (differential evolution, SHADE, CMA-ES,
//! L-BFGS), kept apart from the dissertation's optimizers in `registry/mod.rs`.

use super::OptimizerKind;
use crate::base::error::Error;
use crate::base::limits::MAX_POPULATION;
use crate::base::params::{Default as D, Kind, Params, Spec, probability};
use crate::harness::OptimizerConfig;
use crate::optimizer::cmaes::CmaesConfig;
use crate::optimizer::de::{DeConfig, ShadeConfig};
use crate::optimizer::lbfgs::{GradientSource, LbfgsConfig};
use std::sync::Arc;

const DE_POPULATION: Spec = Spec {
    name: "population",
    kind: Kind::Int {
        min: 4,
        max: MAX_POPULATION as i64,
    },
    default: D::Int(100),
    help: "individuals (at least 4: a mutant needs three others)",
};

const DE_PARAMS: &[Spec] = &[
    DE_POPULATION,
    Spec {
        name: "f",
        kind: Kind::Float { min: 0.0, max: 2.0 },
        default: D::Float(0.5),
        help: "differential weight F of v = x_r1 + F (x_r2 - x_r3)",
    },
    probability("cr", 0.9, "binomial crossover rate CR"),
];

fn build_de(p: &Params) -> Result<Arc<dyn OptimizerConfig>, Error> {
    Ok(Arc::new(DeConfig {
        population: p.usize("population"),
        f: p.float("f"),
        cr: p.float("cr"),
    }))
}

const SHADE_PARAMS: &[Spec] = &[
    DE_POPULATION,
    Spec {
        name: "memory",
        kind: Kind::Int {
            min: 1,
            max: MAX_POPULATION as i64,
        },
        default: D::Int(100),
        help: "success-history entries H of (CR, F) means (paper: H = population)",
    },
    Spec {
        name: "p_max",
        kind: Kind::Float {
            min: f64::MIN_POSITIVE,
            max: 1.0,
        },
        default: D::Float(0.2),
        help: "largest share p of current-to-pbest/1; p is drawn in [2/population, p_max]",
    },
    Spec {
        name: "archive",
        kind: Kind::Float {
            min: 0.0,
            max: 10.0,
        },
        default: D::Float(1.0),
        help: "archive of replaced parents, as a multiple of the population",
    },
];

fn build_shade(p: &Params) -> Result<Arc<dyn OptimizerConfig>, Error> {
    let cfg = ShadeConfig {
        population: p.usize("population"),
        memory: p.usize("memory"),
        p_max: p.float("p_max"),
        archive: p.float("archive"),
    };
    // The archive's points count as one more population (see `MAX_POPULATION`).
    if cfg.archive * cfg.population as f64 > MAX_POPULATION as f64 {
        return Err(p.error(
            "archive",
            format!(
                "{} x population {} is above {MAX_POPULATION} archived points (a limit derived from memory)",
                cfg.archive, cfg.population
            ),
        ));
    }
    if cfg.p_max * (cfg.population as f64) < 2.0 {
        return Err(p.error(
            "p_max",
            format!(
                "{} x population {} is below 2: current-to-pbest needs p_max >= 2/population",
                cfg.p_max, cfg.population
            ),
        ));
    }
    Ok(Arc::new(cfg))
}

const CMAES_PARAMS: &[Spec] = &[
    Spec {
        name: "lambda",
        kind: Kind::Int {
            min: 2,
            max: MAX_POPULATION as i64,
        },
        default: D::Derived("4 + floor(3 ln dim)"),
        help: "offspring per generation of the first run",
    },
    Spec {
        name: "sigma",
        kind: Kind::Float {
            min: f64::MIN_POSITIVE,
            max: 1.0,
        },
        default: D::Float(0.3),
        help: "initial step size as a fraction of each interval's width",
    },
    Spec {
        name: "ipop",
        kind: Kind::Bool,
        default: D::Bool(true),
        help: "double lambda at every restart (IPOP-CMA-ES); false: restart with the same lambda",
    },
];

fn build_cmaes(p: &Params) -> Result<Arc<dyn OptimizerConfig>, Error> {
    Ok(Arc::new(CmaesConfig {
        lambda: p.opt_int("lambda").map(|l| l as usize),
        sigma: p.float("sigma"),
        ipop: p.bool("ipop"),
    }))
}

/// Also the parameters of `polish_with = "lbfgs"`'s defaults.
const LBFGS_PARAMS: &[Spec] = &[
    Spec {
        name: "memory",
        kind: Kind::Int { min: 1, max: 1000 },
        default: D::Int(10),
        help: "(s, y) pairs of the inverse-Hessian model",
    },
    Spec {
        name: "gradient",
        kind: Kind::Choice(&["finite-difference", "analytic"]),
        default: D::Str("finite-difference"),
        help: "forward differences (dim evaluations per gradient) or the objective's own gradient (charged the same: 1 + dim evaluations with its value; fitting objectives with one)",
    },
];

fn build_lbfgs(p: &Params) -> Result<Arc<dyn OptimizerConfig>, Error> {
    Ok(Arc::new(LbfgsConfig {
        memory: p.usize("memory"),
        gradient: match p.str("gradient") {
            "analytic" => GradientSource::Analytic,
            _ => GradientSource::FiniteDifference,
        },
    }))
}

/// The baseline optimizer kinds.
pub fn kinds() -> Vec<OptimizerKind> {
    vec![
        OptimizerKind {
            name: "de",
            help: "differential evolution DE/rand/1/bin (Storn and Price 1997)",
            params: DE_PARAMS,
            build: build_de,
        },
        OptimizerKind {
            name: "shade",
            help: "SHADE: success-history adaptive DE, current-to-pbest/1 with archive (Tanabe and Fukunaga 2013)",
            params: SHADE_PARAMS,
            build: build_shade,
        },
        OptimizerKind {
            name: "cmaes",
            help: "CMA-ES (Hansen 2016 defaults) with IPOP restarts; reflection into the box",
            params: CMAES_PARAMS,
            build: build_cmaes,
        },
        OptimizerKind {
            name: "lbfgs",
            help: "projected L-BFGS with Armijo backtracking, random restarts on convergence; also the polish of `polish_with = \"lbfgs\"`",
            params: LBFGS_PARAMS,
            build: build_lbfgs,
        },
    ]
}

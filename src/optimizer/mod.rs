//! Optimizers. An optimizer transforms its own state one iteration at a time and spends
//! evaluations only through the [`crate::harness::Evaluator`] it is handed, under the
//! contract of [`crate::harness::contract`]; the harness owns the loop, the budget, the
//! trace and the random streams. Optimizers know nothing of files or suites.

pub mod cmaes;
pub mod de;
pub mod ga;
pub mod gradient;
pub mod lbfgs;
pub mod levenberg_marquardt;
pub mod msga;
pub mod nelder_mead;
pub mod operators;
pub mod pso;
pub mod random_search;

/// `Σ aᵢ bᵢ`, in order (the local searches' inner products).
pub(crate) fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// The local search named by a suite's `polish_with` (None: Nelder-Mead).
pub fn polish_method(name: Option<&str>) -> Result<nelder_mead::LocalSearch, String> {
    match name {
        None | Some("nelder-mead") => Ok(nelder_mead::LocalSearch::default()),
        Some("lbfgs") => Ok(nelder_mead::LocalSearch::Lbfgs(
            lbfgs::LbfgsConfig::default(),
        )),
        Some(other) => Err(format!(
            "`polish_with` = \"{other}\": expected \"nelder-mead\" or \"lbfgs\""
        )),
    }
}

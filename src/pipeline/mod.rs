//! The benchmark pipeline, stage by stage: a [`suite`] (TOML, validated) gives the plan of
//! trials; the [`runner`] runs them (one trial loop for every optimizer); the [`store`] keeps
//! traces, summary and provenance; [`run`] ties them into one run (resumable, or one shard of
//! it); [`scale`] merges shards (and runs of different optimizers) and spreads a run over
//! MPI ranks; [`external`] runs a suite's plan for an optimizer outside optbench (the Python
//! package's), writing the folder `run` would. Beside the suite pipeline,
//! the one-trial jobs of `optbench fit` ([`single_fit`]) and `optbench simulate`
//! ([`simulate`]).

pub mod external;
pub mod run;
pub mod runner;
pub mod scale;
pub mod simulate;
pub mod single_fit;
pub mod store;
pub mod suite;

//! The result store: one folder per run with the suite as run, provenance, every trial's
//! trace, and the summary. Every file is written to a temporary name and renamed, so a
//! reader never sees half a file.
//!
//! ```text
//! results/<suite>/
//!   suite.toml        the suite file exactly as read
//!   provenance.json   tool version, git commit, seed, threads, start/end time, command
//!   traces.jsonl      one TrialRecord per line, in plan order
//!   summary.json      per objective x optimizer: finals and their statistics
//!   progress.jsonl    every finished trial, appended as it ends (resume, shards, merge)
//!   .optbench.lock    held by the one `run`, `report` or `merge` writing the folder
//! ```
//!
//! [`output`] knows which files are optbench's: a run refuses a folder holding anything
//! else than results of the same suite, and never leaves another run's files beside its own.

pub mod folder;
pub mod lock;
pub mod output;
pub mod progress;
pub mod summary;

pub use folder::{Provenance, read_traces, write_run};
pub use lock::{FolderLock, lock_folder};
pub use output::{FreshFolder, claim, lock_and_claim};
pub use summary::{CellSummary, Summary, read_summary, summarize};

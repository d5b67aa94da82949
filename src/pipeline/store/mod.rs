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

pub mod folder;
pub mod lock;
pub mod progress;
pub mod summary;

pub use folder::{Provenance, read_traces, write_run};
pub use lock::{FolderLock, lock_folder};
pub use summary::{CellSummary, Summary, summarize};

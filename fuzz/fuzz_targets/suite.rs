//! A benchmark suite's TOML: `Suite::parse` must return `Ok` or `Err`, never panic. The
//! suite's folder does not exist, so relative recordings are never read.
#![no_main]

use libfuzzer_sys::fuzz_target;
use optbench::pipeline::suite::Suite;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let _ = Suite::parse(&text, Path::new("/nonexistent-optbench-fuzz/suite.toml"));
});

//! A control suite's TOML: `ControlSuite::parse` must return `Ok` or `Err`, never panic.
#![no_main]

use libfuzzer_sys::fuzz_target;
use optbench::control::suite::ControlSuite;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let _ = ControlSuite::parse(&text, Path::new("/nonexistent-optbench-fuzz/control.toml"));
});

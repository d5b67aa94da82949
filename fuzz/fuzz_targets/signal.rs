//! A signal spec: `Signal::parse` returns `Ok` or `Err`; what parses is evaluated, and its
//! printed form parses again.
#![no_main]

use libfuzzer_sys::fuzz_target;
use optbench::data::signal::Signal;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    if let Ok(s) = Signal::parse(&text) {
        for t in [0.0, 0.5, 1e3] {
            let _ = s.value(t);
        }
        let printed = s.to_string();
        if let Err(e) = Signal::parse(&printed) {
            panic!("'{text}' parses, its printed form '{printed}' does not: {e}");
        }
    }
});

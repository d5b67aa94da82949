//! A recording CSV: the first byte picks the columns, delimiter and resampling, the rest is
//! the file, written to a temp file and read with `Recording::read_csv_noted`.
#![no_main]

use libfuzzer_sys::fuzz_target;
use optbench::data::recording::{Columns, Delimiter, ReadOptions, Recording};
use std::path::PathBuf;
use std::sync::OnceLock;

const COLUMNS: [&str; 4] = ["t,u,y", "t_s,u_V,y_mm", "time,in,out", "t,u,u2"];
const DELIMITERS: [&str; 5] = ["auto", ",", ";", "tab", "whitespace"];

fn path() -> &'static PathBuf {
    static PATH: OnceLock<PathBuf> = OnceLock::new();
    PATH.get_or_init(|| {
        std::env::temp_dir().join(format!("optbench-fuzz-{}.csv", std::process::id()))
    })
}

fuzz_target!(|data: &[u8]| {
    let Some((&pick, file)) = data.split_first() else {
        return;
    };
    let columns = Columns::parse(COLUMNS[usize::from(pick >> 4) % COLUMNS.len()]).unwrap();
    let opts = ReadOptions {
        resample: pick & 8 != 0,
        delimiter: Delimiter::parse(DELIMITERS[usize::from(pick & 7) % DELIMITERS.len()]).unwrap(),
    };
    std::fs::write(path(), file).unwrap();
    let _ = Recording::read_csv_noted(path(), &columns, &opts);
});

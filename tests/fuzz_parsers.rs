//! A bounded, seeded fuzz test of the parsers that read user files: benchmark suites,
//! control suites, signal specs and recording CSVs (issue 17).
//!
//! Each target starts from seed inputs (the repository's `suites/*.toml`, the signal specs
//! in those suites and the signal module's docs, small CSVs written here) and mutates them
//! with a ChaCha stream: bit flips, random bytes, inserted tokens (huge numbers, `nan`,
//! `inf`, `-1e308`, deep nesting), long lines, duplicated and deleted ranges, truncation,
//! splices of two inputs. Every input must give `Ok` or `Err`: a panic is caught
//! (`catch_unwind`) and the input written to `target/fuzz-failures/` for replay; an abort
//! (stack overflow, an allocation over [`ALLOC_LIMIT`]) kills the process, and the input
//! that did it is the `<target>.last` file left in that folder.
//!
//! Default run (`cargo test --release`): a fixed number of mutants of seed 1 per target
//! (`Target::inputs`, a few seconds in all), deterministic. Longer runs: `OPTBENCH_FUZZ_SECONDS=150` (per target) and
//! `OPTBENCH_FUZZ_SEED=N`; `OPTBENCH_FUZZ_REPLAY=FILE` runs one saved input through every
//! target.

use optbench::control::suite::ControlSuite;
use optbench::data::recording::{Columns, Delimiter, ReadOptions, Recording};
use optbench::data::signal::Signal;
use optbench::pipeline::suite::Suite;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::alloc::{GlobalAlloc, Layout, System};
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Largest single allocation a parser may ask for on an input of at most [`MAX_INPUT`]
/// bytes: anything above is refused (the process aborts, naming the size), as a parser
/// must refuse an absurd size before allocating it.
const ALLOC_LIMIT: usize = 1 << 30;

struct Capped;

unsafe impl GlobalAlloc for Capped {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if layout.size() > ALLOC_LIMIT {
            return std::ptr::null_mut();
        }
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        if layout.size() > ALLOC_LIMIT {
            return std::ptr::null_mut();
        }
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if new_size > ALLOC_LIMIT {
            return std::ptr::null_mut();
        }
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Capped = Capped;

/// Longest mutated input, in bytes.
const MAX_INPUT: usize = 1 << 20;

/// Tokens inserted by the mutator: numbers at and beyond the edges of every type, words
/// the parsers give meaning to, structure.
const TOKENS: &[&str] = &[
    "nan",
    "NaN",
    "inf",
    "-inf",
    "+inf",
    "-1e308",
    "1e308",
    "1e309",
    "-1e999",
    "1e-320",
    "5e-324",
    "0",
    "-0",
    "-1",
    "0.0",
    "1e15",
    "1e6",
    "1e9",
    "4294967296",
    "9223372036854775807",
    "-9223372036854775808",
    "18446744073709551615",
    "18446744073709551616",
    "99999999999999999999999999999",
    "0x7fffffff",
    "1_000_000",
    "\"\"",
    "\"",
    "'",
    "[",
    "]",
    "[[",
    "]]",
    "{",
    "}",
    "=",
    ",",
    ";",
    ":",
    "*",
    "+",
    "(",
    ")",
    "\n",
    "\r\n",
    "\t",
    " ",
    "\0",
    "\u{feff}",
    "é",
    "\u{202e}",
    "[[objective]]\n",
    "[[optimizer]]\n",
    "[[table]]\n",
    "[[controller]]\n",
    "[[plant]]\n",
    "[[reference]]\n",
    "kind = ",
    "id = ",
    "dim = ",
    "population = ",
    "trials = ",
    "budget = ",
    "duration = ",
    "twin:",
    "eq318:",
    "sine:freq=1",
    "chirp:f0=1,f1=1e9,duration=1e9",
    "multisine:fmin=0,fmax=1e12,period=1e9",
    "steps:levels=",
    "am:carrier=(",
    "envelope=",
    "ramp",
    "raised-cosine",
    "../../x",
    "/tmp",
    "$OPTBENCH_DATA/",
    " | ",
    "1,",
    "1;",
    "1,5",
    "t,u,y\n",
];

/// One byte-level mutation of `data`; `other` is a second input to splice from.
fn mutate_once(rng: &mut ChaCha8Rng, data: &mut Vec<u8>, other: &[u8]) {
    let at = |rng: &mut ChaCha8Rng, len: usize| rng.random_range(0..=len);
    match rng.random_range(0..13u32) {
        0 if !data.is_empty() => {
            let i = rng.random_range(0..data.len());
            data[i] ^= 1 << rng.random_range(0..8u32);
        }
        1 if !data.is_empty() => {
            let i = rng.random_range(0..data.len());
            data[i] = rng.random();
        }
        2 | 3 => {
            let t = TOKENS[rng.random_range(0..TOKENS.len())].as_bytes();
            let i = at(rng, data.len());
            data.splice(i..i, t.iter().copied());
        }
        4 => {
            // A number replaced by an extreme one: the cheapest way into the validation.
            let starts: Vec<usize> = (0..data.len())
                .filter(|&i| data[i].is_ascii_digit() && (i == 0 || !data[i - 1].is_ascii_digit()))
                .collect();
            if !starts.is_empty() {
                let s = starts[rng.random_range(0..starts.len())];
                let e = (s..data.len())
                    .find(|&i| !(data[i].is_ascii_digit() || b".eE-+_".contains(&data[i])))
                    .unwrap_or(data.len());
                let t = TOKENS[rng.random_range(0..28)].as_bytes();
                data.splice(s..e, t.iter().copied());
            }
        }
        5 => {
            // Deep nesting.
            let n = [8, 100, 1000, 20_000][rng.random_range(0..4)];
            let (open, close): (&[u8], &[u8]) = match rng.random_range(0..4u32) {
                0 => (b"(", b")"),
                1 => (b"[", b"]"),
                2 => (b"{a=", b"}"),
                _ => (b"am:carrier=(", b")"),
            };
            let i = at(rng, data.len());
            let mut ins = open.repeat(n);
            if rng.random_bool(0.5) {
                ins.extend_from_slice(b"1");
                ins.extend(close.repeat(n));
            }
            data.splice(i..i, ins);
        }
        6 => {
            // A long line.
            let n = [100, 10_000, 200_000][rng.random_range(0..3)];
            let c = [b'9', b'a', b',', b' ', b'x'][rng.random_range(0..5)];
            let i = at(rng, data.len());
            data.splice(i..i, std::iter::repeat_n(c, n));
        }
        7 if !data.is_empty() => {
            // A line (or any range) duplicated, possibly many times.
            let s = rng.random_range(0..data.len());
            let e = data[s..]
                .iter()
                .position(|&b| b == b'\n')
                .map_or(data.len(), |p| s + p + 1);
            let piece = data[s..e].to_vec();
            let times = [1, 2, 50][rng.random_range(0..3)];
            let i = at(rng, data.len());
            data.splice(i..i, piece.repeat(times));
        }
        8 if !data.is_empty() => {
            let s = rng.random_range(0..data.len());
            let e = (s + rng.random_range(1..64)).min(data.len());
            data.drain(s..e);
        }
        9 => {
            let n = at(rng, data.len());
            data.truncate(n);
        }
        10 if !other.is_empty() => {
            // Splice: a prefix of this input and a suffix of the other.
            let a = at(rng, data.len());
            let b = rng.random_range(0..other.len());
            data.truncate(a);
            data.extend_from_slice(&other[b..]);
        }
        11 if !data.is_empty() => {
            // Swap two lines' worth of bytes (order of keys, tables, rows).
            let i = rng.random_range(0..data.len());
            let j = rng.random_range(0..data.len());
            let (i, j) = (i.min(j), i.max(j));
            let n = 32.min(j - i).min(data.len() - j);
            for k in 0..n {
                data.swap(i + k, j + k);
            }
        }
        _ => {
            let i = at(rng, data.len());
            let b: u8 = rng.random();
            data.insert(i, b);
        }
    }
}

/// A mutant of one seed: 1 to 8 mutations, cut to [`MAX_INPUT`].
fn mutant(rng: &mut ChaCha8Rng, seeds: &[Vec<u8>]) -> Vec<u8> {
    let mut data = seeds[rng.random_range(0..seeds.len())].clone();
    let other = &seeds[rng.random_range(0..seeds.len())];
    for _ in 0..rng.random_range(1..=8u32) {
        mutate_once(rng, &mut data, other);
    }
    data.truncate(MAX_INPUT);
    data
}

/// A parser under test, fed raw bytes.
type Run = fn(&[u8], &mut ChaCha8Rng, &Path);

fn run_suite(input: &[u8], _: &mut ChaCha8Rng, dir: &Path) {
    let text = String::from_utf8_lossy(input);
    let _ = Suite::parse(&text, &dir.join("suite.toml"));
}

fn run_control(input: &[u8], _: &mut ChaCha8Rng, dir: &Path) {
    let text = String::from_utf8_lossy(input);
    let _ = ControlSuite::parse(&text, &dir.join("control.toml"));
}

fn run_signal(input: &[u8], _: &mut ChaCha8Rng, _: &Path) {
    let text = String::from_utf8_lossy(input);
    if let Ok(s) = Signal::parse(&text) {
        // What parses is evaluated and printed; the printed form must parse again.
        for t in [0.0, 0.5, 1e3] {
            let _ = s.value(t);
        }
        let printed = s.to_string();
        if let Err(e) = Signal::parse(&printed) {
            panic!("'{text}' parses, its printed form '{printed}' does not: {e}");
        }
    }
}

/// Column choices and read options the CSV target draws from.
const COLUMNS: &[&str] = &["t,u,y", "t_s,u_V,y_mm", "time,in,out", "t,u,u2"];

fn run_csv(input: &[u8], rng: &mut ChaCha8Rng, dir: &Path) {
    let path = dir.join("rec.csv");
    std::fs::write(&path, input).expect("writing the temp CSV");
    let columns = Columns::parse(COLUMNS[rng.random_range(0..COLUMNS.len())]).unwrap();
    let delimiter = ["auto", ",", ";", "tab", "whitespace"][rng.random_range(0..5)];
    let opts = ReadOptions {
        resample: rng.random_bool(0.5),
        delimiter: Delimiter::parse(delimiter).unwrap(),
    };
    let _ = Recording::read_csv_noted(&path, &columns, &opts);
    let _ = Recording::read_csv(&path, &Columns::default(), &ReadOptions::default());
}

fn manifest() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn suites(control: bool) -> Vec<Vec<u8>> {
    let mut out = Vec::new();
    for entry in std::fs::read_dir(manifest().join("suites")).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "toml") {
            let text = std::fs::read(&path).unwrap();
            let is_control = String::from_utf8_lossy(&text).contains("[[controller]]");
            if is_control == control {
                out.push(text);
            }
        }
    }
    out.sort();
    assert!(!out.is_empty(), "no seed suites found");
    out
}

/// Signal specs: those the suites use (`twin:SPEC`, `eq318:SPEC`) and the grammar's examples.
fn signals() -> Vec<Vec<u8>> {
    let mut out: Vec<String> = [
        "2.5 + sine:freq=10,amp=2",
        "sine:freq=10,amp=2,offset=2.5",
        "chirp:f0=10,f1=1,duration=8,amp=2,law=log,offset=2.5",
        "multisine:fmin=5,fmax=150,rms=50,period=10.92,seed=3",
        "steps:levels=0;1;2;1,hold=0.5",
        "steps:levels=0;1,hold=0.5,repeat=true",
        "triangle:freq=1,amp=2,phase=0.5,offset=1",
        "am:carrier=(sine:freq=10),envelope=(raised-cosine:min=0.3,max=1,duration=8)",
        "am:carrier=(sine:freq=10),envelope=ramp",
        "am:carrier=(sine:freq=1),envelope=(ramp:from=0,to=1,duration=1)",
        "am:carrier=(sine:freq=1),envelope=(triangle:freq=0.1)",
        "-1*(triangle:freq=1 + 0.5)",
        "2*3*(1 + sine:freq=1)",
    ]
    .map(String::from)
    .to_vec();
    for text in suites(false).iter().chain(&suites(true)) {
        let text = String::from_utf8_lossy(text);
        for piece in text.split('"').skip(1).step_by(2) {
            for part in piece.split(" | ") {
                if let Some(spec) = part
                    .strip_prefix("twin:")
                    .or_else(|| part.strip_prefix("eq318:"))
                {
                    out.push(spec.to_string());
                }
            }
        }
    }
    out.sort();
    out.dedup();
    out.into_iter().map(String::into_bytes).collect()
}

/// Small recordings in the forms the reader accepts: written here, not copied from data.
fn csvs() -> Vec<Vec<u8>> {
    let rows = |sep: &str, dec: &str, dt: f64, n: usize, skip: Option<usize>| {
        let mut s = format!("t{sep}u{sep}y\n");
        for k in (0..n).filter(|&k| Some(k) != skip) {
            let t = k as f64 * dt;
            let u = (t * 7.0).sin();
            let y = 0.5 * u + 0.1 * (t * 3.0).cos();
            let line = format!("{t}{sep}{u:.6}{sep}{y:.6}\n");
            s.push_str(&if dec == "," {
                line.replace('.', ",")
            } else {
                line
            });
        }
        s.into_bytes()
    };
    let mut out = vec![
        rows(",", ".", 0.001, 20, None),
        rows(";", ",", 0.01, 12, None),
        rows("\t", ".", 0.5, 10, None),
        rows("   ", ".", 0.001, 10, None),
        rows(",", ".", 0.001, 16, Some(5)),
    ];
    let mut bom = b"\xEF\xBB\xBF".to_vec();
    bom.extend(rows(",", ".", 0.002, 9, None));
    out.push(bom);
    let named = String::from_utf8(rows(",", ".", 0.001, 10, None))
        .unwrap()
        .replacen("t,u,y", "t_s,u_V,y_mm,extra", 1)
        .replace('\n', ",0\n")
        .replacen("extra,0", "extra", 1);
    out.push(named.into_bytes());
    out
}

struct Target {
    /// Mutants in the default run.
    inputs: usize,
    seeds: Vec<Vec<u8>>,
    run: Run,
}

fn target(name: &str) -> Target {
    match name {
        "suite" => Target {
            inputs: 200,
            seeds: suites(false),
            run: run_suite,
        },
        "control" => Target {
            inputs: 1000,
            seeds: suites(true),
            run: run_control,
        },
        "signal" => Target {
            inputs: 3000,
            seeds: signals(),
            run: run_signal,
        },
        "csv" => Target {
            inputs: 1000,
            seeds: csvs(),
            run: run_csv,
        },
        _ => unreachable!(),
    }
}

fn failures_dir() -> PathBuf {
    let target = std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| manifest().join("target"));
    target.join("fuzz-failures")
}

fn env_u64(key: &str) -> Option<u64> {
    std::env::var(key).ok().map(|v| {
        v.trim()
            .parse()
            .unwrap_or_else(|_| panic!("{key}={v}: expected a whole number"))
    })
}

/// One input through a target; the panic message if it panicked.
fn run_one(t: &Target, input: &[u8], rng: &mut ChaCha8Rng, dir: &Path) -> Option<String> {
    catch_unwind(AssertUnwindSafe(|| (t.run)(input, rng, dir)))
        .err()
        .map(|p| {
            p.downcast_ref::<String>()
                .cloned()
                .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_else(|| "non-string panic".into())
        })
}

/// Runs target `name`: the seeds, the regression inputs, then mutants until the budget is
/// spent. Panics listing every input that panicked (each saved for replay).
fn fuzz(name: &str, regressions: &[&[u8]]) {
    let t = target(name);
    let seed = env_u64("OPTBENCH_FUZZ_SEED").unwrap_or(1);
    let seconds = env_u64("OPTBENCH_FUZZ_SECONDS");
    let dir = tempfile::tempdir().unwrap();
    let out = failures_dir();
    std::fs::create_dir_all(&out).unwrap();
    let last = out.join(format!("{name}.last"));
    let last_file = std::fs::File::create(&last).unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut failures = Vec::new();
    let check = |input: &[u8], rng: &mut ChaCha8Rng, failures: &mut Vec<String>| {
        // Left behind if the input aborts the process (stack overflow, huge allocation).
        {
            use std::os::unix::fs::FileExt;
            last_file.set_len(0).unwrap();
            last_file.write_all_at(input, 0).unwrap();
        }
        if let Some(msg) = run_one(&t, input, rng, dir.path()) {
            let file = out.join(format!(
                "{name}-{}.bin",
                &optbench::base::hash::stable_hash(&[input])[..16]
            ));
            std::fs::write(&file, input).unwrap();
            failures.push(format!("{}: {msg}", file.display()));
        }
    };
    if let Ok(replay) = std::env::var("OPTBENCH_FUZZ_REPLAY") {
        let input = std::fs::read(&replay).unwrap();
        check(&input, &mut rng, &mut failures);
    } else {
        for input in t
            .seeds
            .iter()
            .map(Vec::as_slice)
            .chain(regressions.iter().copied())
        {
            check(input, &mut rng, &mut failures);
        }
        let start = Instant::now();
        let (mut n, mut slowest) = (0usize, (Duration::ZERO, Vec::new()));
        loop {
            let done = match seconds {
                Some(s) => start.elapsed() >= Duration::from_secs(s),
                None => n >= t.inputs,
            };
            if done {
                break;
            }
            let input = mutant(&mut rng, &t.seeds);
            let t0 = Instant::now();
            check(&input, &mut rng, &mut failures);
            if t0.elapsed() > slowest.0 {
                slowest = (t0.elapsed(), input);
            }
            n += 1;
        }
        let secs = start.elapsed().as_secs_f64();
        eprintln!(
            "fuzz {name}: seed {seed}, {n} inputs in {secs:.1} s ({:.0}/s), slowest {:.3} s \
             ({} bytes), {} panicked",
            n as f64 / secs.max(1e-9),
            slowest.0.as_secs_f64(),
            slowest.1.len(),
            failures.len()
        );
    }
    let _ = std::fs::remove_file(&last);
    assert!(
        failures.is_empty(),
        "{name}: {} input(s) panicked (saved for replay with \
         OPTBENCH_FUZZ_REPLAY=FILE):\n{}",
        failures.len(),
        failures.join("\n")
    );
}

#[test]
fn fuzz_suite() {
    fuzz("suite", &[]);
}

#[test]
fn fuzz_control_suite() {
    fuzz("control", &[]);
}

#[test]
fn fuzz_signal() {
    fuzz(
        "signal",
        &[b"sine:freq=1e308,amp=1e308", b"1e308*(1e308*(sine:freq=1))"],
    );
}

#[test]
fn fuzz_csv() {
    fuzz("csv", &[b"t,u,y\n", b"\xEF\xBB\xBF", b"t;u;y\n0;1,5;2.5\n"]);
}

//! What a paper or a reader takes from a results folder, checked as they would: the
//! Markdown through a GFM renderer, the LaTeX through pdflatex with its bold visible, and
//! report.html as one self-contained page a browser renders. The Rust checks always run;
//! those needing markdown-it-py, pdflatex/pdffonts or Chromium skip with a message when
//! the tool is missing (see scripts/README.md).

mod common;

use common::{check_report_outputs, optbench, run_check_script, run_shipped_suite};

#[test]
fn a_function_suite_and_its_comparison_render_everywhere() {
    // The shipped suite (every optimizer, ties at 0 on Schwefel) at a small size, and the
    // same suite with another seed to compare with.
    let dir = run_shipped_suite("functions", "2", "400");
    let suite = format!("{}/suites/functions.toml", env!("CARGO_MANIFEST_DIR"));
    let o = optbench(
        &[
            "run", &suite, "--trials", "2", "--budget", "400", "--seed", "7", "--out", "b", "-q",
        ],
        dir.path(),
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    check_report_outputs(&dir.path().join("r"));
    // The comparison is printed: its Markdown must render too.
    let o = optbench(&["report", "r", "b"], dir.path());
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let compare = dir.path().join("compare.md");
    std::fs::write(&compare, &o.stdout).unwrap();
    run_check_script("check_markdown.py", &[&compare]);
}

#[test]
fn a_fitting_suite_renders_everywhere() {
    let data = optbench::data::recording::data_dir();
    if !data.join("boucwen-benchmark").exists() {
        eprintln!(
            "skipping: data not found at {} (set OPTBENCH_DATA)",
            data.display()
        );
        return;
    }
    let dir = run_shipped_suite("boucwen-benchmark", "2", "60");
    check_report_outputs(&dir.path().join("r"));
}

// Embeds the git commit and the compiler of the build in the binary, for provenance of
// every result.
use std::path::Path;
use std::process::Command;

fn git(args: &[&str]) -> Option<String> {
    Command::new("git")
        .args(args)
        .output()
        .ok()
        .filter(|o| o.status.success())
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
}

fn main() {
    let commit = git(&["describe", "--always", "--dirty", "--abbrev=12"]).unwrap_or_default();
    println!("cargo:rustc-env=OPTBENCH_GIT_COMMIT={commit}");
    let version = std::env::var("CARGO_PKG_VERSION").unwrap_or_default();
    let built_from = match commit.as_str() {
        "" => "commit unknown: built outside git".to_string(),
        c => format!("commit {c}"),
    };
    println!("cargo:rustc-env=OPTBENCH_VERSION={version} ({built_from})");
    // The compiler, for provenance.json (cargo names it in RUSTC).
    let rustc = std::env::var("RUSTC").unwrap_or_else(|_| "rustc".into());
    let rustc_version = Command::new(rustc)
        .arg("--version")
        .output()
        .ok()
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
        .unwrap_or_default();
    println!("cargo:rustc-env=OPTBENCH_RUSTC_VERSION={rustc_version}");
    // The git folder as git resolves it: in a worktree `.git` is a file, and a watched path
    // that does not exist makes cargo rerun this script, and rebuild the crate, every time.
    if let Some(dir) = git(&["rev-parse", "--git-dir"]) {
        for f in ["HEAD", "index"] {
            let p = Path::new(&dir).join(f);
            if p.exists() {
                println!("cargo:rerun-if-changed={}", p.display());
            }
        }
    } else {
        println!("cargo:rerun-if-changed=build.rs");
    }
}

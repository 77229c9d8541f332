//! Command-line tests: the real `ember` binary, run as a user would.

mod daemon;
mod demo;
mod fuzz;
mod monitor;
mod plan;
mod recording;
mod reliability;
mod robot;

use std::path::PathBuf;
use std::process::{Command, Output};

/// Runs `ember` with `args`.
pub fn ember(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_ember"))
        .args(args)
        .output()
        .expect("ember runs")
}

/// The JSON `ember ... --json` printed, after checking it exited successfully (its stderr
/// is the failure message).
pub fn json_output(out: &Output) -> serde_json::Value {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("ember prints JSON")
}

/// The repository's `tests/fixtures` folder.
pub fn fixtures() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../tests/fixtures")
}

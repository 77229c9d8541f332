//! Command-line tests: the real `ember` binary, run as a user would.

mod daemon;
mod demo;
mod monitor;
mod plan;
mod recording;
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

/// The repository's `tests/fixtures` folder.
pub fn fixtures() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../tests/fixtures")
}

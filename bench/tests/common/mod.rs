//! What the bench tests share: running `ember-bench` as a user runs it.

use std::ffi::OsStr;
use std::process::Command;

/// Runs `ember-bench` with `args`, asserts that it succeeded (printing its output if not),
/// and returns its standard output.
pub fn ember_bench<I, S>(args: I) -> String
where
    I: IntoIterator<Item = S>,
    S: AsRef<OsStr>,
{
    let out = Command::new(env!("CARGO_BIN_EXE_ember-bench"))
        .args(args)
        .output()
        .expect("ember-bench runs");
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    stdout
}

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

/// A folder `name` under the tests' scratch directory holding two hand-written MoveIt
/// problems, numbered 3 and 8: the fixtures' table scene with a joint goal and with a pose
/// goal.
#[allow(dead_code)]
pub fn problem_folder(name: &str) -> std::path::PathBuf {
    let fixtures = concat!(env!("CARGO_MANIFEST_DIR"), "/../tests/fixtures/moveit");
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    std::fs::create_dir_all(&dir).expect("folder");
    for (n, request) in [(3, "request_joint.yaml"), (8, "request_pose.yaml")] {
        std::fs::copy(
            format!("{fixtures}/scene.yaml"),
            dir.join(format!("scene{n:04}.yaml")),
        )
        .expect("scene");
        std::fs::copy(
            format!("{fixtures}/{request}"),
            dir.join(format!("request{n:04}.yaml")),
        )
        .expect("request");
    }
    dir
}

/// The value of key `k` in a `key=value` line; panics naming the key when it is missing.
#[allow(dead_code)]
pub fn key(line: &str, k: &str) -> String {
    line.split_whitespace()
        .find_map(|kv| kv.strip_prefix(&format!("{k}=")).map(str::to_string))
        .unwrap_or_else(|| panic!("no {k} in {line}"))
}

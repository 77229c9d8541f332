//! Python peers (OctoMap, FCL) run in throwaway virtualenvs under `target/`, installed from
//! PyPI on first use.

use std::path::PathBuf;
use std::process::Command;

/// The python of virtualenv `target/<name>`, created with `packages` installed unless
/// `import` (a Python import statement) already works there.
pub fn venv(name: &str, packages: &[&str], import: &str) -> anyhow::Result<PathBuf> {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..");
    let venv = root.join("target").join(name);
    let python = venv.join("bin/python");
    if !python.exists() {
        let ok = Command::new("python3")
            .args(["-m", "venv"])
            .arg(&venv)
            .status()?
            .success();
        anyhow::ensure!(ok, "python3 -m venv failed; install python3-venv");
    }
    let has = Command::new(&python)
        .args(["-c", import])
        .status()?
        .success();
    if !has {
        let ok = Command::new(&python)
            .args(["-m", "pip", "install", "-q"])
            .args(packages)
            .status()?
            .success();
        anyhow::ensure!(ok, "pip install {} failed", packages.join(" "));
    }
    Ok(python)
}

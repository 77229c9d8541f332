//! A real `ember run` process for the benchmarks that go through the daemon.

use ember_sdk::launch::launch;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};

/// A daemon of its own instance with its own folder; killed and cleaned up on drop.
pub struct DaemonProcess {
    child: Child,
    pub instance: String,
    pub dir: PathBuf,
}

impl DaemonProcess {
    /// Starts `ember run` (the binary next to this one) with `config` (TOML) and `extra`
    /// arguments, and waits until it serves.
    pub fn start(tag: &str, config: &str, extra: &[&str]) -> anyhow::Result<DaemonProcess> {
        let exe = std::env::current_exe()?.with_file_name("ember");
        anyhow::ensure!(
            exe.exists(),
            "{} not found: build it first (cargo build --release -p ember-daemon)",
            exe.display()
        );
        let instance = format!("bench-{tag}-{}", std::process::id());
        let dir = std::env::temp_dir().join(&instance);
        std::fs::create_dir_all(&dir)?;
        let config_file = dir.join("emberd.toml");
        std::fs::write(&config_file, config)?;
        let (child, _) = launch(
            Command::new(&exe)
                .args(["run", "--instance", &instance, "--config"])
                .arg(&config_file)
                .arg("--db-dir")
                .arg(&dir)
                .arg("--record-dir")
                .arg(dir.join("recordings"))
                .args(extra)
                .stderr(Stdio::null()),
        )?;
        Ok(DaemonProcess {
            child,
            instance,
            dir,
        })
    }
}

impl DaemonProcess {
    /// CPU time the daemon has used so far (all its threads, user + system), seconds; None
    /// where `/proc` is not available.
    pub fn cpu_seconds(&self) -> Option<f64> {
        let stat = std::fs::read_to_string(format!("/proc/{}/stat", self.child.id())).ok()?;
        // Fields after the command name (which may hold spaces): utime and stime are the
        // 12th and 13th, in clock ticks (100 per second on Linux).
        let rest = &stat[stat.rfind(')')? + 2..];
        let f: Vec<&str> = rest.split_whitespace().collect();
        let ticks: f64 = f.get(11)?.parse::<f64>().ok()? + f.get(12)?.parse::<f64>().ok()?;
        Some(ticks / 100.0)
    }
}

impl Drop for DaemonProcess {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

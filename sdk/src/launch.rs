//! Starting a daemon (`ember run`) as a child process: the readiness line it prints once it
//! serves ([`Ready`], printed by the daemon and parsed here, one home for its format) and
//! [`launch`], which waits for it.

use std::fmt;
use std::io::{BufRead, BufReader};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use thiserror::Error;

/// What the daemon announces on its first line of standard output once it serves.
#[derive(Debug, Clone, PartialEq)]
pub struct Ready {
    /// Instance served.
    pub instance: String,
    /// Robot name.
    pub robot: String,
    /// Its planning group's joints.
    pub dof: usize,
    /// SPARK entries loaded.
    pub spark_entries: usize,
    /// FLAME entries loaded.
    pub flame_entries: usize,
    /// Zenoh endpoints of the monitor (`off`: not monitoring).
    pub monitoring: String,
    /// The recording file (None: not recording).
    pub recording: Option<PathBuf>,
}

impl fmt::Display for Ready {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "emberd ready: instance '{}', robot {} ({} joints), experience {} SPARK / {} FLAME entries, monitoring {}, recording {}",
            self.instance,
            self.robot,
            self.dof,
            self.spark_entries,
            self.flame_entries,
            self.monitoring,
            self.recording
                .as_ref()
                .map_or("off".to_string(), |p| p.display().to_string()),
        )
    }
}

impl Ready {
    /// Parses the line [`Ready`]'s `Display` writes.
    ///
    /// ```
    /// use ember_sdk::launch::Ready;
    /// let r = Ready {
    ///     instance: "default".into(), robot: "fetch".into(), dof: 8, spark_entries: 3,
    ///     flame_entries: 0, monitoring: "off".into(), recording: None,
    /// };
    /// assert_eq!(Ready::parse(&r.to_string()), Some(r));
    /// ```
    pub fn parse(line: &str) -> Option<Ready> {
        let rest = line.trim_end().strip_prefix("emberd ready: instance '")?;
        let (instance, rest) = rest.split_once("', robot ")?;
        let (robot, rest) = rest.rsplit_once(" joints), experience ")?;
        let (robot, dof) = robot.rsplit_once(" (")?;
        let (spark, rest) = rest.split_once(" SPARK / ")?;
        let (flame, rest) = rest.split_once(" FLAME entries, monitoring ")?;
        let (monitoring, recording) = rest.rsplit_once(", recording ")?;
        Some(Ready {
            instance: instance.into(),
            robot: robot.into(),
            dof: dof.parse().ok()?,
            spark_entries: spark.parse().ok()?,
            flame_entries: flame.parse().ok()?,
            monitoring: monitoring.into(),
            recording: (recording != "off").then(|| PathBuf::from(recording)),
        })
    }
}

/// A daemon that did not come up.
#[derive(Debug, Error)]
pub enum LaunchError {
    /// The process could not be started or read.
    #[error("cannot start the daemon: {0}")]
    Io(#[from] std::io::Error),
    /// It printed something else than its readiness line (or nothing) and was stopped.
    #[error("the daemon did not start (it said: {0:?})")]
    NotReady(String),
}

/// Starts `command` (an `ember run ...` command; its standard output is taken) and waits for
/// the readiness line. A daemon that says anything else is killed and reaped.
pub fn launch(command: &mut Command) -> Result<(Child, Ready), LaunchError> {
    let mut child = command.stdout(Stdio::piped()).spawn()?;
    let mut line = String::new();
    let read = BufReader::new(child.stdout.as_mut().expect("stdout is piped")).read_line(&mut line);
    match (read, Ready::parse(&line)) {
        (Ok(_), Some(ready)) => Ok((child, ready)),
        (read, _) => {
            let _ = child.kill();
            let _ = child.wait();
            read?;
            Err(LaunchError::NotReady(line.trim().to_string()))
        }
    }
}

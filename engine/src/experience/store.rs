//! [`Experience`]: both databases, the folder they are kept in, and what the planner asks of
//! them — a sampler for a method and a scene's primitives, and learning from a solution.

use super::database::Database;
use super::file::DbError;
use super::flame::{FlameDb, Octobox};
use super::sampler::{GlobalSampler, Retrieval};
use super::spark::{SparkDb, SparkPair};
use super::ExperienceParams;
use std::path::{Path, PathBuf};

/// How a plan samples: uniformly, or biased by what SPARK or FLAME retrieve.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Method {
    /// Uniform sampling within the joint limits.
    Uniform,
    /// SPARK: retrieval by the scene's object pairs.
    Spark,
    /// FLAME: retrieval by the sensed map's octoboxes.
    Flame,
}

impl Method {
    /// The method's lower-case name (`uniform`, `spark`, `flame`).
    pub fn name(self) -> &'static str {
        match self {
            Method::Uniform => "uniform",
            Method::Spark => "spark",
            Method::Flame => "flame",
        }
    }
}

/// A database file that could not be loaded and was moved aside (never overwritten); shown as
/// one sentence for logs.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{error}; moved to {} and starting empty", moved_to.display())]
pub struct SetAside {
    /// Why it could not be loaded.
    pub error: DbError,
    /// Where it now is.
    pub moved_to: PathBuf,
}

/// The experience the planner learns from and samples with: SPARK's and FLAME's databases.
#[derive(Debug, Clone, Default)]
pub struct Experience {
    /// SPARK's database.
    pub spark: SparkDb,
    /// FLAME's database.
    pub flame: FlameDb,
    /// Learned since the last save.
    pub(crate) dirty: bool,
}

impl Experience {
    /// Empty databases with `params`, FLAME's for maps of `map_resolution`.
    pub fn new(params: ExperienceParams, map_resolution: f64) -> Self {
        Experience {
            spark: SparkDb::new(params.clone()),
            flame: FlameDb::new(params, map_resolution),
            dirty: false,
        }
    }

    /// Loads both databases from `dir` (`spark.emberdb`, `flame.emberdb`). A missing file
    /// starts empty with `params` / `map_resolution`; a file that cannot be loaded (corrupt,
    /// truncated, foreign, newer) is moved aside beside itself — never overwritten — and starts
    /// empty too, and is listed in the second value. Fails only when it cannot be moved.
    /// Temporary files that a process killed mid-save left behind are removed.
    pub fn load_dir(
        dir: &Path,
        params: &ExperienceParams,
        map_resolution: f64,
    ) -> Result<(Self, Vec<SetAside>), DbError> {
        remove_stale_temporaries(dir);
        let mut set_aside = Vec::new();
        let spark = load_or_new(dir, &mut set_aside, || SparkDb::new(params.clone()))?;
        let flame = load_or_new(dir, &mut set_aside, || {
            FlameDb::new(params.clone(), map_resolution)
        })?;
        let experience = Experience {
            spark,
            flame,
            dirty: false,
        };
        Ok((experience, set_aside))
    }

    /// Saves both databases into `dir` (created when missing), each file atomically.
    pub fn save_dir(&mut self, dir: &Path) -> Result<(), DbError> {
        self.spark.save(&dir.join(SparkDb::FILE_NAME))?;
        self.flame.save(&dir.join(FlameDb::FILE_NAME))?;
        self.dirty = false;
        Ok(())
    }

    /// True when something was learned since the last [`save_dir`](Self::save_dir).
    pub fn is_dirty(&self) -> bool {
        self.dirty
    }

    /// The paths of the two database files in `dir`.
    pub fn files(dir: &Path) -> [PathBuf; 2] {
        [dir.join(SparkDb::FILE_NAME), dir.join(FlameDb::FILE_NAME)]
    }

    /// The method an unspecified request gets: SPARK once it has learned something, else
    /// uniform.
    pub fn default_method(&self) -> Method {
        if self.spark.is_empty() {
            Method::Uniform
        } else {
            Method::Spark
        }
    }

    /// The sampler for `method` in a scene whose primitives are `pairs` (SPARK) and `octoboxes`
    /// (FLAME): what the method's database retrieves, mixed with uniform samples by its λ and
    /// spread by its σ. Uniform (or nothing retrieved) samples exactly as the uniform sampler.
    pub fn sampler_for(
        &self,
        method: Method,
        pairs: &[SparkPair],
        octoboxes: &[Octobox],
    ) -> GlobalSampler<'_> {
        let (retrieval, params) = match method {
            Method::Uniform => (Retrieval::default(), self.spark.params()),
            Method::Spark => (self.spark.retrieve(pairs), self.spark.params()),
            Method::Flame => (self.flame.retrieve(octoboxes), self.flame.params()),
        };
        GlobalSampler::new(retrieval, params.sigma, params.lambda)
    }
}

/// Removes `.<file>.tmp-<pid>` files (see [`file`](super::file)'s atomic save) whose process is
/// gone (Linux: no `/proc/<pid>`); elsewhere they are left alone.
fn remove_stale_temporaries(dir: &Path) {
    if !Path::new("/proc/self").exists() {
        return;
    }
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let name = e.file_name().to_string_lossy().to_string();
        let pid = [SparkDb::FILE_NAME, FlameDb::FILE_NAME]
            .iter()
            .find_map(|f| name.strip_prefix(&format!(".{f}.tmp-")))
            .and_then(|p| p.parse::<u32>().ok());
        if pid.is_some_and(|p| !Path::new(&format!("/proc/{p}")).exists()) {
            let _ = std::fs::remove_file(e.path());
        }
    }
}

/// Loads database `D` from `dir`, or makes it with `new` (see [`Experience::load_dir`]).
fn load_or_new<D: Database>(
    dir: &Path,
    set_aside: &mut Vec<SetAside>,
    new: impl Fn() -> D,
) -> Result<D, DbError> {
    let path = dir.join(D::FILE_NAME);
    if !path.exists() {
        return Ok(new());
    }
    match D::load(&path) {
        Ok(db) => Ok(db),
        Err(error) => {
            let moved_to = path.with_extension(format!("corrupt-{}", std::process::id()));
            std::fs::rename(&path, &moved_to).map_err(|e| DbError::Io {
                path: path.display().to_string(),
                message: format!("cannot be loaded ({error}) nor moved aside: {e}"),
            })?;
            set_aside.push(SetAside { error, moved_to });
            Ok(new())
        }
    }
}

//! The database file: versioned, checksummed, written atomically.
//!
//! Layout (little endian): magic `EMBEREXP`, format version (u32), kind (u8: 1 SPARK, 2 FLAME),
//! payload length (u64), payload, CRC-32 of the payload (u32). Saving writes a temporary file
//! beside the target, fsyncs it, renames it over the target and fsyncs the folder, so a crash
//! leaves either the old or the new database, never a torn one.

use super::database::Database;
use super::flame::{FlameDb, Octobox};
use super::sampler::LocalSampler;
use super::spark::{BoxPrimitive, SparkDb, SparkPair};
use super::ExperienceParams;
use crate::scene::pose_from_xyz_xyzw;
use std::path::Path;
use thiserror::Error;

const MAGIC: &[u8; 8] = b"EMBEREXP";
/// Current file format version (2 added `flame_radius` to the parameters; version 1 files
/// load with its default).
pub const VERSION: u32 = 2;
const KIND_SPARK: u8 = 1;
const KIND_FLAME: u8 = 2;

/// A database file that cannot be used.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum DbError {
    /// Reading or writing failed.
    #[error("{path}: {message}")]
    Io {
        /// File path.
        path: String,
        /// The operating system's reason.
        message: String,
    },
    /// The file does not start with Ember's magic bytes.
    #[error("{0}: not an Ember experience database")]
    NotADatabase(String),
    /// The format version is not one this build reads.
    #[error("{path}: format version {found}, this build reads version {supported}")]
    Version {
        /// File path.
        path: String,
        /// Version in the file.
        found: u32,
        /// Version this build reads.
        supported: u32,
    },
    /// A SPARK file where a FLAME one was expected or the reverse.
    #[error("{path}: holds a {found} database, expected {expected}")]
    WrongKind {
        /// File path.
        path: String,
        /// Expected kind.
        expected: &'static str,
        /// Kind in the file.
        found: &'static str,
    },
    /// The file is shorter than its header says.
    #[error("{0}: truncated")]
    Truncated(String),
    /// The payload does not match its checksum.
    #[error("{0}: checksum mismatch (the file is corrupt)")]
    Checksum(String),
    /// The payload is malformed.
    #[error("{path}: corrupt payload: {what}")]
    Corrupt {
        /// File path.
        path: String,
        /// What is wrong.
        what: String,
    },
}

fn kind_name(k: u8) -> &'static str {
    match k {
        KIND_SPARK => "SPARK",
        KIND_FLAME => "FLAME",
        _ => "unknown",
    }
}

#[derive(Default)]
struct Writer(Vec<u8>);

impl Writer {
    fn u32(&mut self, v: u32) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn u64(&mut self, v: u64) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn i32(&mut self, v: i32) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn f64(&mut self, v: f64) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn str(&mut self, s: &str) {
        self.u32(s.len() as u32);
        self.0.extend_from_slice(s.as_bytes());
    }
    fn params(&mut self, p: &ExperienceParams) {
        for v in [
            p.sigma,
            p.lambda,
            p.d_radius,
            p.d_pairs,
            p.w_t,
            p.w_s,
            p.flame_radius,
        ] {
            self.f64(v);
        }
    }
    fn sampler(&mut self, dof: usize, s: &LocalSampler) {
        self.u32(s.len() as u32);
        debug_assert!(s.is_empty() || s.dof() == dof);
        for q in s.means() {
            for v in q {
                self.f64(*v);
            }
        }
    }
    fn boxp(&mut self, b: &BoxPrimitive) {
        let t = b.pose.translation.vector;
        let q = b.pose.rotation.coords;
        for v in [
            t.x, t.y, t.z, q.x, q.y, q.z, q.w, b.size[0], b.size[1], b.size[2],
        ] {
            self.f64(v);
        }
    }
}

struct Reader<'a> {
    data: &'a [u8],
    pos: usize,
    path: &'a str,
    version: u32,
}

impl Reader<'_> {
    fn take(&mut self, n: usize) -> Result<&[u8], DbError> {
        if self.pos + n > self.data.len() {
            return Err(DbError::Corrupt {
                path: self.path.into(),
                what: "payload ends early".into(),
            });
        }
        let s = &self.data[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }
    fn u32(&mut self) -> Result<u32, DbError> {
        Ok(u32::from_le_bytes(
            self.take(4)?.try_into().expect("4 bytes"),
        ))
    }
    fn u64(&mut self) -> Result<u64, DbError> {
        Ok(u64::from_le_bytes(
            self.take(8)?.try_into().expect("8 bytes"),
        ))
    }
    fn i32(&mut self) -> Result<i32, DbError> {
        Ok(i32::from_le_bytes(
            self.take(4)?.try_into().expect("4 bytes"),
        ))
    }
    fn f64(&mut self) -> Result<f64, DbError> {
        Ok(f64::from_le_bytes(
            self.take(8)?.try_into().expect("8 bytes"),
        ))
    }
    fn str(&mut self) -> Result<String, DbError> {
        let n = self.u32()? as usize;
        let b = self.take(n)?.to_vec();
        String::from_utf8(b).map_err(|_| DbError::Corrupt {
            path: self.path.into(),
            what: "name is not UTF-8".into(),
        })
    }
    fn params(&mut self) -> Result<ExperienceParams, DbError> {
        Ok(ExperienceParams {
            sigma: self.f64()?,
            lambda: self.f64()?,
            d_radius: self.f64()?,
            d_pairs: self.f64()?,
            w_t: self.f64()?,
            w_s: self.f64()?,
            flame_radius: if self.version >= 2 {
                self.f64()?
            } else {
                ExperienceParams::default().flame_radius
            },
        })
    }
    fn count(&mut self, each: usize) -> Result<usize, DbError> {
        let n = self.u32()? as usize;
        if n.saturating_mul(each) > self.data.len() - self.pos {
            return Err(DbError::Corrupt {
                path: self.path.into(),
                what: format!("count {n} exceeds the payload"),
            });
        }
        Ok(n)
    }
    fn configs(&mut self, dof: usize) -> Result<Vec<Vec<f64>>, DbError> {
        let n = self.count(8 * dof)?;
        (0..n)
            .map(|_| (0..dof).map(|_| self.f64()).collect())
            .collect()
    }
    /// Ends the payload: nothing may follow.
    fn finish(&self) -> Result<(), DbError> {
        if self.pos != self.data.len() {
            return Err(DbError::Corrupt {
                path: self.path.into(),
                what: "trailing bytes".into(),
            });
        }
        Ok(())
    }
    fn boxp(&mut self) -> Result<BoxPrimitive, DbError> {
        let v: Vec<f64> = (0..10).map(|_| self.f64()).collect::<Result<_, _>>()?;
        let pose =
            pose_from_xyz_xyzw([v[0], v[1], v[2]], [v[3], v[4], v[5], v[6]]).ok_or_else(|| {
                DbError::Corrupt {
                    path: self.path.into(),
                    what: "invalid box pose".into(),
                }
            })?;
        Ok(BoxPrimitive {
            pose,
            size: [v[7], v[8], v[9]],
        })
    }
}

fn io(path: &Path, e: std::io::Error) -> DbError {
    DbError::Io {
        path: path.display().to_string(),
        message: e.to_string(),
    }
}

/// Creates (or truncates) `path` readable and writable by its owner only (`0600` on Unix):
/// what the robot learned is nobody else's to read or change.
pub fn private_file(path: &Path) -> std::io::Result<std::fs::File> {
    let mut options = std::fs::OpenOptions::new();
    options.write(true).create(true).truncate(true);
    #[cfg(unix)]
    std::os::unix::fs::OpenOptionsExt::mode(&mut options, 0o600);
    options.open(path)
}

/// Writes `kind` + `payload` to `path` atomically.
fn save(path: &Path, kind: u8, payload: &[u8]) -> Result<(), DbError> {
    use std::io::Write;
    let mut bytes = Vec::with_capacity(payload.len() + 32);
    bytes.extend_from_slice(MAGIC);
    bytes.extend_from_slice(&VERSION.to_le_bytes());
    bytes.push(kind);
    bytes.extend_from_slice(&(payload.len() as u64).to_le_bytes());
    bytes.extend_from_slice(payload);
    bytes.extend_from_slice(&crc32fast::hash(payload).to_le_bytes());
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    std::fs::create_dir_all(dir).map_err(|e| io(dir, e))?;
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().to_string())
        .unwrap_or_default();
    let tmp = dir.join(format!(".{name}.tmp-{}", std::process::id()));
    let mut f = private_file(&tmp).map_err(|e| io(&tmp, e))?;
    f.write_all(&bytes).map_err(|e| io(&tmp, e))?;
    f.sync_all().map_err(|e| io(&tmp, e))?;
    drop(f);
    std::fs::rename(&tmp, path).map_err(|e| io(path, e))?;
    if let Ok(d) = std::fs::File::open(dir) {
        d.sync_all().ok();
    }
    Ok(())
}

/// Reads and checks a file; returns its kind and payload.
fn load(path: &Path) -> Result<(u8, u32, Vec<u8>), DbError> {
    let p = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|e| io(path, e))?;
    if bytes.len() < 8 || &bytes[..8] != MAGIC {
        return Err(DbError::NotADatabase(p));
    }
    if bytes.len() < 21 {
        return Err(DbError::Truncated(p));
    }
    let version = u32::from_le_bytes(bytes[8..12].try_into().expect("4 bytes"));
    if !(1..=VERSION).contains(&version) {
        return Err(DbError::Version {
            path: p,
            found: version,
            supported: VERSION,
        });
    }
    let kind = bytes[12];
    let len = u64::from_le_bytes(bytes[13..21].try_into().expect("8 bytes")) as usize;
    if bytes.len() < 21usize.saturating_add(len).saturating_add(4) {
        return Err(DbError::Truncated(p));
    }
    let payload = &bytes[21..21 + len];
    let crc = u32::from_le_bytes(bytes[21 + len..25 + len].try_into().expect("4 bytes"));
    if crc32fast::hash(payload) != crc {
        return Err(DbError::Checksum(p));
    }
    Ok((kind, version, payload.to_vec()))
}

/// A checked file of kind `expected`: its payload, path as text and format version.
struct Loaded {
    payload: Vec<u8>,
    path: String,
    version: u32,
}

impl Loaded {
    fn open(path: &Path, expected: u8) -> Result<Loaded, DbError> {
        let (found, version, payload) = load(path)?;
        let p = path.display().to_string();
        if found != expected {
            return Err(DbError::WrongKind {
                path: p,
                expected: kind_name(expected),
                found: kind_name(found),
            });
        }
        Ok(Loaded {
            payload,
            path: p,
            version,
        })
    }

    fn reader(&self) -> Reader<'_> {
        Reader {
            data: &self.payload,
            pos: 0,
            path: &self.path,
            version: self.version,
        }
    }
}

fn dof_of<'a>(mut samplers: impl Iterator<Item = &'a LocalSampler>) -> usize {
    samplers
        .find(|s| !s.is_empty())
        .map_or(0, LocalSampler::dof)
}

/// Saves a SPARK database atomically to `path`.
pub(crate) fn save_spark(db: &SparkDb, path: &Path) -> Result<(), DbError> {
    let mut w = Writer::default();
    w.params(db.params());
    let dof = dof_of(db.samplers().iter());
    w.u32(dof as u32);
    w.u64(db.len() as u64);
    for (k, s) in db.entries() {
        w.boxp(&k.a);
        w.boxp(&k.b);
        w.str(&k.names[0]);
        w.str(&k.names[1]);
        w.sampler(dof, s);
    }
    save(path, KIND_SPARK, &w.0)
}

/// Loads a database saved by [`save_spark`].
pub(crate) fn load_spark(path: &Path) -> Result<SparkDb, DbError> {
    let file = Loaded::open(path, KIND_SPARK)?;
    let mut r = file.reader();
    let params = r.params()?;
    let dof = r.u32()? as usize;
    let n = r.u64()? as usize;
    let mut db = SparkDb::new(params);
    for _ in 0..n {
        let a = r.boxp()?;
        let b = r.boxp()?;
        let names = [r.str()?, r.str()?];
        let configs = r.configs(dof)?;
        db.insert(SparkPair { a, b, names }, configs);
    }
    r.finish()?;
    Ok(db)
}

/// Saves a FLAME database atomically to `path`.
pub(crate) fn save_flame(db: &FlameDb, path: &Path) -> Result<(), DbError> {
    let mut w = Writer::default();
    w.params(db.params());
    w.f64(db.resolution());
    let dof = dof_of(db.samplers().iter());
    w.u32(dof as u32);
    w.u64(db.len() as u64);
    for (k, s) in db.entries() {
        for c in k.key {
            w.i32(c);
        }
        w.u64(k.mask);
        w.sampler(dof, s);
    }
    save(path, KIND_FLAME, &w.0)
}

/// Loads a database saved by [`save_flame`].
pub(crate) fn load_flame(path: &Path) -> Result<FlameDb, DbError> {
    let file = Loaded::open(path, KIND_FLAME)?;
    let mut r = file.reader();
    let params = r.params()?;
    let resolution = r.f64()?;
    let dof = r.u32()? as usize;
    let n = r.u64()? as usize;
    let mut db = FlameDb::new(params, resolution);
    for _ in 0..n {
        let key = [r.i32()?, r.i32()?, r.i32()?];
        let mask = r.u64()?;
        let configs = r.configs(dof)?;
        db.insert(Octobox { key, mask }, configs);
    }
    r.finish()?;
    Ok(db)
}

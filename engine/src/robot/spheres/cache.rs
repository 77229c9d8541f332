//! Fitted spheres cached by content: in memory for the process and on disk across starts.
//!
//! The key is a SHA-256 of the fitter version, the protrusion and each part's pose and
//! geometry (primitive dimensions, hull vertices), so any change to a mesh, its scale or its
//! origin fits afresh. Files live in `<dir>/spheres-v1/<key>.bin` (magic, count, spheres as
//! little-endian f64, CRC-32), written atomically; an unreadable or corrupt file is refitted
//! and replaced.

use super::fit::{fit, Sphere};
use crate::robot::{Geometry, LinkShape};
use rustc_hash::FxHashMap;
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, OnceLock};

/// Bumped whenever the fitter's output for the same input changes.
const FIT_VERSION: &str = "ember-spheres-v3";
const MAGIC: &[u8; 8] = b"EMBSPHR1";

/// Where fitted spheres are kept between runs.
#[derive(Debug, Clone, Default, PartialEq)]
pub enum SphereCache {
    /// `$EMBER_CACHE_DIR`, else `$XDG_CACHE_HOME/ember`, else `~/.cache/ember`.
    #[default]
    Default,
    /// No disk cache (the in-process memo still applies).
    Off,
    /// This folder.
    Dir(PathBuf),
}

impl SphereCache {
    /// The folder in use, if any.
    pub fn dir(&self) -> Option<PathBuf> {
        match self {
            SphereCache::Off => None,
            SphereCache::Dir(d) => Some(d.clone()),
            SphereCache::Default => {
                let env = |k: &str| std::env::var_os(k).filter(|v| !v.is_empty());
                env("EMBER_CACHE_DIR")
                    .map(PathBuf::from)
                    .or_else(|| env("XDG_CACHE_HOME").map(|d| Path::new(&d).join("ember")))
                    .or_else(|| env("HOME").map(|d| Path::new(&d).join(".cache/ember")))
            }
        }
    }
}

/// Where a link's spheres came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Source {
    /// Fitted in this process before.
    Memory,
    /// Read from the disk cache.
    Disk,
    /// Fitted now.
    Fitted,
}

/// Per content key, a cell filled once: concurrent loads of the same geometry (tests, threads)
/// fit it once and wait for each other.
type Memo = Mutex<FxHashMap<[u8; 32], Arc<OnceLock<Arc<Vec<Sphere>>>>>>;

fn memo() -> &'static Memo {
    static MEMO: OnceLock<Memo> = OnceLock::new();
    MEMO.get_or_init(Default::default)
}

/// Forgets the in-process memo (benchmarks time the disk cache and the fitter with it).
pub fn clear_memory() {
    memo().lock().unwrap_or_else(|e| e.into_inner()).clear();
}

/// The spheres of one link: from memory, disk, or the fitter (then stored in both).
pub(crate) fn fitted(
    shapes: &[LinkShape],
    protrusion: f64,
    cache: &SphereCache,
) -> (Arc<Vec<Sphere>>, Source) {
    let key = content_key(shapes, protrusion);
    let cell = memo()
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .entry(key)
        .or_default()
        .clone();
    let mut source = Source::Memory;
    let spheres = cell.get_or_init(|| {
        let file = cache
            .dir()
            .map(|d| d.join("spheres-v1").join(format!("{}.bin", hex(&key))));
        if let Some(s) = file.as_deref().and_then(read) {
            source = Source::Disk;
            return Arc::new(s);
        }
        source = Source::Fitted;
        let s = fit(shapes, protrusion);
        if let Some(f) = &file {
            if let Err(e) = write(f, &s) {
                tracing::warn!("sphere cache {} not written: {e}", f.display());
            }
        }
        Arc::new(s)
    });
    (spheres.clone(), source)
}

fn content_key(shapes: &[LinkShape], protrusion: f64) -> [u8; 32] {
    let mut h = Sha256::new();
    h.update(FIT_VERSION.as_bytes());
    h.update(protrusion.to_le_bytes());
    hash_shapes(&mut h, shapes);
    h.finalize().into()
}

/// Feeds each part's pose and geometry to `h`.
pub(crate) fn hash_shapes(h: &mut Sha256, shapes: &[LinkShape]) {
    for ls in shapes {
        let t = ls.origin.translation.vector;
        let q = ls.origin.rotation.coords;
        for v in [t.x, t.y, t.z, q.x, q.y, q.z, q.w] {
            h.update(v.to_le_bytes());
        }
        match &ls.geometry {
            Geometry::Primitive(s) => h.update(format!("{s:?}").as_bytes()),
            Geometry::Convex(hull) => {
                h.update(b"convex");
                for p in &hull.points {
                    for v in p {
                        h.update(v.to_le_bytes());
                    }
                }
            }
        }
    }
}

pub(crate) fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

fn read(path: &Path) -> Option<Vec<Sphere>> {
    let body = read_checked(path)?;
    if body.len() < 12 || &body[..8] != MAGIC {
        return None;
    }
    let n = u32::from_le_bytes(body[8..12].try_into().ok()?) as usize;
    let data = &body[12..];
    if data.len() != n * 32 {
        return None;
    }
    let f = |i: usize| f64::from_le_bytes(data[i * 8..i * 8 + 8].try_into().expect("8 bytes"));
    let spheres: Vec<Sphere> = (0..n)
        .map(|k| ([f(4 * k), f(4 * k + 1), f(4 * k + 2)], f(4 * k + 3)))
        .collect();
    spheres
        .iter()
        .all(|(c, r)| c.iter().all(|v| v.is_finite()) && r.is_finite() && *r > 0.0)
        .then_some(spheres)
}

fn write(path: &Path, spheres: &[Sphere]) -> std::io::Result<()> {
    let mut bytes = MAGIC.to_vec();
    bytes.extend((spheres.len() as u32).to_le_bytes());
    for (c, r) in spheres {
        for v in [c[0], c[1], c[2], *r] {
            bytes.extend(v.to_le_bytes());
        }
    }
    write_checked(path, bytes)
}

/// The body of a cache file written by [`write_checked`] when its CRC-32 holds.
pub(crate) fn read_checked(path: &Path) -> Option<Vec<u8>> {
    let mut bytes = std::fs::read(path).ok()?;
    if bytes.len() < 4 {
        return None;
    }
    let crc = bytes.split_off(bytes.len() - 4);
    (crc32fast::hash(&bytes).to_le_bytes()[..] == crc[..]).then_some(bytes)
}

/// Writes `bytes` and their CRC-32 to `path` atomically (a temporary file renamed), making
/// its folder.
pub(crate) fn write_checked(path: &Path, mut bytes: Vec<u8>) -> std::io::Result<()> {
    let dir = path.parent().expect("cache files live in a folder");
    std::fs::create_dir_all(dir)?;
    let crc = crc32fast::hash(&bytes);
    bytes.extend(crc.to_le_bytes());
    let tmp = dir.join(format!(
        ".{}.{}.tmp",
        path.file_name().unwrap_or_default().to_string_lossy(),
        std::process::id()
    ));
    std::fs::write(&tmp, &bytes)?;
    std::fs::rename(&tmp, path)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::collision::Shape;
    use crate::Pose;

    #[test]
    fn disk_cache_round_trips_and_survives_corruption() {
        let dir = std::env::temp_dir().join(format!("ember-sphere-cache-{}", std::process::id()));
        let cache = SphereCache::Dir(dir.clone());
        let shapes = [LinkShape {
            origin: Pose::translation(0.0, 0.0, 0.123456),
            geometry: Geometry::Primitive(Shape::cuboid([0.05, 0.06, 0.07])),
        }];
        let (a, _) = fitted(&shapes, 0.01, &cache);
        let file = std::fs::read_dir(dir.join("spheres-v1"))
            .unwrap()
            .next()
            .unwrap()
            .unwrap()
            .path();
        assert_eq!(read(&file).as_deref(), Some(a.as_slice()));
        let mut bytes = std::fs::read(&file).unwrap();
        let mid = bytes.len() / 2;
        bytes[mid] ^= 0xff;
        std::fs::write(&file, &bytes).unwrap();
        assert_eq!(read(&file), None);
        clear_memory();
        let (b, source) = fitted(&shapes, 0.01, &cache);
        assert_eq!(source, Source::Fitted);
        assert_eq!(a, b);
        clear_memory();
        let (_, source) = fitted(&shapes, 0.01, &cache);
        assert_eq!(source, Source::Disk);
        std::fs::remove_dir_all(&dir).ok();
    }
}

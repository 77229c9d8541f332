//! Room inside a link that its spheres leave: the spheres cover each link's surface, and
//! nearly always its inside, but not by construction. An obstacle wholly inside a link and
//! clear of its spheres holds a ball (of its inradius) whose centre is inside the link and at
//! least that radius from every sphere. [`has_room`] decides, for a radius `t`, whether any
//! point inside the link's geometry may be `t` or farther from every sphere (a subdivision of
//! the link's box whose cells are cleared by the distance bounds at their centres); when none
//! is, no obstacle holding a ball of radius `t` (a map's voxel of edge `2t`) can hide there.
//! [`LinkPockets`] keeps each link's answers with its sphere model.

use super::cache::{hash_shapes, hex, read_checked, write_checked};
use super::fit::{Part, Sphere};
use crate::robot::LinkShape;
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};
use std::sync::{Mutex, OnceLock};

/// Bumped whenever [`has_room`]'s answer for the same input may change.
const ROOM_VERSION: &str = "ember-pockets-v1";
const MAGIC: &[u8; 8] = b"EMBROOM1";

/// Cells are split until their half diagonal is this fraction of the radius asked about; a
/// cell still undecided then counts as room.
const FINEST: f64 = 0.25;

/// True when some point inside `parts` (the link's geometry, link frame) may lie at distance
/// `t` or more from every sphere of `spheres` (false is certain: every point is nearer).
pub(crate) fn has_room(parts: &[Part], spheres: &[Sphere], t: f64) -> bool {
    if parts.is_empty() {
        return false;
    }
    // Not a positive radius (or not a number): nothing is certain.
    if t.is_nan() || t <= 0.0 {
        return true;
    }
    let (lo, hi) = Part::bounds_of(parts);
    let half = (0..3).map(|a| (hi[a] - lo[a]) / 2.0).fold(0.0, f64::max);
    let mut cells = vec![(std::array::from_fn(|a| (lo[a] + hi[a]) / 2.0), half)];
    // The sphere that cleared the last cell is tried first: neighbouring cells mostly share it.
    let mut hint = 0;
    while let Some((c, h)) = cells.pop() {
        // Distances change no faster than the point moves: bounds at the centre hold for the
        // cell within its half diagonal.
        let reach = h * 3f64.sqrt();
        let depth = parts.iter().map(|p| p.depth(c)).fold(f64::MIN, f64::max);
        if depth + reach <= 0.0 {
            continue;
        }
        let near = |s: &Sphere| {
            let d = (0..3).map(|a| (c[a] - s.0[a]).powi(2)).sum::<f64>().sqrt();
            d - s.1 + reach < t
        };
        if spheres.get(hint).is_some_and(near) {
            continue;
        }
        if let Some(k) = spheres.iter().position(near) {
            hint = k;
            continue;
        }
        if reach <= FINEST * t {
            return true;
        }
        let q = h / 2.0;
        for k in 0..8 {
            let corner = [k & 1, k >> 1 & 1, k >> 2 & 1].map(|b| if b == 1 { q } else { -q });
            cells.push((std::array::from_fn(|a| c[a] + corner[a]), q));
        }
    }
    false
}

/// One link's geometry and spheres, and the radii [`has_room`] was asked about with its
/// answers: shared by a robot's copies (a copy holding an object asks again only of the
/// object's link). With a cache folder the answers are also kept on disk, keyed by a SHA-256
/// of the geometry, the spheres and the radius (`<dir>/pockets-v1/<key>.bin`), so another
/// process loading the same robot reads them instead of working them out again.
pub struct LinkPockets {
    shapes: Vec<LinkShape>,
    spheres: Vec<Sphere>,
    /// The link is balls alone, its own sphere model: no room anywhere.
    balls: bool,
    asked: Mutex<Vec<(u64, bool)>>,
    /// The disk cache's folder, if any, and the link's content key (hashed on first use).
    dir: Option<PathBuf>,
    key: OnceLock<String>,
}

impl LinkPockets {
    /// The pockets of a link with geometry `shapes` and spheres `spheres` (link frame),
    /// answers kept under `dir` when given.
    pub fn new(shapes: &[LinkShape], spheres: &[Sphere], dir: Option<PathBuf>) -> Self {
        LinkPockets {
            shapes: shapes.to_vec(),
            spheres: spheres.to_vec(),
            balls: super::fit::balls(shapes).is_some(),
            asked: Mutex::new(Vec::new()),
            dir,
            key: OnceLock::new(),
        }
    }

    /// True when an obstacle holding a ball of radius `t` may lie inside the link clear of
    /// its spheres ([`has_room`], worked out on first asking for each radius, or read from
    /// the disk cache; false for a link without geometry).
    pub fn has_room_for(&self, t: f64) -> bool {
        if self.balls {
            return false;
        }
        let bits = t.to_bits();
        if let Some(&(_, room)) = self.lock().iter().find(|(k, _)| *k == bits) {
            return room;
        }
        let file = self.dir.as_ref().map(|d| {
            let key = self.key.get_or_init(|| self.content_key());
            d.join("pockets-v1").join(format!("{key}-{bits:016x}.bin"))
        });
        let room = match file.as_deref().and_then(read_room) {
            Some(room) => room,
            None => {
                let parts: Vec<Part> = self.shapes.iter().map(Part::new).collect();
                let room = has_room(&parts, &self.spheres, t);
                if let Some(f) = &file {
                    let bytes = [&MAGIC[..], &[u8::from(room)]].concat();
                    if let Err(e) = write_checked(f, bytes) {
                        tracing::warn!("pocket cache {} not written: {e}", f.display());
                    }
                }
                room
            }
        };
        self.lock().push((bits, room));
        room
    }

    fn content_key(&self) -> String {
        let mut h = Sha256::new();
        h.update(ROOM_VERSION.as_bytes());
        hash_shapes(&mut h, &self.shapes);
        for (c, r) in &self.spheres {
            for v in [c[0], c[1], c[2], *r] {
                h.update(v.to_le_bytes());
            }
        }
        hex(&h.finalize())
    }

    /// Radii asked about so far.
    #[cfg(test)]
    pub(crate) fn answered(&self) -> usize {
        self.lock().len()
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Vec<(u64, bool)>> {
        // A panic elsewhere while it was held leaves a list that is still whole.
        self.asked.lock().unwrap_or_else(|e| e.into_inner())
    }
}

/// A cached answer: `None` when the file is missing, corrupt or not one.
fn read_room(path: &Path) -> Option<bool> {
    match read_checked(path)?.as_slice() {
        [magic @ .., answer] if magic == MAGIC && *answer <= 1 => Some(*answer == 1),
        _ => None,
    }
}

impl std::fmt::Debug for LinkPockets {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LinkPockets")
            .field("spheres", &self.spheres.len())
            .finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::collision::Shape;
    use crate::robot::{Geometry, Robot};
    use crate::Pose;

    fn cube(edge: f64) -> Vec<Part> {
        vec![Part::new(&LinkShape {
            origin: Pose::translation(0.1, 0.0, 0.0),
            geometry: Geometry::Primitive(Shape::cuboid([edge; 3])),
        })]
    }

    #[test]
    fn a_cube_covered_at_its_surface_only_has_room_inside() {
        // Spheres on the faces' centres and corners of a 10 cm cube reach 3 cm in: its
        // centre is 2 cm from them.
        let mut spheres = Vec::new();
        for k in 0..8 {
            let c = [k & 1, k >> 1 & 1, k >> 2 & 1].map(|b| if b == 1 { 0.05 } else { -0.05 });
            spheres.push(([0.1 + c[0], c[1], c[2]], 0.045));
        }
        for a in 0..3 {
            for s in [-0.05, 0.05] {
                let mut c = [0.1, 0.0, 0.0];
                c[a] += s;
                spheres.push((c, 0.045));
            }
        }
        let parts = cube(0.1);
        assert!(has_room(&parts, &spheres, 0.002));
        assert!(has_room(&parts, &spheres, 0.004));
        assert!(!has_room(&parts, &spheres, 0.012));
        // One ball at the centre holding the whole cube leaves none.
        assert!(!has_room(&parts, &[([0.1, 0.0, 0.0], 0.09)], 0.001));
    }

    /// No room for a ball of 4 mm (so none for a centimetre voxel, which holds one of 5 mm).
    #[test]
    fn the_built_in_robots_leave_no_room_for_a_ball_of_4_mm() {
        for name in ["fetch", "panda"] {
            let robot = Robot::builtin(name).unwrap();
            assert_eq!(robot.spheres().pockets.len(), robot.links().len());
            // Worked out here, not read from a disk cache.
            let pockets: Vec<LinkPockets> = (0..robot.links().len())
                .map(|l| {
                    let spheres: Vec<Sphere> = robot.spheres().link_spheres(l).collect();
                    LinkPockets::new(&robot.links()[l].collision, &spheres, None)
                })
                .collect();
            assert!(pockets.iter().all(|p| !p.has_room_for(0.004)), "{name}");
            if name == "fetch" {
                // The forearm's pocket is found for a small grain.
                let forearm = robot.link_index("forearm_roll_link").unwrap();
                assert!(pockets[forearm].has_room_for(0.0005));
                assert_eq!(pockets[forearm].lock().len(), 2);
                assert!(pockets[forearm].has_room_for(0.0005));
                assert_eq!(pockets[forearm].lock().len(), 2, "asked again");
            }
        }
    }

    /// Answers are kept on disk and read back by a new link with the same content (a file
    /// holding the other answer is believed: it is what was read); a corrupt file is worked
    /// out again and replaced.
    #[test]
    fn answers_round_trip_through_the_disk_cache() {
        let dir = std::env::temp_dir().join(format!("ember-pocket-cache-{}", std::process::id()));
        let shapes = [LinkShape {
            origin: Pose::translation(0.1, 0.0, 0.0),
            geometry: Geometry::Primitive(Shape::cuboid([0.1; 3])),
        }];
        let spheres = [([0.1, 0.0, 0.0], 0.05)];
        let fresh = || LinkPockets::new(&shapes, &spheres, Some(dir.clone()));
        assert!(fresh().has_room_for(0.002));
        let file = std::fs::read_dir(dir.join("pockets-v1"))
            .unwrap()
            .next()
            .unwrap()
            .unwrap()
            .path();
        assert_eq!(read_room(&file), Some(true));
        write_checked(&file, [&MAGIC[..], &[0]].concat()).unwrap();
        assert!(!fresh().has_room_for(0.002), "not read from the file");
        let mut bytes = std::fs::read(&file).unwrap();
        bytes[3] ^= 0xff;
        std::fs::write(&file, &bytes).unwrap();
        assert_eq!(read_room(&file), None);
        assert!(fresh().has_room_for(0.002));
        assert_eq!(read_room(&file), Some(true));
        std::fs::remove_dir_all(&dir).ok();
    }
}

//! Room inside a link that its spheres leave: the spheres cover each link's surface, and
//! nearly always its inside, but not by construction. An obstacle wholly inside a link and
//! clear of its spheres holds a ball (of its inradius) whose centre is inside the link and at
//! least that radius from every sphere. [`has_room`] decides, for a radius `t`, whether any
//! point inside the link's geometry may be `t` or farther from every sphere (a subdivision of
//! the link's box whose cells are cleared by the distance bounds at their centres); when none
//! is, no obstacle holding a ball of radius `t` (a map's voxel of edge `2t`) can hide there.

use super::fit::{Part, Sphere};
use crate::robot::LinkShape;
use rustc_hash::FxHashMap;
use sha2::{Digest, Sha256};
use std::sync::{Arc, Mutex, OnceLock};

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

/// [`has_room`] of one link's geometry and spheres for one radius, kept per process by
/// content (a robot copy holding an object asks again only of the object's link).
fn link_has_room(shapes: &[LinkShape], spheres: &[Sphere], t: f64) -> bool {
    static MEMO: OnceLock<Mutex<FxHashMap<[u8; 32], bool>>> = OnceLock::new();
    let mut h = Sha256::new();
    super::cache::hash_shapes(&mut h, shapes);
    for (c, r) in spheres {
        for v in [c[0], c[1], c[2], *r] {
            h.update(v.to_le_bytes());
        }
    }
    h.update(t.to_le_bytes());
    let key: [u8; 32] = h.finalize().into();
    let memo = MEMO.get_or_init(Default::default);
    if let Some(&room) = memo.lock().unwrap_or_else(|e| e.into_inner()).get(&key) {
        return room;
    }
    let parts: Vec<Part> = shapes.iter().map(Part::new).collect();
    let room = has_room(&parts, spheres, t);
    memo.lock()
        .unwrap_or_else(|e| e.into_inner())
        .insert(key, room);
    room
}

/// Per link, whether an obstacle holding a ball of a given radius may hide inside it
/// ([`has_room`]), worked out on first asking for each radius and kept.
pub struct Pockets {
    /// Per link: its geometry and its spheres (link frame).
    links: Vec<(Vec<LinkShape>, Vec<Sphere>)>,
    asked: Mutex<Vec<(u64, Arc<[bool]>)>>,
}

impl Pockets {
    /// The pockets of links `links` with spheres `spheres(l)` per link.
    pub fn new<'a>(
        links: impl Iterator<Item = &'a [LinkShape]>,
        spheres: impl Fn(usize) -> Vec<Sphere>,
    ) -> Self {
        Pockets {
            links: links
                .enumerate()
                .map(|(l, shapes)| (shapes.to_vec(), spheres(l)))
                .collect(),
            asked: Mutex::new(Vec::new()),
        }
    }

    /// Per link: true when an obstacle holding a ball of radius `t` may lie inside it clear of
    /// its spheres (always false for a link without geometry).
    pub fn room_for(&self, t: f64) -> Arc<[bool]> {
        let key = t.to_bits();
        if let Some((_, room)) = self.lock().iter().find(|(k, _)| *k == key) {
            return room.clone();
        }
        let room: Arc<[bool]> = self
            .links
            .iter()
            .map(|(shapes, spheres)| link_has_room(shapes, spheres, t))
            .collect();
        self.lock().push((key, room.clone()));
        room
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Vec<(u64, Arc<[bool]>)>> {
        // A panic elsewhere while it was held leaves a list that is still whole.
        self.asked.lock().unwrap_or_else(|e| e.into_inner())
    }
}

impl std::fmt::Debug for Pockets {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Pockets")
            .field("links", &self.links.len())
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

    #[test]
    fn the_built_in_robots_leave_no_room_for_a_centimetre_voxel() {
        for name in ["fetch", "panda"] {
            let robot = Robot::builtin(name).unwrap();
            let pockets = Pockets::new(robot.links().iter().map(|l| &l.collision[..]), |l| {
                robot.spheres().link_spheres(l).collect()
            });
            let room = pockets.room_for(0.005);
            assert!(room.iter().all(|r| !r), "{name}: {room:?}");
            assert!(Arc::ptr_eq(&room, &pockets.room_for(0.005)));
            if name == "fetch" {
                // The forearm's pocket (~1.4 mm deep, by sampling) is found for a small grain.
                let forearm = robot.link_index("forearm_roll_link").unwrap();
                let room = pockets.room_for(0.0005);
                assert!(room[forearm], "{room:?}");
            }
        }
    }
}

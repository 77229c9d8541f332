//! FLAME's local primitive: an occupied octobox of the map (4×4×4 leaves: the map's block key and
//! the 64-bit occupancy mask of its leaves), the map's own [`Octobox`].

use crate::world::map::OccupancyMap;
pub use crate::world::map::Octobox;

/// All non-empty octoboxes of a map, in key order.
pub fn octoboxes(map: &OccupancyMap) -> Vec<Octobox> {
    let mut v: Vec<Octobox> = map.octoboxes().collect();
    v.sort_by_key(|o| o.key);
    v
}

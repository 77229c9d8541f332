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

/// [`octoboxes`] of `map` from those of an earlier state (`before`, in key order) and the blocks
/// whose masks changed since: one merge, no pass over the map.
pub fn octoboxes_updated(
    before: &[Octobox],
    map: &OccupancyMap,
    changed: &[crate::world::map::BlockKey],
) -> Vec<Octobox> {
    let mut changed = changed.to_vec();
    changed.sort_unstable();
    changed.dedup();
    let mut out = Vec::with_capacity(before.len() + changed.len());
    let mut old = before.iter().peekable();
    for key in changed {
        while let Some(o) = old.next_if(|o| o.key < key) {
            out.push(*o);
        }
        old.next_if(|o| o.key == key);
        let mask = map.octobox(key);
        if mask != 0 {
            out.push(Octobox { key, mask });
        }
    }
    out.extend(old);
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::world::map::MapParams;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        /// Updating from the changed blocks gives what extracting anew gives.
        #[test]
        fn updated_octoboxes_equal_extracted_ones(
            first in prop::collection::vec(prop::array::uniform3(-20i32..20), 0..60),
            then in prop::collection::vec((prop::array::uniform3(-20i32..20), any::<bool>()), 0..60),
        ) {
            let mut map = OccupancyMap::new(MapParams::default());
            for k in first {
                map.set_voxel(k, true);
            }
            let before = octoboxes(&map);
            let mut changed = Vec::new();
            for (k, occupied) in then {
                map.set_voxel(k, occupied);
                changed.push(k.map(|v| v >> 2));
            }
            prop_assert_eq!(octoboxes_updated(&before, &map, &changed), octoboxes(&map));
        }
    }
}

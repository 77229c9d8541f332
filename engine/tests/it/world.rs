//! The world model: tracked objects carved out of the map, cleared at once, voxelised for FLAME.

use ember_engine::collision::Shape;
use ember_engine::robot::Robot;
use ember_engine::world::map::{MapParams, Occupancy};
use ember_engine::world::model::{World, WorldParams};
use ember_engine::world::Object;
use ember_engine::Pose;

fn world(carve: Option<f64>) -> World {
    World::new(&WorldParams {
        map: MapParams::default(),
        use_map: true,
        self_filter_padding: 0.03,
        carve_padding: carve,
    })
}

/// A box 0.2 m on a side centred at `(x, 0, 1)`.
fn crate_at(x: f64) -> Object {
    Object {
        name: "crate".into(),
        shape: Shape::cuboid([0.2, 0.2, 0.2]),
        pose: Pose::translation(x, 0.0, 1.0),
    }
}

/// Points of a square patch facing the origin at `x`, `n` points 2 cm apart on a side,
/// centred at `(x, y, 1)`.
fn patch(x: f32, y: f32, n: usize) -> Vec<[f32; 3]> {
    let half = 0.01 * (n - 1) as f32;
    (0..n)
        .flat_map(|i| {
            (0..n).map(move |j| [x, y - half + 0.02 * i as f32, 1.0 - half + 0.02 * j as f32])
        })
        .collect()
}

#[test]
fn points_on_tracked_objects_are_carved_and_the_rest_are_obstacles() {
    let robot = Robot::builtin("fetch").unwrap();
    for carve in [Some(0.02), None] {
        let mut sut = world(carve);
        sut.upsert_object(crate_at(1.0));
        // The crate's front face (tracked) and an untracked panel beside it.
        let mut cloud = patch(0.91, 0.0, 11);
        cloud.extend(patch(0.91, 0.6, 15));
        let report = sut.insert_cloud(&robot, &cloud, &Pose::identity());
        let snap = sut.snapshot();
        let map = snap.env.map().expect("the map is an obstacle");
        assert_eq!(map.occupancy([0.91, 0.6, 1.0]), Occupancy::Occupied);
        assert!(
            snap.env.sphere_collides([0.85, 0.6, 1.0], 0.06),
            "the panel blocks"
        );
        match carve {
            Some(_) => {
                assert_eq!(report.carved, 121, "{report:?}");
                assert_eq!(map.occupancy([0.91, 0.0, 1.0]), Occupancy::Free);
            }
            None => {
                assert_eq!(report.carved, 0);
                assert_eq!(map.occupancy([0.91, 0.0, 1.0]), Occupancy::Occupied);
            }
        }
        // FLAME sees the crate either way: voxelised when carved, sensed otherwise.
        let crate_block = map.key_of([1.0, 0.0, 1.0]).map(|v| v >> 2);
        let face_block = map.key_of([0.91, 0.0, 1.0]).map(|v| v >> 2);
        let keys: Vec<_> = snap.octoboxes.iter().map(|o| o.key).collect();
        match carve {
            Some(_) => assert!(
                keys.contains(&crate_block),
                "the crate is in FLAME's octoboxes"
            ),
            None => assert!(keys.contains(&face_block)),
        }
    }
}

#[test]
fn voxels_an_object_comes_to_fill_are_cleared_at_once() {
    let robot = Robot::builtin("fetch").unwrap();
    let mut sut = world(Some(0.02));
    // Seen before anyone tracked it: occupied.
    sut.insert_cloud(&robot, &patch(1.01, 0.0, 5), &Pose::identity());
    let before = sut.snapshot();
    assert_eq!(before.map.occupancy([1.01, 0.0, 1.0]), Occupancy::Occupied);
    // Motion capture reports a crate there: its voxels are cleared with the update, not after
    // clouds of free-space rays; the snapshot taken before keeps its own state.
    sut.upsert_object(crate_at(1.0));
    let after = sut.snapshot();
    assert_eq!(after.map.occupancy([1.01, 0.0, 1.0]), Occupancy::Free);
    assert_eq!(before.map.occupancy([1.01, 0.0, 1.0]), Occupancy::Occupied);
    // The crate moves away: its old voxels stay free, its octoboxes follow it.
    sut.upsert_object(crate_at(1.5));
    let moved = sut.snapshot();
    let old = moved.map.key_of([1.0, 0.0, 1.0]).map(|v| v >> 2);
    let new = moved.map.key_of([1.5, 0.0, 1.0]).map(|v| v >> 2);
    let keys: Vec<_> = moved.octoboxes.iter().map(|o| o.key).collect();
    assert!(keys.contains(&new) && !keys.contains(&old), "{keys:?}");
    sut.remove_object("crate");
    assert!(sut.snapshot().octoboxes.is_empty());
}

//! The occupancy map: insertion semantics, queries, octoboxes, `.bt` files, robot collision.

use ember_engine::collision::SphereChecker;
use ember_engine::robot::spheres::PlacedSpheres;
use ember_engine::robot::Robot;
use ember_engine::world::map::{MapParams, Occupancy, OccupancyMap};
use ember_engine::world::Environment;
use ember_engine::Pose;
use std::sync::Arc;

/// Points on the plane x = `x`, |y|, |z - zc| <= half, every 5 mm.
fn wall(x: f32, zc: f32, half: f32) -> Vec<[f32; 3]> {
    let n = (2.0 * half / 0.005) as i32;
    let mut out = Vec::new();
    for i in 0..=n {
        for j in 0..=n {
            out.push([x, -half + 0.005 * i as f32, zc - half + 0.005 * j as f32]);
        }
    }
    out
}

#[test]
fn wall_seen_from_the_origin_is_occupied_with_free_space_in_front() {
    let mut sut = OccupancyMap::new(MapParams::default());
    let report = sut.insert_cloud(&wall(1.0, 0.0, 0.2), &Pose::identity(), None);
    assert!(report.rays > 100 && report.rays < report.points);
    assert_eq!(sut.occupancy([1.0, 0.0, 0.0]), Occupancy::Occupied);
    assert_eq!(sut.occupancy([1.005, 0.1, -0.1]), Occupancy::Occupied);
    assert_eq!(sut.occupancy([0.5, 0.0, 0.0]), Occupancy::Free);
    assert_eq!(sut.occupancy([0.9, 0.1, 0.1]), Occupancy::Free);
    assert_eq!(
        sut.occupancy([1.1, 0.0, 0.0]),
        Occupancy::Unknown,
        "behind the wall"
    );
    assert_eq!(
        sut.occupancy([0.5, 0.5, 0.0]),
        Occupancy::Unknown,
        "outside the view"
    );
    // One hit: probability 0.7; many hits saturate at the clamping bound.
    let k = sut.key_of([1.0, 0.0, 0.0]);
    assert!((sut.probability(k).unwrap() - 0.7).abs() < 1e-6);
    for _ in 0..10 {
        sut.insert_cloud(&wall(1.0, 0.0, 0.2), &Pose::identity(), None);
    }
    assert!((sut.probability(k).unwrap() - 0.97).abs() < 1e-5);
    let free = sut.key_of([0.5, 0.0, 0.0]);
    assert!((sut.probability(free).unwrap() - 0.12).abs() < 1e-5);
}

#[test]
fn points_beyond_max_range_only_clear() {
    let mut sut = OccupancyMap::new(MapParams {
        max_range: 0.6,
        ..Default::default()
    });
    sut.insert_cloud(&wall(1.0, 0.0, 0.1), &Pose::identity(), None);
    assert_eq!(sut.occupancy([1.0, 0.0, 0.0]), Occupancy::Unknown);
    assert_eq!(sut.occupancy([0.3, 0.0, 0.0]), Occupancy::Free);
    assert_eq!(sut.occupancy([0.7, 0.0, 0.0]), Occupancy::Unknown);
    assert_eq!(sut.occupied_voxels().count(), 0);
}

#[test]
fn keys_floor_on_both_sides_of_zero() {
    let sut = OccupancyMap::new(MapParams::default());
    assert_eq!(sut.key_of([0.0, 0.019, 0.02]), [0, 0, 1]);
    assert_eq!(sut.key_of([-0.001, -0.02, -0.0201]), [-1, -1, -2]);
    assert_eq!(sut.key_of([-1.0e-12, 40.01, -40.01]), [-1, 2000, -2001]);
}

/// Distinct voxel keys of `points` (identity sensor pose) at the default resolution.
fn distinct_voxels(points: &[[f32; 3]]) -> usize {
    let map = OccupancyMap::new(MapParams::default());
    let keys: std::collections::HashSet<_> = points
        .iter()
        .map(|p| map.key_of([p[0] as f64, p[1] as f64, p[2] as f64]))
        .collect();
    keys.len()
}

#[test]
fn discretize_casts_one_ray_per_endpoint_voxel_even_beyond_range() {
    let cloud = wall(1.0, 0.0, 0.2);
    for max_range in [3.0, 0.6] {
        let params = MapParams {
            max_range,
            ..Default::default()
        };
        let mut exact = OccupancyMap::new(params.clone());
        exact.insert_cloud(&cloud, &Pose::identity(), None);
        let mut sut = OccupancyMap::new(MapParams {
            discretize: true,
            ..params
        });
        let report = sut.insert_cloud(&cloud, &Pose::identity(), None);
        // Beyond the range, distinct far voxels still get their own (clipped) ray, as in
        // OctoMap, although many clipped ends share a cell.
        assert_eq!(report.rays, distinct_voxels(&cloud), "range {max_range}");
        // Sorted: the map's own order follows its hash table's layout, which differs between
        // insertion histories (and between x86-64's and aarch64's table groups).
        let occupied = |m: &OccupancyMap| {
            let mut v = m.occupied_voxels().collect::<Vec<_>>();
            v.sort_by(|a, b| a.partial_cmp(b).expect("finite centres"));
            v
        };
        assert_eq!(occupied(&sut), occupied(&exact), "range {max_range}");
        // Rays to voxel centres carve nearly the free space of rays to the points themselves.
        let free: Vec<_> = exact
            .known_voxels()
            .filter(|(_, s)| *s == Occupancy::Free)
            .collect();
        let shared = free
            .iter()
            .filter(|(k, _)| sut.probability(*k).is_some_and(|p| p < 0.5))
            .count();
        assert!(
            shared as f64 > 0.95 * free.len() as f64,
            "range {max_range}: {shared} of {} free voxels shared",
            free.len()
        );
    }
}

#[test]
fn bounds_limit_what_is_stored() {
    let mut sut = OccupancyMap::new(MapParams {
        bounds: Some(([-1.0, -1.0, -1.0], [0.5, 1.0, 1.0])),
        ..Default::default()
    });
    sut.insert_cloud(&wall(1.0, 0.0, 0.1), &Pose::identity(), None);
    assert_eq!(sut.occupancy([1.0, 0.0, 0.0]), Occupancy::Unknown);
    assert_eq!(sut.occupancy([0.4, 0.0, 0.0]), Occupancy::Free);
}

#[test]
fn sensor_pose_places_the_cloud() {
    let mut sut = OccupancyMap::new(MapParams::default());
    let pose = Pose::translation(0.0, 0.0, 1.0);
    sut.insert_cloud(&wall(1.0, 0.0, 0.1), &pose, None);
    assert_eq!(sut.occupancy([1.0, 0.0, 1.0]), Occupancy::Occupied);
}

#[test]
fn octobox_masks_change_only_where_the_scene_changed() {
    let mut sut = OccupancyMap::new(MapParams::default());
    let first = sut.insert_cloud(&wall(1.0, 0.0, 0.3), &Pose::identity(), None);
    assert!(!first.changed.is_empty());
    let boxes: std::collections::HashMap<_, _> = sut.octoboxes().map(|b| (b.key, b.mask)).collect();
    assert_eq!(boxes.len(), first.changed.len());
    // The same view again: nothing changes.
    let again = sut.insert_cloud(&wall(1.0, 0.0, 0.3), &Pose::identity(), None);
    assert!(again.changed.is_empty(), "{:?}", again.changed);
    // A small object appears in front of the wall's lower half: only blocks near it change.
    let mut cloud = wall(1.0, 0.0, 0.3);
    cloud.retain(|p| !(p[1].abs() < 0.05 && p[2].abs() < 0.05));
    cloud.extend(wall(0.7, 0.0, 0.05));
    let mut changed = Vec::new();
    for _ in 0..3 {
        changed.extend(sut.insert_cloud(&cloud, &Pose::identity(), None).changed);
    }
    assert!(!changed.is_empty());
    let size = sut.block_size();
    for k in &changed {
        let c = sut.block_center(*k);
        assert!(
            c[0] > 0.6 - size && c[1].abs() < 0.05 + 2.0 * size && c[2].abs() < 0.05 + 2.0 * size,
            "{c:?}"
        );
    }
    // Every octobox mask bit is an occupied voxel.
    let b = sut.octoboxes().next().unwrap();
    let occupied = (0..64).filter(|bit| b.mask & (1 << bit) != 0).count();
    assert_eq!(occupied as u32, b.mask.count_ones());
}

#[test]
fn bt_file_round_trips() {
    let mut sut = OccupancyMap::new(MapParams::default());
    sut.insert_cloud(&wall(1.0, 0.0, 0.2), &Pose::identity(), None);
    sut.insert_cloud(
        &wall(0.8, 0.5, 0.1),
        &Pose::translation(0.0, 0.0, 0.2),
        None,
    );
    let mut bytes = Vec::new();
    sut.write_bt(&mut bytes).unwrap();
    assert!(bytes.starts_with(b"# Octomap OcTree binary file"));
    let back = OccupancyMap::read_bt(&mut std::io::Cursor::new(&bytes)).unwrap();
    let mut a: Vec<_> = sut.known_voxels().collect();
    let mut b: Vec<_> = back.known_voxels().collect();
    a.sort_by_key(|v| v.0);
    b.sort_by_key(|v| v.0);
    assert_eq!(a.len(), b.len());
    assert_eq!(a, b);
    // And written again, byte for byte the same.
    let mut again = Vec::new();
    back.write_bt(&mut again).unwrap();
    assert_eq!(bytes, again);
}

#[test]
fn bad_bt_files_are_rejected() {
    let mut sut = OccupancyMap::new(MapParams::default());
    sut.insert_cloud(&wall(1.0, 0.0, 0.2), &Pose::identity(), None);
    let mut bytes = Vec::new();
    sut.write_bt(&mut bytes).unwrap();
    let truncated = &bytes[..bytes.len() - 10];
    let err = OccupancyMap::read_bt(&mut std::io::Cursor::new(truncated)).unwrap_err();
    assert!(err.to_string().contains("truncated"), "{err}");
    let err = OccupancyMap::read_bt(&mut std::io::Cursor::new(b"hello\n".as_slice())).unwrap_err();
    assert!(err.to_string().contains("not an OctoMap"), "{err}");
}

#[test]
fn robot_filter_removes_points_on_the_robot() {
    let robot = Robot::builtin("fetch").unwrap();
    let q = robot.named_state("tuck").unwrap();
    let sut = PlacedSpheres::at(&robot, q, 0.02);
    // A point inside the gripper: the centre of its first sphere.
    let li = robot.link_index("gripper_link").unwrap();
    let (c, _) = robot.spheres().link_spheres(li).next().unwrap();
    let gripper = (robot.link_poses(q).unwrap()[li] * nalgebra::Point3::from(c)).coords;
    assert!(sut.contains([gripper.x, gripper.y, gripper.z]));
    assert!(!sut.contains([1.5, 0.0, 1.0]));
    let mut map = OccupancyMap::new(MapParams::default());
    let cloud = [
        [gripper.x as f32, gripper.y as f32, gripper.z as f32],
        [1.5, 0.0, 1.0],
    ];
    let report = map.insert_cloud(&cloud, &Pose::identity(), Some(&sut));
    assert_eq!(report.filtered, 1);
    assert_eq!(
        map.occupancy([gripper.x, gripper.y, gripper.z]),
        Occupancy::Unknown
    );
    assert_eq!(map.occupancy([1.5, 0.0, 1.0]), Occupancy::Occupied);
}

#[test]
fn robot_collides_with_occupied_voxels() {
    let robot = Robot::builtin("fetch").unwrap();
    let mut map = OccupancyMap::new(MapParams::default());
    // A wall of occupied voxels where the straight arm's gripper is.
    map.insert_cloud(
        &wall(1.1, 0.0, 0.15),
        &Pose::translation(0.0, 0.0, 0.78),
        None,
    );
    let mut env = Environment::new();
    env.set_map(Some(Arc::new(map)));
    let mut sut = SphereChecker::new(&robot, &env);
    assert!(!sut.is_valid(&[0.0; 8]));
    assert!(sut.is_valid(robot.named_state("tuck").unwrap()));
    assert!(sut
        .contact(&[0.0; 8])
        .unwrap()
        .to_string()
        .contains("occupancy map"));
}

/// Unknown space in a box made occupied: what was seen stays as it was (free in front of a
/// wall, occupied on it), what was never seen inside the box is occupied, outside it unknown;
/// the copy's clearance grids agree with its voxels, and the map itself is unchanged.
#[test]
fn unknown_space_in_a_box_becomes_occupied_in_a_copy() {
    let mut map = OccupancyMap::new(MapParams::default());
    // A wall at x = 1 seen from the origin: free space in front of it, unknown behind it.
    map.insert_cloud(&wall(1.0, 0.0, 0.2), &Pose::identity(), None);
    let (lo, hi) = ([0.5, -0.1, -0.1], [1.3, 0.1, 0.1]);
    let sut = map.with_unknown_occupied(lo, hi);
    for (p, state, what) in [
        ([0.7, 0.0, 0.0], Occupancy::Free, "seen free"),
        ([1.0, 0.0, 0.0], Occupancy::Occupied, "the wall"),
        ([1.2, 0.0, 0.0], Occupancy::Occupied, "behind it, unseen"),
        ([1.2, 0.3, 0.0], Occupancy::Unknown, "outside the box"),
        ([0.7, 0.5, 0.0], Occupancy::Unknown, "outside the box"),
    ] {
        assert_eq!(sut.occupancy(p), state, "{what} at {p:?}");
    }
    assert_eq!(
        map.occupancy([1.2, 0.0, 0.0]),
        Occupancy::Unknown,
        "the map is unchanged"
    );
    // Every voxel centre in the box is free or occupied now, none unknown.
    let r = map.resolution();
    let mut occupied = 0;
    for i in 0..40 {
        for j in 0..10 {
            for k in 0..10 {
                let p = [
                    lo[0] + r * (i as f64 + 0.5),
                    lo[1] + r * (j as f64 + 0.5),
                    lo[2] + r * (k as f64 + 0.5),
                ];
                let o = sut.occupancy(p);
                assert_ne!(o, Occupancy::Unknown, "{p:?}");
                occupied += (o == Occupancy::Occupied) as usize;
            }
        }
    }
    assert!(occupied > 500, "{occupied} occupied voxels in the box");
    // The grids answer for the copy: a ball behind the wall is not clear, one in front is.
    let grids = sut.clearance().expect("occupied voxels");
    assert!(!grids.clear([1.2, 0.0, 0.0], 0.01));
    assert!(grids.clear([0.6, 0.0, 0.0], 0.05));
    assert!(sut.sphere_collides([1.2, 0.0, 0.0], 0.01));
    assert!(!sut.sphere_collides([0.6, 0.0, 0.0], 0.05));
}

/// Unknown voxels a ball touches inside a box are observed free (one miss), and only those:
/// seen voxels keep their state, unknown ones beyond the ball or outside the box stay unknown.
#[test]
fn unknown_voxels_a_ball_touches_in_a_box_become_free() {
    let mut sut = OccupancyMap::new(MapParams::default());
    // A wall at x = 1 seen from the origin; a ball behind it, reaching into the wall.
    sut.insert_cloud(&wall(1.0, 0.0, 0.2), &Pose::identity(), None);
    let (lo, hi) = ([0.5, -0.2, -0.2], [1.3, 0.0, 0.2]);
    let ball = ([1.1, 0.0, 0.0], 0.08);
    // Two balls touching the same voxels: each block is named once, its masks joined.
    let one = sut.unknown_touched([&ball], lo, hi);
    let both = sut.unknown_touched([&ball, &([1.12, 0.0, 0.0], 0.08)], lo, hi);
    let mut blocks: Vec<_> = both.iter().map(|&(b, _)| b).collect();
    blocks.dedup();
    assert_eq!(blocks.len(), both.len(), "a block named twice");
    for (b, mask) in &one {
        let joined = both.iter().find(|(c, _)| c == b).map_or(0, |&(_, m)| m);
        assert_eq!(
            joined & mask,
            *mask,
            "block {b:?} lost voxels of the first ball"
        );
    }
    let marked = sut.observe_free(&one);
    for (p, state, what) in [
        (
            [1.1, -0.02, 0.0],
            Occupancy::Free,
            "behind the wall, in the ball",
        ),
        (
            [1.16, -0.04, 0.04],
            Occupancy::Free,
            "the ball touches its cube",
        ),
        ([1.0, 0.0, 0.0], Occupancy::Occupied, "the wall stays"),
        (
            [1.1, 0.05, 0.0],
            Occupancy::Unknown,
            "in the ball, outside the box",
        ),
        (
            [1.25, -0.15, 0.0],
            Occupancy::Unknown,
            "in the box, beyond the ball",
        ),
    ] {
        assert_eq!(sut.occupancy(p), state, "{what} at {p:?}");
    }
    assert!(marked > 20, "{marked} marked");
    assert!(sut.unknown_touched([&ball], lo, hi).is_empty(), "once only");
}

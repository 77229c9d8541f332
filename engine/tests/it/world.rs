//! The world model: tracked objects carved out of the map, cleared at once, voxelised for FLAME;
//! objects the robot holds.

use ember_engine::collision::{Shape, SphereChecker};
use ember_engine::robot::Robot;
use ember_engine::world::map::{MapParams, Occupancy};
use ember_engine::world::model::{ChangeError, ObjectChange, World, WorldParams};
use ember_engine::world::Object;
use ember_engine::Pose;

fn world(carve: Option<f64>) -> World {
    World::new(&WorldParams {
        map: MapParams::default(),
        use_map: true,
        self_filter_padding: 0.03,
        carve_padding: carve,
        unknown_obstacles: None,
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

#[test]
fn attaching_moves_an_object_into_the_hand_and_refusals_change_nothing() {
    let robot = Robot::builtin("fetch").unwrap();
    let tip = robot.links()[robot.tip()].name.clone();
    let q = robot.middle();
    let mut sut = world(Some(0.02));
    assert!(
        !sut.set_joints(&robot, q.clone()),
        "no unknown box: no change"
    );
    let can = Object {
        name: "can".into(),
        shape: Shape::Cylinder {
            radius: 0.03,
            half_length: 0.06,
        },
        pose: Pose::translation(1.0, 0.3, 0.8),
    };
    sut.apply(&robot, ObjectChange::Upsert(can.clone()))
        .unwrap();
    let grasp = Pose::translation(0.15, 0.0, 0.0);
    let attach = |id: &str, link: &str, shape: Option<Shape>| ObjectChange::Attach {
        link: link.into(),
        id: id.into(),
        shape,
        grasp,
    };
    sut.apply(&robot, attach("can", &tip, None)).unwrap();
    let held = sut.snapshot();
    assert!(held.scene.objects.is_empty(), "the can left the world");
    assert_eq!(held.scene.attached.len(), 1);
    assert_eq!(held.scene.attached[0].object.shape, can.shape);
    let holding = held.robot(&robot);
    assert_eq!(holding.links().len(), robot.links().len() + 1);

    // The held can is part of the robot for the self-filter: points on it mark nothing.
    let mut poses = vec![Pose::identity(); robot.links().len()];
    robot.forward_kinematics(&q, &mut poses);
    let centre = (poses[robot.tip()] * grasp).translation.vector;
    let on_can: Vec<[f32; 3]> = (0..50)
        .map(|i| {
            let a = i as f64 * 0.125;
            let p = centre + nalgebra::Vector3::new(0.03 * a.cos(), 0.03 * a.sin(), 0.0);
            [p.x as f32, p.y as f32, p.z as f32]
        })
        .collect();
    let report = sut.insert_cloud(&robot, &on_can, &Pose::identity());
    assert_eq!(report.filtered, 50, "{report:?}");

    // Each refusal is typed and leaves the world as it was.
    let big = Shape::cuboid([0.8, 0.8, 0.8]);
    for (change, expected) in [
        (
            attach("can", "no_such_link", None),
            ChangeError::AlreadyAttached("can".into()),
        ),
        (
            attach("cup", "no_such_link", None),
            ChangeError::UnknownLink("no_such_link".into()),
        ),
        (
            attach("ghost", &tip, None),
            ChangeError::UnknownObject("ghost".into()),
        ),
        (
            ObjectChange::Upsert(can.clone()),
            ChangeError::AlreadyAttached("can".into()),
        ),
        (
            ObjectChange::Detach {
                id: "ghost".into(),
                pose: Pose::identity(),
            },
            ChangeError::NotAttached("ghost".into()),
        ),
        (
            ObjectChange::Remove("ghost".into()),
            ChangeError::UnknownObject("ghost".into()),
        ),
    ] {
        let before = sut.snapshot();
        assert_eq!(sut.apply(&robot, change), Err(expected));
        let after = sut.snapshot();
        assert_eq!(after.scene, before.scene);
        assert_eq!(after.objects_version, before.objects_version);
    }
    // A box too large to hold: it would reach back into the arm.
    match sut.apply(&robot, attach("slab", &tip, Some(big))) {
        Err(ChangeError::AttachCollides { object, link }) => {
            assert_eq!(object, "slab");
            assert!(robot.link_index(&link).is_some(), "{link}");
        }
        other => panic!("{other:?}"),
    }
    assert_eq!(sut.snapshot().scene.attached.len(), 1);

    // Detached, the can is a world object again where it was put down; removed, it is gone.
    let down = Pose::translation(0.9, -0.2, 0.75);
    sut.apply(
        &robot,
        ObjectChange::Detach {
            id: "can".into(),
            pose: down,
        },
    )
    .unwrap();
    let snap = sut.snapshot();
    assert!(snap.scene.attached.is_empty() && snap.holding.is_none());
    assert_eq!(
        snap.scene.objects,
        vec![Object {
            pose: down,
            ..can.clone()
        }]
    );
    sut.apply(&robot, attach("can", &tip, None)).unwrap();
    sut.apply(&robot, ObjectChange::Remove("can".into()))
        .unwrap();
    let snap = sut.snapshot();
    assert!(snap.scene.objects.is_empty() && snap.scene.attached.is_empty());
}

/// With a box of unknown space as an obstacle, planning avoids the box until the camera has
/// seen through it; FLAME's map stays the map itself. Without the box, unknown space is free.
#[test]
fn unknown_space_in_the_configured_box_is_an_obstacle_until_seen() {
    let robot = Robot::builtin("fetch").unwrap();
    let params = |unknown| WorldParams {
        map: MapParams::default(),
        use_map: true,
        self_filter_padding: 0.03,
        carve_padding: Some(0.02),
        unknown_obstacles: unknown,
    };
    let inside = [0.7, 0.0, 1.0];
    let mut sut = World::new(&params(Some(([0.6, -0.1, 0.9], [0.8, 0.1, 1.1]))));
    let snap = sut.snapshot();
    assert!(
        snap.env.sphere_collides(inside, 0.01),
        "unseen: an obstacle"
    );
    assert!(
        !snap.env.sphere_collides([0.3, 0.0, 1.0], 0.05),
        "outside the box"
    );
    assert_eq!(
        snap.map.occupancy(inside),
        Occupancy::Unknown,
        "FLAME's map"
    );
    // A wall at x = 1.5 seen from a camera at (0, 0, 1): its rays cross the box.
    let wall: Vec<[f32; 3]> = (0..31)
        .flat_map(|i| (0..31).map(move |j| [1.5, -0.3 + 0.02 * i as f32, -0.3 + 0.02 * j as f32]))
        .collect();
    sut.insert_cloud(&robot, &wall, &Pose::translation(0.0, 0.0, 1.0));
    let snap = sut.snapshot();
    assert!(!snap.env.sphere_collides(inside, 0.01), "seen free");
    assert!(snap.env.sphere_collides([1.5, 0.0, 1.0], 0.01), "the wall");
    // Without the box the same unseen space is free.
    let snap = World::new(&params(None)).snapshot();
    assert!(!snap.env.sphere_collides(inside, 0.01));
}

/// Where unknown space is an obstacle, the robot's own volume in the box is observed free
/// (the self-filter's space: no point can mark it occupied) with its joint state: a start
/// whose arm lies in the unseen box is valid once the joint state is in, while unseen space
/// beside the arm stays an obstacle. An object the robot takes hold of is freed at once.
#[test]
fn the_robots_own_volume_in_the_unknown_box_is_free_at_its_joint_state() {
    let robot = Robot::builtin("fetch").unwrap();
    // The arm straight out in front, the torso a little up; and folded away from the box.
    let q = vec![0.2, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0];
    let away_q = robot.named_state("stow").unwrap().to_vec();
    let tip = robot.tip_pose(&q).unwrap().translation.vector;
    let (lo, hi) = (
        [tip.x - 0.15, tip.y - 0.15, tip.z - 0.15],
        [tip.x + 0.15, tip.y + 0.15, tip.z + 0.15],
    );
    let params = WorldParams {
        map: MapParams::default(),
        use_map: true,
        self_filter_padding: 0.03,
        carve_padding: Some(0.02),
        unknown_obstacles: Some((lo, hi)),
    };
    // A patch behind the camera's back: its rays never reach the box.
    let away = patch(-1.5, 0.0, 5);
    let camera = Pose::translation(0.0, 0.0, 1.0);
    let valid = |world: &World| {
        let snap = world.snapshot();
        SphereChecker::new(&robot, &snap.env).is_valid(&q)
    };
    let mut sut = World::new(&params);
    assert!(
        !sut.set_joints(&robot, away_q.clone()),
        "folded away, the robot touches nothing of the box"
    );
    assert!(
        !valid(&sut),
        "the box is unseen: the arm out there is refused"
    );
    assert!(
        sut.set_joints(&robot, q.clone()),
        "the arm in the box frees its volume"
    );
    assert!(valid(&sut), "the arm's own volume is observed free");
    assert!(!sut.set_joints(&robot, q.clone()), "once only");
    // Unseen space in the box away from the arm is still an obstacle.
    let snap = sut.snapshot();
    let corner = [lo[0] + 0.02, lo[1] + 0.02, lo[2] + 0.02];
    assert!(
        snap.env.sphere_collides(corner, 0.005),
        "unseen beside the arm"
    );
    assert_eq!(
        snap.map.occupancy(tip.into()),
        Occupancy::Free,
        "FLAME's map too"
    );
    // An object held on top of the hand is freed with the attach (no new joint state).
    let grasp = Pose::translation(0.0, 0.0, 0.12);
    let ahead: [f64; 3] = (robot.tip_pose(&q).unwrap() * grasp)
        .translation
        .vector
        .into();
    assert!(
        sut.snapshot().env.sphere_collides(ahead, 0.005),
        "unseen above the hand"
    );
    let tip_link = robot.links()[robot.tip()].name.clone();
    sut.apply(
        &robot,
        ObjectChange::Attach {
            link: tip_link,
            id: "probe".into(),
            shape: Some(Shape::cuboid([0.04, 0.04, 0.04])),
            grasp,
        },
    )
    .unwrap();
    assert_eq!(
        sut.snapshot().map.occupancy(ahead),
        Occupancy::Free,
        "the held object's volume"
    );
    // A cloud frees nothing of the robot's volume: only joint states do.
    let mut clouded = World::new(&params);
    clouded.set_joints(&robot, away_q);
    clouded.insert_cloud(&robot, &away, &camera);
    assert!(!valid(&clouded), "folded away: the box stays unseen");
    // No joint state: no self-filter, nothing freed.
    let mut blind = World::new(&params);
    blind.insert_cloud(&robot, &away, &camera);
    assert!(!valid(&blind));
}

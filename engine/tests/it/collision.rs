//! Collision checking: named states, known collisions, sphere conservativeness, edge checks.

use ember_engine::collision::checker::Contact;
use ember_engine::collision::{parry, Shape, SphereChecker};
use ember_engine::robot::Robot;
use ember_engine::world::{Environment, Object};
use ember_engine::Pose;

#[test]
fn named_states_are_collision_free() {
    let env = Environment::new();
    for (name, state) in [("fetch", "stow"), ("fetch", "tuck"), ("panda", "ready")] {
        let robot = Robot::builtin(name).unwrap();
        let mut sut = SphereChecker::new(&robot, &env);
        let q = robot.named_state(state).unwrap();
        assert_eq!(sut.contact(q), None, "{name} {state}");
        assert!(sut.is_valid(q));
    }
}

fn boxed(name: &str, size: [f64; 3], xyz: [f64; 3]) -> Object {
    Object {
        name: name.into(),
        shape: Shape::cuboid(size),
        pose: Pose::translation(xyz[0], xyz[1], xyz[2]),
    }
}

#[test]
fn known_colliding_configurations_are_reported() {
    let fetch = Robot::builtin("fetch").unwrap();
    // A box where the gripper is with the arm straight out.
    let env =
        Environment::from_objects([boxed("crate", [0.2, 0.2, 0.2], [1.1, 0.0, 0.78])]).unwrap();
    let mut sut = SphereChecker::new(&fetch, &env);
    let straight = [0.0; 8];
    assert!(!sut.is_valid(&straight));
    assert!(matches!(
        sut.contact(&straight),
        Some(Contact::Object { ref object, .. }) if object == "crate"
    ));

    // The forearm folded back into the torso: self-collision, in both models.
    let empty = Environment::new();
    let mut sut = SphereChecker::new(&fetch, &empty);
    let folded = [0.0, 0.0, 0.0, 0.0, 2.25, 0.0, 0.0, 0.0];
    assert!(!sut.is_valid(&folded));
    assert!(matches!(
        sut.contact(&folded),
        Some(Contact::SelfCollision { .. })
    ));

    // The arm pushed down into the base.
    let down = [0.0, 0.0, 1.518, 0.0, 0.0, 0.0, 0.0, 0.0];
    assert!(!sut.is_valid(&down));
}

#[test]
fn an_attached_object_moves_with_the_hand_and_collides_as_part_of_the_robot() {
    let fetch = Robot::builtin("fetch").unwrap();
    let tip = fetch.tip();
    // A 30 cm rod held along the tip's x axis, from 20 to 50 cm in front of it.
    let rod = Shape::cuboid([0.3, 0.04, 0.04]);
    let sut = fetch.with_attached(tip, "rod", rod, Pose::translation(0.35, 0.0, 0.0));
    assert_eq!(sut.links().len(), fetch.links().len() + 1);
    let straight = [0.0; 8];
    let mut poses = vec![Pose::identity(); sut.links().len()];
    sut.forward_kinematics(&straight, &mut poses);
    assert_eq!(
        poses.last().unwrap(),
        &poses[tip],
        "the rod moves with the tip"
    );

    // A block 45 cm in front of the tip: beyond the bare hand, on the held rod.
    let at = poses[tip] * nalgebra::Point3::new(0.45, 0.0, 0.0);
    let env = Environment::from_objects([boxed("block", [0.06; 3], [at.x, at.y, at.z])]).unwrap();
    assert!(SphereChecker::new(&fetch, &env).is_valid(&straight));
    let mut checker = SphereChecker::new(&sut, &env);
    assert!(matches!(
        checker.contact(&straight),
        Some(Contact::Object { ref object, .. }) if object == "block"
    ));
    // The hand that holds it may touch it: no self-collision in free space.
    assert!(SphereChecker::new(&sut, &Environment::new()).is_valid(&straight));

    // Held backwards along the forearm it collides with the arm itself.
    let back = fetch.with_attached(tip, "rod", rod, Pose::translation(-0.35, 0.0, 0.0));
    assert!(matches!(
        SphereChecker::new(&back, &Environment::new()).contact(&straight),
        Some(Contact::SelfCollision { .. })
    ));
}

#[test]
fn static_body_in_collision_blocks_every_configuration() {
    let fetch = Robot::builtin("fetch").unwrap();
    let env =
        Environment::from_objects([boxed("pillar", [0.1, 0.1, 1.0], [0.0, 0.0, 0.5])]).unwrap();
    let mut sut = SphereChecker::new(&fetch, &env);
    let stow = fetch.named_state("stow").unwrap();
    assert!(!sut.is_valid(stow));
    assert!(matches!(
        sut.contact(stow),
        Some(Contact::Object { ref link, .. }) if link == "base_link"
    ));
}

#[test]
fn edge_check_catches_thin_obstacle_between_free_configurations() {
    let panda = Robot::builtin("panda").unwrap();
    let ready = panda.named_state("ready").unwrap().to_vec();
    // A 1 cm plate in the x-z plane in front of the robot, which the hand sweeps through when
    // joint 1 turns from -0.8 to 0.8.
    let env =
        Environment::from_objects([boxed("plate", [0.6, 0.01, 0.4], [0.5, 0.0, 0.5])]).unwrap();
    let mut sut = SphereChecker::new(&panda, &env);
    let mut a = ready.clone();
    a[0] = -0.8;
    let mut b = ready.clone();
    b[0] = 0.8;
    assert!(sut.is_valid(&a) && sut.is_valid(&b));
    assert!(!sut.motion_valid(&a, &b));
    // Moving on one side of the plate is fine.
    let mut c = ready.clone();
    c[0] = -0.72;
    assert!(sut.motion_valid(&a, &c));
}

/// Where the exact primitives penetrate an obstacle, the sphere model reports a collision too.
/// Random configurations and random obstacles placed near a moving link; a seeded loop rather
/// than proptest so the share of real contacts can be asserted (the test must bite).
#[test]
fn sphere_model_is_conservative() {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(7);
    for robot_name in ["fetch", "panda"] {
        let robot = Robot::builtin(robot_name).unwrap();
        let moving: Vec<usize> = (0..robot.links().len())
            .filter(|&l| robot.link_moves(l) && !robot.links()[l].collision.is_empty())
            .collect();
        let mut contacts = 0;
        let cases = 600;
        for _ in 0..cases {
            let mut q = vec![0.0; robot.dof()];
            robot.sample_uniform(&mut rng, &mut q);
            let poses = robot.link_poses(&q).unwrap();
            let near = poses[moving[rng.random_range(0..moving.len())]]
                .translation
                .vector;
            let d = [0, 1, 2].map(|_| rng.random_range(0.02..0.25));
            let kind = rng.random_range(0..4);
            let shape = |shrink: f64| match kind {
                0 => Shape::Sphere {
                    radius: d[0] - shrink,
                },
                1 => Shape::Box {
                    half_extents: [d[0] - shrink, d[1] - shrink, d[2] - shrink],
                },
                2 => Shape::Cylinder {
                    radius: d[0] - shrink,
                    half_length: d[1] - shrink,
                },
                _ => Shape::Capsule {
                    radius: d[0] - shrink,
                    half_length: d[1],
                },
            };
            let pose = Pose::from_parts(
                nalgebra::Translation3::new(
                    near.x + rng.random_range(-0.3..0.3),
                    near.y + rng.random_range(-0.3..0.3),
                    near.z + rng.random_range(-0.3..0.3),
                ),
                nalgebra::UnitQuaternion::from_euler_angles(
                    rng.random_range(-3.0..3.0),
                    rng.random_range(-3.0..3.0),
                    rng.random_range(-3.0..3.0),
                ),
            );
            // Shrunk by 1 mm for the exact test, so a contact it reports is a real penetration.
            let probe = Object {
                name: "probe".into(),
                shape: shape(0.001),
                pose,
            };
            if parry::robot_object_distance(&robot, &poses, &probe) > 0.0 {
                continue;
            }
            contacts += 1;
            let env = Environment::from_objects([Object {
                name: "o".into(),
                shape: shape(0.0),
                pose,
            }])
            .unwrap();
            let mut sut = SphereChecker::new(&robot, &env);
            assert!(
                !sut.is_valid(&q),
                "{robot_name}: exact contact missed by spheres at {q:?}, {probe:?}"
            );
        }
        assert!(
            contacts > cases / 10,
            "{robot_name}: only {contacts} contacts; the test does not bite"
        );
    }
}

/// A random scene of `n` objects of every kind within reach of the robot.
fn random_scene(rng: &mut impl rand::Rng, n: usize) -> Environment {
    let objects = (0..n).map(|i| {
        let shape = match i % 4 {
            0 => Shape::cuboid([
                rng.random_range(0.05..0.6),
                rng.random_range(0.05..0.6),
                rng.random_range(0.02..0.4),
            ]),
            1 => Shape::Cylinder {
                radius: rng.random_range(0.02..0.2),
                half_length: rng.random_range(0.05..0.3),
            },
            2 => Shape::Sphere {
                radius: rng.random_range(0.03..0.2),
            },
            _ => Shape::Capsule {
                radius: rng.random_range(0.02..0.15),
                half_length: rng.random_range(0.05..0.3),
            },
        };
        let t = nalgebra::Translation3::new(
            rng.random_range(-0.3..1.3),
            rng.random_range(-1.0..1.0),
            rng.random_range(0.0..1.6),
        );
        let axis = nalgebra::Vector3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        let r = nalgebra::UnitQuaternion::from_scaled_axis(axis);
        Object {
            name: format!("o{i}"),
            shape,
            pose: Pose::from_parts(t, r),
        }
    });
    Environment::from_objects(objects).unwrap()
}

/// An occupancy map of a few random clumps of occupied voxels (2 cm) within reach of the robot.
fn random_map(rng: &mut impl rand::Rng) -> std::sync::Arc<ember_engine::world::map::OccupancyMap> {
    use ember_engine::world::map::{MapParams, OccupancyMap};
    let mut map = OccupancyMap::new(MapParams::default());
    for _ in 0..rng.random_range(1..5) {
        let c = [
            rng.random_range(-15..65),
            rng.random_range(-50..50),
            rng.random_range(0..80),
        ];
        let h = [0, 1, 2].map(|_| rng.random_range(0..8));
        for x in -h[0]..=h[0] {
            for y in -h[1]..=h[1] {
                for z in -h[2]..=h[2] {
                    if rng.random_bool(0.7) {
                        map.set_voxel([c[0] + x, c[1] + y, c[2] + z], true);
                    }
                }
            }
        }
    }
    std::sync::Arc::new(map)
}

/// A random scene of `n` objects, with a random map when `with_map`, for the batch checker:
/// `None` when the robot's base touches an object (the scalar checker decides that once,
/// exactly, and the planner does not use the batch checker then).
fn batch_scene(
    rng: &mut impl rand::Rng,
    robot: &Robot,
    n: usize,
    with_map: bool,
) -> Option<Environment> {
    let mut env = random_scene(rng, n);
    if with_map {
        env.set_map(Some(random_map(rng)));
    }
    (!SphereChecker::new(robot, &env).blocked()).then_some(env)
}

/// The eight-lane checker against the scalar one (the oracle) on random scenes and
/// configurations, half of them with an occupancy map: it never misses a contact the scalar
/// checker finds, and it flags a free configuration only at the margin's edge (rarely).
/// Configurations are checked one per batch (all lanes equal, and as one state) for
/// per-configuration verdicts, and eight different ones per batch for the lanes' independence.
#[test]
fn batch_checker_agrees_with_the_scalar_checker() {
    use rand::SeedableRng;
    let mut rng = rand::rngs::StdRng::seed_from_u64(11);
    for name in ["fetch", "panda"] {
        batch_agrees(name, &Robot::builtin(name).unwrap(), &mut rng);
    }
}

/// [`batch_checker_agrees_with_the_scalar_checker`] on a robot whose joints slide: the test
/// robot with its first joint lifting the arm (no turn above it, so its rotation is written
/// once) and its last sliding along the turning link before it.
#[test]
fn batch_checker_agrees_on_sliding_joints() {
    use rand::SeedableRng;
    let bot = crate::robot::testbot::write_variant("slides", false);
    let mut urdf = std::fs::read_to_string(&bot.urdf).unwrap();
    for (joint, parent, child, z, axis, upper) in [
        ("joint1", "base_link", "link1", 0.2, "0 0 1", 0.6),
        ("joint3", "link2", "tool", 0.4, "1 0 0", 0.9),
    ] {
        let start = urdf.find(&format!(r#"<joint name="{joint}""#)).unwrap();
        let end = start + urdf[start..].find("</joint>").unwrap();
        urdf.replace_range(
            start..end,
            &format!(
                r#"<joint name="{joint}" type="prismatic">
    <parent link="{parent}"/><child link="{child}"/><origin xyz="0 0 {z}" rpy="0 0 0"/>
    <axis xyz="{axis}"/><limit lower="-0.1" upper="{upper}" effort="1" velocity="1"/>
  "#
            ),
        );
    }
    assert_eq!(urdf.matches("prismatic").count(), 2, "{urdf}");
    std::fs::write(&bot.urdf, urdf).unwrap();
    let robot = crate::robot::spec(&bot).load().unwrap();
    let mut rng = rand::rngs::StdRng::seed_from_u64(12);
    batch_agrees("sliding testbot", &robot, &mut rng);
}

/// The eight-lane checker against the scalar one (the oracle) for `robot` on random scenes
/// and configurations: see [`batch_checker_agrees_with_the_scalar_checker`].
fn batch_agrees(name: &str, robot: &Robot, rng: &mut rand::rngs::StdRng) {
    use ember_engine::collision::batch::{lanes::F8, BatchChecker};
    let dof = robot.dof();
    let (mut configs, mut contacts, mut extra) = (0, 0, 0);
    for scene in 0..30 {
        let objects = (4 + scene % 6) * (scene % 3).min(1);
        let Some(env) = batch_scene(rng, robot, objects, scene % 3 != 1) else {
            continue;
        };
        let mut scalar = SphereChecker::new(robot, &env);
        let mut batch = BatchChecker::new(robot, &env);
        let mut q = vec![vec![0.0; dof]; 8];
        for _ in 0..150 {
            for qi in q.iter_mut() {
                robot.sample_uniform(rng, qi);
            }
            let verdicts: Vec<bool> = q.iter().map(|qi| scalar.is_valid(qi)).collect();
            for (qi, &valid) in q.iter().zip(&verdicts) {
                let lanes: Vec<F8> = (0..dof).map(|j| F8::splat(qi[j] as f32)).collect();
                let flagged = batch.may_collide(&lanes);
                // The same state given once, its map walks done in one lane only.
                assert_eq!(batch.state_may_collide(qi), flagged, "{name}: one state");
                configs += 1;
                if !valid {
                    contacts += 1;
                    assert!(
                        flagged,
                        "{name}: a contact missed at {qi:?}: {:?}",
                        scalar.contact(qi)
                    );
                } else if flagged {
                    extra += 1;
                }
            }
            let lanes: Vec<F8> = (0..dof)
                .map(|j| F8(std::array::from_fn(|k| q[k][j] as f32)))
                .collect();
            assert_eq!(
                batch.may_collide(&lanes),
                verdicts.iter().any(|v| !v) || {
                    // Free in the scalar checker: the batch may only err at the margin,
                    // which the per-configuration runs above counted.
                    q.iter().any(|qi| {
                        let l: Vec<F8> = (0..dof).map(|j| F8::splat(qi[j] as f32)).collect();
                        batch.may_collide(&l)
                    })
                },
                "{name}: lanes are not independent"
            );
        }
    }
    eprintln!("{name}: {configs} configurations, {contacts} in contact, {extra} flagged free");
    // The test must bite: a good share of real contacts, and the margin rarely matters.
    assert!(
        contacts * 6 > configs,
        "{name}: {contacts} contacts in {configs}"
    );
    assert!(
        extra * 200 < configs,
        "{name}: {extra} of {configs} flagged free configs"
    );
}

/// The eight-lane checker tries the spheres of its last contacts first in each batch: a
/// checker with a history answers every batch as a fresh one does, on random walks (whose
/// neighbouring batches hit the same obstacles with the same spheres, as a search's do), with
/// and without a map.
#[test]
fn batch_checker_with_a_history_answers_as_a_fresh_one() {
    use ember_engine::collision::batch::{lanes::F8, BatchChecker};
    use rand::SeedableRng;
    let mut rng = rand::rngs::StdRng::seed_from_u64(5);
    for name in ["fetch", "panda"] {
        let robot = Robot::builtin(name).unwrap();
        let dof = robot.dof();
        let (mut batches, mut contacts) = (0, 0);
        for scene in 0..12 {
            let Some(env) = batch_scene(&mut rng, &robot, 6 + scene % 5, scene % 2 == 0) else {
                continue;
            };
            let mut batch = BatchChecker::new(&robot, &env);
            let mut q = vec![0.0; dof];
            robot.sample_uniform(&mut rng, &mut q);
            let mut step = vec![0.0; dof];
            for _ in 0..60 {
                // A tenth of the way to a random configuration: inside the limits.
                robot.sample_uniform(&mut rng, &mut step);
                for j in 0..dof {
                    q[j] += 0.1 * (step[j] - q[j]);
                }
                let lanes: Vec<F8> = (0..dof)
                    .map(|j| F8(std::array::from_fn(|k| (q[j] + 0.01 * k as f64) as f32)))
                    .collect();
                let with_history = batch.may_collide(&lanes);
                let fresh = BatchChecker::new(&robot, &env).may_collide(&lanes);
                assert_eq!(with_history, fresh, "{name}, scene {scene}: at {q:?}");
                batches += 1;
                contacts += usize::from(fresh);
            }
        }
        // The test must bite: runs of contacts, where the history is used, and free batches.
        assert!(
            contacts * 4 > batches && contacts * 4 < 3 * batches,
            "{name}: {contacts} contacts in {batches} batches"
        );
    }
}

/// A motion's verdict does not depend on the checker's history either: the remembered
/// contacts are tried on a motion's first batch, and skipped on the batches after a free one;
/// a long-lived checker answers every motion between free states as a fresh one does, and
/// finds a small ball that only a batch after the first one reaches.
#[test]
fn a_motion_is_answered_as_a_fresh_checker_answers_it() {
    use ember_engine::collision::batch::BatchChecker;
    use ember_engine::collision::checker::{bisection_order, motion_steps, DEFAULT_RESOLUTION};
    use rand::SeedableRng;
    let mut rng = rand::rngs::StdRng::seed_from_u64(8);
    for name in ["fetch", "panda"] {
        let robot = Robot::builtin(name).unwrap();
        let (mut motions, mut contacts, mut balls) = (0, 0, 0);
        for scene in 0..10 {
            let Some(env) = batch_scene(&mut rng, &robot, 4 + scene % 4, false) else {
                continue;
            };
            let mut batch = BatchChecker::new(&robot, &env);
            let mut free_state = |batch: &mut BatchChecker| {
                let mut q = vec![0.0; robot.dof()];
                (0..100).find_map(|_| {
                    robot.sample_uniform(&mut rng, &mut q);
                    (!batch.state_may_collide(&q)).then(|| q.clone())
                })
            };
            for _ in 0..30 {
                // Between free states: dozens of states, several batches, and obstacles that
                // only the states between the first batch's may meet.
                let (Some(a), Some(b)) = (free_state(&mut batch), free_state(&mut batch)) else {
                    continue;
                };
                let ends = (&a[..], &b[..]);
                let with_history = batch.motion_may_collide(&robot, DEFAULT_RESOLUTION, ends, true);
                let fresh = BatchChecker::new(&robot, &env).motion_may_collide(
                    &robot,
                    DEFAULT_RESOLUTION,
                    ends,
                    true,
                );
                assert_eq!(with_history, fresh, "{name}, scene {scene}: {a:?} to {b:?}");
                motions += 1;
                contacts += usize::from(fresh);
                if fresh {
                    continue;
                }
                // A free motion with a small ball put on the tip's link where the second batch's
                // first state has it: the first batch (the end state and seven states spread
                // over the motion) misses it, a later one must find it.
                let n = motion_steps(&robot, &a, &b, DEFAULT_RESOLUTION);
                let Some(k) = bisection_order(n).nth(7) else {
                    continue;
                };
                let mut q = a.clone();
                robot.interpolate(&a, &b, k as f64 / n as f64, &mut q);
                // The centre of the last moving link's first sphere (the tip frame may lie
                // in the air between fingers).
                let model = robot.spheres();
                let s = (0..model.link.len())
                    .rev()
                    .find(|&s| robot.link_moves(model.link[s] as usize))
                    .map(|s| model.ranges[model.link[s] as usize].start)
                    .unwrap();
                let pose = robot.link_poses(&q).unwrap()[model.link[s] as usize];
                let tip = pose * nalgebra::Point3::from(model.center[s]);
                let mut crowded = env.clone();
                crowded
                    .add(Object {
                        name: "ball".into(),
                        shape: Shape::Sphere { radius: 0.02 },
                        pose: Pose::translation(tip.x, tip.y, tip.z),
                    })
                    .unwrap();
                let mut later = BatchChecker::new(&robot, &crowded);
                if later.state_may_collide(&a) || later.state_may_collide(&b) {
                    continue;
                }
                // The history of the free motion above first, as a search would have it.
                later.motion_may_collide(&robot, DEFAULT_RESOLUTION, (&b, &a), true);
                assert!(
                    later.motion_may_collide(&robot, DEFAULT_RESOLUTION, ends, true),
                    "{name}, scene {scene}: the ball at a later batch's state missed"
                );
                balls += 1;
            }
        }
        eprintln!("{name}: {contacts} contacts in {motions} motions, {balls} balls");
        // The test must bite: free motions (whose later batches skip the history), motions
        // in contact, and balls found by the batches after a free first one.
        assert!(
            contacts * 5 > motions && contacts * 5 < 4 * motions && balls * 4 > motions,
            "{name}: {contacts} contacts in {motions} motions, {balls} balls"
        );
    }
}

/// A motion checked with a decision: each state of a flagged batch is checked again alone, and
/// exactly the states the lanes flag alone are handed to the decision (Panda: no continuous
/// joints, so a state alone is the same numbers as in its batch). With a decision that clears
/// everything the motion is free; with one that clears nothing it is what the lanes say.
#[test]
fn a_decided_motion_asks_about_each_state_the_lanes_flag_alone() {
    use ember_engine::collision::batch::BatchChecker;
    use ember_engine::collision::checker::DEFAULT_RESOLUTION;
    use rand::SeedableRng;
    let mut rng = rand::rngs::StdRng::seed_from_u64(17);
    let robot = Robot::builtin("panda").unwrap();
    let dof = robot.dof();
    let (mut motions, mut decided) = (0, 0);
    for scene in 0..10 {
        let Some(env) = batch_scene(&mut rng, &robot, 5 + scene % 4, true) else {
            continue;
        };
        let mut batch = BatchChecker::new(&robot, &env);
        let (mut a, mut b) = (vec![0.0; dof], vec![0.0; dof]);
        for _ in 0..20 {
            robot.sample_uniform(&mut rng, &mut a);
            robot.sample_uniform(&mut rng, &mut b);
            let ends = (a.as_slice(), b.as_slice());
            let mut asked = Vec::new();
            let free = batch.motion_free(
                &robot,
                DEFAULT_RESOLUTION,
                ends,
                true,
                Some(|_: &mut BatchChecker, k, n| {
                    asked.push((k, n));
                    true
                }),
            );
            assert!(free, "a decision that clears everything clears the motion");
            let mut q = vec![0.0; dof];
            let n =
                ember_engine::collision::checker::motion_steps(&robot, &a, &b, DEFAULT_RESOLUTION)
                    .max(1);
            let mut flagged: Vec<(usize, usize)> = (1..=n)
                .filter(|&k| {
                    robot.interpolate(&a, &b, k as f64 / n as f64, &mut q);
                    batch.state_may_collide(&q)
                })
                .map(|k| (k, n))
                .collect();
            asked.sort_unstable();
            flagged.sort_unstable();
            assert_eq!(asked, flagged, "the states handed to the decision");
            let refused = !batch.motion_free(
                &robot,
                DEFAULT_RESOLUTION,
                ends,
                true,
                Some(|_: &mut BatchChecker, _, _| false),
            );
            assert_eq!(
                refused,
                batch.motion_may_collide(&robot, DEFAULT_RESOLUTION, ends, true)
            );
            motions += 1;
            decided += usize::from(!asked.is_empty());
        }
    }
    // The test must bite: motions with states to decide, and motions without.
    assert!(
        decided * 5 > motions && decided < motions,
        "{decided} of {motions}"
    );
}

/// The balls inside the geometry (each fitted sphere less its link's protrusion) never touch
/// what the exact geometry does not, on random scenes with and without a map, for the Fetch
/// and the Panda; and they find a good share of the exact contacts (what the planner saves:
/// a state they find in contact skips the exact checker).
#[test]
fn balls_inside_the_geometry_touch_only_what_it_touches() {
    use ember_engine::collision::batch::BatchChecker;
    use ember_engine::collision::exact::ExactChecker;
    use rand::SeedableRng;
    let mut rng = rand::rngs::StdRng::seed_from_u64(23);
    for name in ["fetch", "panda"] {
        let robot = Robot::builtin(name).unwrap();
        let mut q = vec![0.0; robot.dof()];
        let (mut sure, mut contacts) = (0, 0);
        for scene in 0..24 {
            let Some(env) = batch_scene(&mut rng, &robot, 4 + scene % 6, scene % 2 == 0) else {
                continue;
            };
            let mut batch = BatchChecker::new(&robot, &env);
            let mut exact = ExactChecker::new(&robot, &env);
            for _ in 0..100 {
                robot.sample_uniform(&mut rng, &mut q);
                let contact = exact.contact(&q);
                if batch.state_surely_collides(&q) {
                    assert!(contact.is_some(), "{name}: sure of a contact at {q:?}");
                    sure += 1;
                }
                contacts += usize::from(contact.is_some());
            }
        }
        eprintln!("{name}: {sure} of {contacts} exact contacts found by the inner balls");
        // The test must bite: contacts, most of them found.
        assert!(
            contacts > 200 && sure * 2 > contacts,
            "{name}: {sure} of {contacts}"
        );
    }
}

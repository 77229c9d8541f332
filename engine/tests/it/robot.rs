//! Robots as users bring them: URDF with meshes and an SRDF; what Ember makes of them, and the
//! sentences it refuses bad ones with.

include!("../../../tests/fixtures/testbot.rs");

use ember_engine::collision::checker::{Contact, DEFAULT_RESOLUTION};
use ember_engine::collision::exact::ExactChecker;
use ember_engine::collision::{Shape, SphereChecker};
use ember_engine::planning::{
    self, path_is_valid, Goal, PlanError, PlanRequest, PlannerParams, UniformSampler,
};
use ember_engine::robot::spheres::{cache::SphereCache, measure};
use ember_engine::robot::srdf::{Group, Srdf};
use ember_engine::robot::{self_collision, Geometry, Robot, RobotSpec};
use ember_engine::world::{Environment, Object};
use ember_engine::Pose;
use testbot::Testbot;

pub(crate) fn spec(bot: &Testbot) -> RobotSpec {
    RobotSpec {
        robot: bot.urdf.display().to_string(),
        srdf: Some(bot.srdf.clone()),
        package_paths: vec![bot.packages.clone()],
        sphere_cache: SphereCache::Dir(bot.packages.join("cache")),
        ..Default::default()
    }
}

fn load(bot: &Testbot) -> Robot {
    spec(bot).load().unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn a_mesh_robot_loads_from_every_format() {
    let bot = testbot::write("formats");
    let robot = load(&bot);
    assert_eq!(robot.group_name(), "arm");
    let names: Vec<&str> = robot.variables().iter().map(|v| v.name.as_str()).collect();
    assert_eq!(names, ["joint1", "joint2", "joint3"]);
    assert_eq!(robot.links()[robot.tip()].name, "tool");
    assert_eq!(robot.named_state("bent"), Some([0.5, 0.8, 0.8].as_slice()));
    // Every mesh became a hull of the box it holds (the millimetre one scaled to metres).
    for (link, size) in [
        ("base_link", [0.4, 0.4, 0.2]),
        ("link1", [0.1, 0.1, 0.4]),
        ("link2", [0.08, 0.08, 0.4]),
        ("tool", [0.06, 0.06, 0.1]),
    ] {
        let l = &robot.links()[robot.link_index(link).unwrap()];
        let Geometry::Convex(hull) = &l.collision[0].geometry else {
            panic!("{link} is not a mesh")
        };
        let (lo, hi) = hull.aabb();
        for k in 0..3 {
            assert!(
                (hi[k] - lo[k] - size[k]).abs() < 1e-5,
                "{link}: {lo:?} {hi:?}"
            );
        }
    }
    // Two collision elements on the tool: the mesh and the sphere.
    let tool = &robot.links()[robot.link_index("tool").unwrap()];
    assert!(matches!(
        tool.collision[1].geometry,
        Geometry::Primitive(Shape::Sphere { .. })
    ));
    // The SRDF's pair naming a link the URDF lacks is a warning, as in MoveIt.
    let info = robot.load_info();
    assert!(
        info.warnings.iter().any(|w| w.contains("ghost_link")),
        "{:?}",
        info.warnings
    );
    assert_eq!(info.meshes.len(), 4);
    // Adjacent links are not checked; the camera is (it is not disabled against the arm).
    let pairs: Vec<(String, String)> = robot
        .self_collision_pairs()
        .iter()
        .map(|&(a, b)| (robot.links()[a].name.clone(), robot.links()[b].name.clone()))
        .collect();
    assert!(!pairs.contains(&("base_link".into(), "link1".into())));
    assert!(pairs
        .iter()
        .any(|(a, b)| a == "camera_link" || b == "camera_link"));
    std::fs::remove_dir_all(&bot.packages).ok();
}

/// Each link with geometry: its index and its spheres' measured protrusion (their coverage of
/// the geometry asserted whole).
fn link_protrusions(robot: &Robot) -> Vec<(usize, f64)> {
    let with_geometry = robot.links().iter().enumerate();
    with_geometry
        .filter(|(_, link)| !link.collision.is_empty())
        .map(|(i, link)| {
            let spheres: Vec<_> = robot.spheres().link_spheres(i).collect();
            let q = measure(&link.collision, &spheres, 3000, 1);
            assert_eq!(q.coverage, 1.0, "{}: {q:?}", link.name);
            (i, q.protrusion)
        })
        .collect()
}

#[test]
fn fitted_spheres_cover_the_meshes_within_the_protrusion() {
    let bot = testbot::write("spheres");
    for protrusion in [0.01, 0.02] {
        let robot = RobotSpec {
            protrusion: Some(protrusion),
            ..spec(&bot)
        }
        .load()
        .unwrap();
        for (i, p) in link_protrusions(&robot) {
            assert!(p <= protrusion + 1e-6, "{}: {p}", robot.links()[i].name);
        }
    }
    // A tighter bound on the hand (the tip link and the links below it) applies there only.
    let robot = RobotSpec {
        protrusion: Some(0.02),
        hand_protrusion: Some(0.005),
        ..spec(&bot)
    }
    .load()
    .unwrap();
    let hand: Vec<usize> = robot.hand_links().collect();
    assert!(hand.contains(&robot.tip()) && hand.len() < robot.links().len());
    let mut coarse_elsewhere = false;
    for (i, p) in link_protrusions(&robot) {
        if hand.contains(&i) {
            assert!(
                p <= 0.005 + 1e-6,
                "hand link {}: {p}",
                robot.links()[i].name
            );
        } else {
            coarse_elsewhere |= p > 0.01;
        }
    }
    assert!(coarse_elsewhere, "the arm's links kept the 2 cm bound");
    // A second load reads the disk cache instead of fitting (a protrusion no other test uses,
    // on the hand too, so no other test refills the in-process memo meanwhile).
    let odd = RobotSpec {
        protrusion: Some(0.0137),
        hand_protrusion: Some(0.0137),
        ..spec(&bot)
    };
    assert!(odd.load().unwrap().spheres().build.fitted > 0);
    ember_engine::robot::spheres::cache::clear_memory();
    let again = odd.load().unwrap();
    assert_eq!(
        again.spheres().build.fitted,
        0,
        "{:?}",
        again.spheres().build
    );
    assert!(again.spheres().build.from_disk > 0);
    std::fs::remove_dir_all(&bot.packages).ok();
}

#[test]
fn joints_outside_the_group_take_the_start_state() {
    let bot = testbot::write("passive");
    let robot = load(&bot);
    assert_eq!(robot.passive_joints().len(), 1);
    let camera = robot.link_index("camera_link").unwrap();
    let q = [0.0; 3];
    let before = robot.link_poses(&q).unwrap()[camera];
    let turned = robot
        .with_joint_values([
            ("camera_joint", 1.0),
            ("joint1", 2.0),
            ("no_such_joint", 3.0),
        ])
        .unwrap();
    let after = turned.link_poses(&q).unwrap()[camera];
    assert!((before.rotation.angle() - 0.0).abs() < 1e-12);
    assert!((after.rotation.angle() - 1.0).abs() < 1e-9);
    // Group joints are the configuration's, not the start state's.
    assert_eq!(
        turned.link_poses(&q).unwrap()[robot.link_index("link1").unwrap()],
        robot.link_poses(&q).unwrap()[robot.link_index("link1").unwrap()]
    );
    assert!(robot
        .with_joint_values([("camera_joint", f64::NAN)])
        .is_err());
    std::fs::remove_dir_all(&bot.packages).ok();
}

/// Links that never move apart (here the camera, on a joint outside the group) and overlap
/// block every configuration, named; the same pair listed as allowed to touch blocks nothing.
#[test]
fn overlapping_links_that_never_move_apart_block_every_configuration() {
    let bot = testbot::write("fixedpair");
    // The camera box pushed into the base box.
    let urdf = std::fs::read_to_string(&bot.urdf).unwrap();
    let sunk = urdf.replace(
        r#"<origin xyz="0.25 0 0" rpy="0 0 0"/><geometry><box size="0.05"#,
        r#"<origin xyz="0.15 0 0" rpy="0 0 0"/><geometry><box size="0.05"#,
    );
    assert_ne!(sunk, urdf);
    std::fs::write(&bot.urdf, sunk).unwrap();
    let allowed = load(&bot);
    let env = Environment::new();
    assert_eq!(ExactChecker::new(&allowed, &env).static_contact(), None);
    let srdf = std::fs::read_to_string(&bot.srdf).unwrap();
    let pair = r#"<disable_collisions link1="base_link" link2="camera_link" reason="Adjacent"/>"#;
    assert!(srdf.contains(pair));
    std::fs::write(&bot.srdf, srdf.replace(pair, "")).unwrap();
    let robot = load(&bot);
    let contact = ExactChecker::new(&robot, &env).static_contact().cloned();
    let named = |c: &Contact| {
        matches!(c, Contact::SelfCollision { link_a, link_b }
        if [link_a.as_str(), link_b.as_str()] == ["base_link", "camera_link"]
            || [link_a.as_str(), link_b.as_str()] == ["camera_link", "base_link"])
    };
    assert!(contact.as_ref().is_some_and(named), "{contact:?}");
    assert!(SphereChecker::new(&robot, &env).blocked());
    let request = PlanRequest {
        start: vec![0.0; 3],
        goal: Goal::Joints(vec![vec![0.5, 0.8, 0.8]]),
        params: PlannerParams::default(),
    };
    match planning::plan(&robot, &env, &request, &mut UniformSampler) {
        Err(PlanError::StartInCollision(c)) => assert!(named(&c), "{c}"),
        other => panic!("{other:?}"),
    }
    std::fs::remove_dir_all(&bot.packages).ok();
}

#[test]
fn without_an_srdf_pairs_are_computed_and_written_as_one() {
    let bot = testbot::write_variant("nosrdf", false);
    let bare = RobotSpec {
        srdf: None,
        ..spec(&bot)
    }
    .load()
    .unwrap();
    assert_eq!(bare.dof(), 3);
    let skipped = &bare.load_info().skipped_pairs;
    let has = |a: &str, b: &str, why: &str| {
        skipped
            .iter()
            .any(|(x, y, r)| ((x == a && y == b) || (x == b && y == a)) && r == why)
    };
    assert!(has("base_link", "link1", "Adjacent"), "{skipped:?}");
    assert!(has("link2", "tool", "Adjacent"), "{skipped:?}");
    // The tool can fold down onto the base: that pair stays checked.
    assert!(
        !skipped
            .iter()
            .any(|(x, y, _)| (x == "base_link" && y == "tool") || (x == "tool" && y == "base_link")),
        "{skipped:?}"
    );
    // Written as an SRDF and read back, the same pairs are checked.
    let again =
        self_collision::skipped_pairs(&bare, self_collision::DEFAULT_SAMPLES, &SphereCache::Off);
    assert_eq!(&again, skipped);
    let srdf = Srdf {
        groups: vec![Group {
            name: "arm".into(),
            chains: vec![("base_link".into(), "tool".into())],
            ..Default::default()
        }],
        ..Default::default()
    };
    let written = bot.dir.join("written.srdf");
    std::fs::write(&written, srdf.write_disabled("testbot", skipped)).unwrap();
    let reloaded = RobotSpec {
        srdf: Some(written),
        ..spec(&bot)
    }
    .load()
    .unwrap();
    assert_eq!(reloaded.self_collision_pairs(), bare.self_collision_pairs());
    std::fs::remove_dir_all(&bot.packages).ok();
}

#[test]
fn bad_descriptions_are_refused_with_a_sentence_naming_the_file() {
    let bot = testbot::write("bad");
    let good_urdf = std::fs::read_to_string(&bot.urdf).unwrap();
    let urdf = |text: &str| {
        std::fs::write(&bot.urdf, text).unwrap();
        spec(&bot).load().map(|_| ()).unwrap_err().to_string()
    };
    let err = urdf(&good_urdf.replace("meshes/tool.dae", "meshes/missing.stl"));
    assert!(err.contains("missing.stl") && err.contains("tool"), "{err}");
    let err = urdf(&good_urdf.replace("package://testbot/", "package://nowhere/"));
    assert!(
        err.contains("unknown package 'nowhere'") && err.contains("base_link"),
        "{err}"
    );
    std::fs::write(bot.dir.join("meshes/cloud.ply"), "ply\n").unwrap();
    let err = urdf(&good_urdf.replace("meshes/tool.dae", "meshes/cloud.ply"));
    assert!(
        err.contains("unsupported format") && err.contains("cloud.ply"),
        "{err}"
    );
    testbot::write_binary_stl(&bot.dir.join("meshes/empty.stl"), &[]);
    let err = urdf(&good_urdf.replace("meshes/tool.dae", "meshes/empty.stl"));
    assert!(err.contains("empty") && err.contains("empty.stl"), "{err}");
    std::fs::write(
        bot.dir.join("meshes/garbage.stl"),
        b"solid x\n facet nonsense",
    )
    .unwrap();
    let err = urdf(&good_urdf.replace("meshes/tool.dae", "meshes/garbage.stl"));
    assert!(err.contains("garbage.stl"), "{err}");
    std::fs::write(&bot.urdf, &good_urdf).unwrap();

    let srdf = |text: &str| {
        std::fs::write(&bot.srdf, text).unwrap();
        spec(&bot).load().map(|_| ()).unwrap_err().to_string()
    };
    let err = srdf(&testbot::SRDF.replace(
        r#"<chain base_link="base_link" tip_link="tool"/>"#,
        r#"<joint name="joint1"/><joint name="elbow"/>"#,
    ));
    assert!(
        err.contains("testbot.srdf") && err.contains("elbow") && err.contains("'arm'"),
        "{err}"
    );
    let err = srdf(&testbot::SRDF.replace(
        r#"<chain base_link="base_link" tip_link="tool"/>"#,
        r#"<joint name="joint1"/><joint name="camera_joint"/>"#,
    ));
    assert!(err.contains("not a chain"), "{err}");
    let err = srdf(&testbot::SRDF.replace(r#"<joint name="joint3" value="0.8"/>"#, ""));
    assert!(err.contains("bent") && err.contains("joint3"), "{err}");
    let err = srdf("<robot name=\"x\"><group name=\"arm\">");
    assert!(
        err.contains("invalid SRDF") && err.contains("testbot.srdf"),
        "{err}"
    );
    std::fs::write(&bot.srdf, testbot::SRDF).unwrap();
    let err = RobotSpec {
        group: Some("legs".into()),
        ..spec(&bot)
    }
    .load()
    .unwrap_err()
    .to_string();
    assert!(err.contains("'legs'") && err.contains("arm"), "{err}");
    std::fs::remove_dir_all(&bot.packages).ok();
}

/// A box obstacle named `name` of `size` centred at `c`.
fn block(name: &str, size: [f64; 3], c: [f64; 3]) -> Object {
    Object {
        name: name.into(),
        shape: Shape::cuboid(size),
        pose: Pose::translation(c[0], c[1], c[2]),
    }
}

#[test]
fn goals_only_the_spheres_touch_are_reached_and_real_contacts_are_named() {
    let bot = testbot::write("goals");
    let robot = load(&bot);
    let goal = vec![0.0, 0.0, 0.0];
    // The arm stands straight up at the goal; a post 5 mm from link2's face: free in the
    // exact geometry, inside the spheres' centimetre.
    let env = Environment::from_objects([block(
        "post",
        [0.05, 0.05, 0.3],
        [0.04 + 0.005 + 0.025, 0.0, 0.8],
    )])
    .unwrap();
    assert!(ExactChecker::new(&robot, &env).contact(&goal).is_none());
    assert!(SphereChecker::new(&robot, &env).contact(&goal).is_some());
    let start = vec![-1.2, -0.8, 0.6];
    let req = PlanRequest {
        start: start.clone(),
        goal: Goal::Joints(vec![goal.clone()]),
        params: PlannerParams {
            seed: 4,
            ..Default::default()
        },
    };
    let res = planning::plan(&robot, &env, &req, &mut UniformSampler).unwrap();
    assert_eq!(res.path.last().unwrap(), &goal);
    assert!(path_is_valid(&robot, &env, &res.path, DEFAULT_RESOLUTION));
    assert!(res.stats.exact_fallbacks > 0);
    // A start inside the post is refused, naming the link and the object.
    let inside = PlanRequest {
        start: goal.clone(),
        goal: Goal::Joints(vec![start]),
        params: PlannerParams::default(),
    };
    let env =
        Environment::from_objects([block("post", [0.05, 0.05, 0.3], [0.04 + 0.02, 0.0, 0.8])])
            .unwrap();
    match planning::plan(&robot, &env, &inside, &mut UniformSampler) {
        Err(PlanError::StartInCollision(c)) => {
            assert_eq!(c.to_string(), "link link2 touches object post")
        }
        other => panic!("{other:?}"),
    }
    std::fs::remove_dir_all(&bot.packages).ok();
}

#[test]
fn returned_paths_are_free_in_the_exact_geometry() {
    use rand::{Rng, SeedableRng};
    let bot = testbot::write("paths");
    let mesh_bot = load(&bot);
    let fetch = Robot::builtin("fetch").unwrap();
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(9);
    let mut solved = 0;
    for (robot, reach) in [(&mesh_bot, 1.0), (&fetch, 1.3)] {
        let mut tries = 0;
        let mut planned = 0;
        while planned < 12 && tries < 500 {
            tries += 1;
            // A few random boxes in the robot's reach, away from its base.
            let objects: Vec<Object> = (0..4)
                .map(|i| {
                    let r = rng.random_range(0.45..reach);
                    let a = rng.random_range(-3.1..3.1f64);
                    block(
                        &format!("box{i}"),
                        [
                            rng.random_range(0.05..0.3),
                            rng.random_range(0.05..0.3),
                            rng.random_range(0.05..0.3),
                        ],
                        [r * a.cos(), r * a.sin(), rng.random_range(0.2..1.2)],
                    )
                })
                .collect();
            let env = Environment::from_objects(objects).unwrap();
            let mut exact = ExactChecker::new(robot, &env);
            let mut pick = || {
                let mut q = vec![0.0; robot.dof()];
                robot.sample_uniform(&mut rng, &mut q);
                q
            };
            let (start, goal) = (pick(), pick());
            if exact.contact(&start).is_some() || exact.contact(&goal).is_some() {
                continue;
            }
            planned += 1;
            let req = PlanRequest {
                start,
                goal: Goal::Joints(vec![goal]),
                params: PlannerParams {
                    seed: tries as u64,
                    time_limit: std::time::Duration::from_secs(5),
                    ..Default::default()
                },
            };
            if let Ok(res) = planning::plan(robot, &env, &req, &mut UniformSampler) {
                solved += 1;
                assert!(
                    path_is_valid(robot, &env, &res.path, DEFAULT_RESOLUTION),
                    "{}: path collides",
                    robot.name()
                );
            }
        }
        assert_eq!(planned, 12, "{}", robot.name());
    }
    assert!(solved >= 18, "only {solved} of 24 solved");
    std::fs::remove_dir_all(&bot.packages).ok();
}

#[test]
fn a_moveit_joint_limits_file_overrides_the_description() {
    let dir = std::env::temp_dir().join(format!("ember-limits-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("joint_limits.yaml");
    std::fs::write(
        &file,
        "joint_limits:\n  shoulder_pan_joint:\n    has_velocity_limits: true\n    max_velocity: 0.5\n    \
         has_acceleration_limits: true\n    max_acceleration: 0.25\n    has_jerk_limits: true\n    \
         max_jerk: 5\n  elbow_flex_joint:\n    has_velocity_limits: false\n    max_velocity: 0\n  \
         l_gripper_finger_joint:\n    max_velocity: 0.1\n",
    )
    .unwrap();
    let mut spec = ember_engine::robot::RobotSpec::new("fetch");
    let builtin = spec.load().unwrap();
    spec.joint_limits = Some(file.clone());
    let robot = spec.load().unwrap();
    let pan = &robot.limits()[1];
    assert_eq!(
        (pan.velocity, pan.acceleration, pan.jerk),
        (Some(0.5), Some(0.25), Some(5.0))
    );
    // A `false` flag leaves the value before it; joints outside the group are skipped.
    assert_eq!(robot.limits()[4], builtin.limits()[4]);
    assert!(robot
        .load_info()
        .sources
        .iter()
        .any(|s| s.ends_with("joint_limits.yaml")));
    std::fs::write(&file, "joint_limits: [1, 2]\n").unwrap();
    let err = spec.load().unwrap_err().to_string();
    assert!(
        err.contains("joint_limits.yaml") && err.contains("not a MoveIt joint_limits.yaml"),
        "{err}"
    );
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn a_millimetre_mesh_without_its_scale_is_refused_not_fitted() {
    // Found by fuzzing: read as metres, the 0.4 m link is 400 m long and fitting its spheres
    // asked for tens of GB.
    let bot = testbot::write("noscale");
    let urdf = std::fs::read_to_string(&bot.urdf).unwrap();
    let broken = urdf.replace(r#" scale="0.001 0.001 0.001""#, "");
    assert_ne!(broken, urdf);
    let path = bot.dir.join("noscale.urdf");
    std::fs::write(&path, broken).unwrap();
    let e = RobotSpec {
        robot: path.display().to_string(),
        ..spec(&bot)
    }
    .load()
    .expect_err("refused");
    let text = e.to_string();
    assert!(
        text.contains("link 'link2'") && text.contains("millimetres"),
        "{text}"
    );
}

/// A fine sphere model (links of 640 balls: 80 clusters each) and a crowded scene (more than 64
/// objects, those in reach past the 64th) still go through the batch checker, which never
/// misses a contact the scalar checker finds, self-collisions included.
#[test]
fn fine_models_and_crowded_scenes_keep_the_batch_checker() {
    use ember_engine::collision::batch::BatchChecker;
    use rand::{Rng, SeedableRng};
    let bot = testbot::write("fine");
    // link1 and the tool as columns of balls (a spherized link is used as given, not
    // fitted): their pair is checked, and folds onto itself.
    let column = |dz: f64| {
        (0..640)
            .map(|i| {
                let (x, y, z) = ((i % 4) as f64, (i / 4 % 4) as f64, (i / 16) as f64);
                format!(
                    r#"<collision><origin xyz="{} {} {}"/><geometry><sphere radius="0.01"/></geometry></collision>"#,
                    0.0125 * x - 0.019,
                    0.0125 * y - 0.019,
                    dz * z,
                )
            })
            .collect::<String>()
    };
    let mut urdf = std::fs::read_to_string(&bot.urdf).unwrap();
    for (link, dz) in [("link1", 0.01), ("tool", 0.008)] {
        let open = format!(r#"<link name="{link}">"#);
        let start = urdf.find(&open).unwrap() + open.len();
        let end = start + urdf[start..].find("</link>").unwrap();
        urdf.replace_range(start..end, &column(dz));
    }
    std::fs::write(&bot.urdf, urdf).unwrap();
    let robot = load(&bot);
    let most = robot.spheres().link_clusters.iter().map(|r| r.len()).max();
    assert!(most > Some(64), "{most:?} clusters on a link at most");
    let mut rng = rand::rngs::StdRng::seed_from_u64(3);
    // 64 boxes out of reach, then 40 around the arm.
    let objects = (0..104).map(|i| {
        let c = if i < 64 {
            [5.0 + i as f64, 5.0, 0.0]
        } else {
            [
                rng.random_range(-0.8..0.8),
                rng.random_range(-0.8..0.8),
                rng.random_range(0.0..1.2),
            ]
        };
        block(&format!("b{i}"), [0.06, 0.06, 0.06], c)
    });
    let env = Environment::from_objects(objects).unwrap();
    let mut scalar = SphereChecker::new(&robot, &env);
    let mut batch = BatchChecker::new(&robot, &env);
    let mut q = vec![0.0; robot.dof()];
    let (mut objects_hit, mut self_hit, mut free) = (0, 0, 0);
    for _ in 0..1000 {
        robot.sample_uniform(&mut rng, &mut q);
        let flagged = batch.state_may_collide(&q);
        match scalar.contact(&q) {
            None => free += 1,
            Some(c) => {
                assert!(flagged, "missed {c} at {q:?}");
                match c {
                    Contact::SelfCollision { .. } => self_hit += 1,
                    _ => objects_hit += 1,
                }
            }
        }
    }
    // The test must bite: contacts of both kinds, and free configurations.
    assert!(
        objects_hit > 20 && self_hit > 5 && free > 20,
        "{objects_hit} object contacts, {self_hit} self-collisions, {free} free"
    );
    std::fs::remove_dir_all(&bot.packages).ok();
}

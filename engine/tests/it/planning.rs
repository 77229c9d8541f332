//! The planner: validity of plans in generated scenes, determinism, and each failure's own error.

use ember_engine::collision::checker::DEFAULT_RESOLUTION;
use ember_engine::planning::{
    self, path_is_valid, Goal, PlanError, PlanRequest, PlannerParams, PoseGoal, UniformSampler,
};
use ember_engine::problems::{self, GenerateOptions, ProblemSet, Task};
use ember_engine::robot::{ConfigError, Robot};
use ember_engine::scene::Scene;
use ember_engine::world::Environment;
use ember_engine::Pose;
use std::time::Duration;

fn table_scene() -> Environment {
    Scene::load(crate::fixtures().join("moveit/scene.yaml"))
        .unwrap()
        .environment()
        .unwrap()
}

fn request(start: Vec<f64>, goal: Goal, seed: u64) -> PlanRequest {
    PlanRequest {
        start,
        goal,
        params: PlannerParams {
            seed,
            time_limit: Duration::from_secs(20),
            ..Default::default()
        },
    }
}

#[test]
fn plans_in_generated_scenes_are_collision_free() {
    let robot = Robot::builtin("fetch").unwrap();
    let dir = std::env::temp_dir().join(format!("ember-it-problems-{}", std::process::id()));
    let spec = problems::dataset("shelf_height_rot").unwrap();
    let options = GenerateOptions {
        count: 4,
        seed: 11,
        ..Default::default()
    };
    let report = problems::generate(&robot, &spec, &options, &dir, &mut |_, _| {}).unwrap();
    assert_eq!(report.written, 4);
    let set = ProblemSet::load(&dir, &robot).unwrap();
    assert_eq!(set.robot.as_deref(), Some("fetch"));
    for p in &set.problems {
        let env = p.scene.environment().unwrap();
        // The generator's own path is valid too.
        assert!(path_is_valid(
            &robot,
            &env,
            p.path.as_ref().unwrap(),
            DEFAULT_RESOLUTION
        ));
        let req = request(p.request.start.clone(), p.request.goal.clone(), 3);
        let res = planning::plan(&robot, &env, &req, &mut UniformSampler).unwrap();
        assert!(path_is_valid(&robot, &env, &res.path, DEFAULT_RESOLUTION));
        let Goal::Joints(goals) = &p.request.goal else {
            panic!()
        };
        assert_eq!(res.path.first().unwrap(), &p.request.start);
        assert_eq!(res.path.last().unwrap(), &goals[0]);
        assert!(res.stats.length_after <= res.stats.length_before + 1e-9);
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn place_problems_start_holding_the_target_and_are_solved_for_the_holding_robot() {
    let robot = Robot::builtin("fetch").unwrap();
    let spec = problems::dataset("shelf_zero").unwrap();
    let dir = std::env::temp_dir().join(format!("ember-it-place-{}", std::process::id()));
    let options = GenerateOptions {
        count: 2,
        seed: 5,
        task: Task::Place,
        ..Default::default()
    };
    let report = problems::generate(&robot, &spec, &options, &dir, &mut |_, _| {}).unwrap();
    assert_eq!(report.written, 2);
    // Written as MoveIt files and read back: the held can is an attached collision object.
    let set = ProblemSet::load(&dir, &robot).unwrap();
    assert_eq!(set.problems.len(), 2);
    for p in &set.problems {
        assert!(p.scene.objects.iter().all(|o| o.name != "Can1"));
        assert_eq!(p.scene.attached.len(), 1);
        assert_eq!(p.scene.attached[0].link, robot.links()[robot.tip()].name);
        let holding = p.scene.robot(&robot).unwrap();
        assert_eq!(holding.links().len(), robot.links().len() + 1);
        let env = p.scene.environment().unwrap();
        let path = p.path.as_ref().unwrap();
        assert_eq!(path.first().unwrap(), &p.request.start);
        assert!(path_is_valid(&holding, &env, path, DEFAULT_RESOLUTION));
        // The can goes from the middle board down into the lower compartment (0.34 m lower).
        let held_z = |q: &[f64]| {
            let mut poses = vec![Pose::identity(); holding.links().len()];
            holding.forward_kinematics(q, &mut poses);
            (poses.last().unwrap() * spec.goal_offset.inverse())
                .translation
                .z
        };
        let drop = held_z(&p.request.start) - held_z(path.last().unwrap());
        assert!((drop - 0.34).abs() < 0.02, "dropped by {drop}");
    }
    std::fs::remove_dir_all(&dir).ok();
    let err = problems::generate(
        &robot,
        &problems::dataset("box").unwrap(),
        &options,
        &dir,
        &mut |_, _| {},
    )
    .unwrap_err();
    assert!(err.to_string().contains("no place task"), "{err}");
    assert_eq!(
        Task::Place.set_name("shelf_zero", true),
        "shelf_zero_place_test"
    );
    assert_ne!(
        Task::Place.set_seed(1, false),
        Task::Pick.set_seed(1, false)
    );
}

#[test]
fn same_seed_gives_the_same_path() {
    let robot = Robot::builtin("fetch").unwrap();
    let env = table_scene();
    let start = robot.named_state("tuck").unwrap().to_vec();
    let goal = Goal::Joints(vec![vec![0.3, 0.2, -0.6, 0.0, 0.6, 0.0, 0.0, 0.0]]);
    let a = planning::plan(
        &robot,
        &env,
        &request(start.clone(), goal.clone(), 42),
        &mut UniformSampler,
    )
    .unwrap();
    let b = planning::plan(
        &robot,
        &env,
        &request(start.clone(), goal.clone(), 42),
        &mut UniformSampler,
    )
    .unwrap();
    assert_eq!(a.path, b.path);
    assert_eq!(a.stats.iterations, b.stats.iterations);
    let c = planning::plan(&robot, &env, &request(start, goal, 43), &mut UniformSampler).unwrap();
    assert_ne!(
        a.path, c.path,
        "a different seed should explore differently"
    );
}

#[test]
fn pose_goal_is_reached_within_tolerance() {
    let robot = Robot::builtin("fetch").unwrap();
    let env = table_scene();
    let target = Pose::translation(0.7, 0.1, 0.95);
    let goal = Goal::Pose(PoseGoal {
        link: None,
        pose: target,
        position_tolerance: 0.005,
        orientation_tolerance: 0.02,
    });
    let res = planning::plan(
        &robot,
        &env,
        &request(robot.named_state("tuck").unwrap().to_vec(), goal, 1),
        &mut UniformSampler,
    )
    .unwrap();
    let tip = robot.tip_pose(res.path.last().unwrap()).unwrap();
    assert!((tip.translation.vector - target.translation.vector).norm() <= 0.005);
    assert!(tip.rotation.angle_to(&target.rotation) <= 0.02);
    assert!(path_is_valid(&robot, &env, &res.path, DEFAULT_RESOLUTION));
}

#[test]
fn each_failure_has_its_own_error() {
    let robot = Robot::builtin("fetch").unwrap();
    let env = table_scene();
    let tuck = robot.named_state("tuck").unwrap().to_vec();
    let free_goal = vec![0.3, 0.2, -0.6, 0.0, 0.6, 0.0, 0.0, 0.0];
    // Arm straight out through the table.
    let in_table = vec![0.0, 0.0, 0.1, 0.0, 0.0, 0.0, 0.0, 0.0];
    let plan = |start: Vec<f64>, goal: Goal| {
        planning::plan(&robot, &env, &request(start, goal, 0), &mut UniformSampler).unwrap_err()
    };

    let mut kinds = std::collections::BTreeSet::new();
    let e = plan(tuck.clone(), Goal::Joints(vec![in_table.clone()]));
    assert!(matches!(e, PlanError::GoalInCollision(_)), "{e}");
    kinds.insert(e.kind());
    let e = plan(in_table, Goal::Joints(vec![free_goal.clone()]));
    assert!(matches!(e, PlanError::StartInCollision(_)), "{e}");
    kinds.insert(e.kind());
    let mut out_of_limits = free_goal.clone();
    out_of_limits[4] = 2.5;
    let e = plan(tuck.clone(), Goal::Joints(vec![out_of_limits]));
    assert!(
        matches!(e, PlanError::InvalidGoal(ConfigError::OutOfLimits { .. })),
        "{e}"
    );
    kinds.insert(e.kind());
    let e = plan(vec![0.1; 5], Goal::Joints(vec![free_goal.clone()]));
    assert!(
        matches!(e, PlanError::InvalidStart(ConfigError::WrongLength { .. })),
        "{e}"
    );
    kinds.insert(e.kind());
    let far = Goal::Pose(PoseGoal {
        link: None,
        pose: Pose::translation(3.0, 0.0, 1.0),
        position_tolerance: 0.01,
        orientation_tolerance: 0.1,
    });
    let e = plan(tuck, far);
    assert!(matches!(e, PlanError::UnreachablePose { .. }), "{e}");
    kinds.insert(e.kind());
    assert_eq!(
        kinds.len(),
        5,
        "each failure reports its own kind: {kinds:?}"
    );
}

#[test]
fn iteration_limit_gives_a_timeout() {
    let robot = Robot::builtin("fetch").unwrap();
    let env = table_scene();
    // Under the table: no straight way from the tucked arm.
    let under = vec![0.0, 0.0, 0.9, 0.0, -0.9, 0.0, 0.0, 0.0];
    let req = PlanRequest {
        start: robot.named_state("tuck").unwrap().to_vec(),
        goal: Goal::Joints(vec![under]),
        params: PlannerParams {
            max_iterations: 2,
            ..Default::default()
        },
    };
    match planning::plan(&robot, &env, &req, &mut UniformSampler) {
        Err(PlanError::Timeout { iterations, .. }) => assert_eq!(iterations, 2),
        other => panic!("expected a timeout, got {other:?}"),
    }
}

/// The same configuration every time.
struct Fixed(Vec<f64>);

impl planning::Sampler for Fixed {
    fn sample(&mut self, _: &Robot, _: &mut planning::PlannerRng, out: &mut [f64]) {
        out.copy_from_slice(&self.0);
    }
}

/// By default only the time limit ends a search: no iteration cap cuts short a search that
/// rejects its samples. Here every sample is the tucked arm raised by the torso into a block,
/// so the one extension fails, the start's dynamic domain shrinks to a millimetre, and every
/// later sample is rejected in tens of nanoseconds (by the domain, then, once the search has
/// stalled, by the screen of its gathered extensions): the old cap of 5M iterations ended
/// such a search in a fraction of a second.
#[test]
fn the_time_limit_ends_a_default_search() {
    use ember_engine::collision::exact::ExactChecker;
    use ember_engine::collision::Shape;
    use ember_engine::planning::rrt_connect::DynamicDomain;
    use ember_engine::world::Object;
    let robot = Robot::builtin("fetch").unwrap();
    let mut start = robot.named_state("tuck").unwrap().to_vec();
    start[0] = 0.0;
    let mut raised = start.clone();
    raised[0] = 0.3;
    // A 4 cm block where one of the hand's links is once the torso has risen, placed where the
    // tucked arm clears it.
    let poses = robot.link_poses(&raised).unwrap();
    let env = [
        "gripper_link",
        "wrist_roll_link",
        "wrist_flex_link",
        "forearm_roll_link",
    ]
    .iter()
    .map(|name| {
        let at = poses[robot.link_index(name).unwrap()].translation;
        let block = Object {
            name: "block".into(),
            shape: Shape::cuboid([0.04, 0.04, 0.04]),
            pose: Pose::translation(at.x, at.y, at.z),
        };
        let mut objects = table_scene().objects().to_vec();
        objects.push(block);
        Environment::from_objects(objects).unwrap()
    })
    .find(|env| {
        let mut exact = ExactChecker::new(&robot, env);
        exact.is_valid(&start) && !exact.is_valid(&raised)
    })
    .expect("no block stops the torso and leaves the tucked arm free");
    let limit = Duration::from_millis(1500);
    let req = PlanRequest {
        start,
        // Under the table: no straight way from the tucked arm.
        goal: Goal::Joints(vec![vec![0.0, 0.0, 0.9, 0.0, -0.9, 0.0, 0.0, 0.0]]),
        params: PlannerParams {
            time_limit: limit,
            dynamic_domain: Some(DynamicDomain {
                radius: 1e-3,
                min_radius: 1e-3,
                alpha: 0.0,
            }),
            ..Default::default()
        },
    };
    match planning::plan(&robot, &env, &req, &mut Fixed(raised)) {
        Err(PlanError::Timeout {
            elapsed_ms,
            iterations,
        }) => assert!(
            elapsed_ms >= limit.as_secs_f64() * 1e3,
            "ended after {iterations} iterations, {elapsed_ms} ms"
        ),
        other => panic!("expected a timeout, got {other:?}"),
    }
}

#[test]
fn a_set_cancel_flag_stops_the_search() {
    let robot = Robot::builtin("fetch").unwrap();
    let env = table_scene();
    let flag = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let mut req = request(
        robot.named_state("tuck").unwrap().to_vec(),
        Goal::Joints(vec![vec![0.3, 0.2, -0.6, 0.0, 0.6, 0.0, 0.0, 0.0]]),
        1,
    );
    req.params.cancel = planning::Cancel::new(flag.clone());
    // Not set: the plan runs as usual.
    assert!(planning::plan(&robot, &env, &req, &mut UniformSampler).is_ok());
    flag.store(true, std::sync::atomic::Ordering::Relaxed);
    match planning::plan(&robot, &env, &req, &mut UniformSampler) {
        Err(e @ PlanError::Cancelled { iterations: 0 }) => assert_eq!(e.kind(), "cancelled"),
        other => panic!("expected a cancelled plan, got {other:?}"),
    }
}

/// Fetch and a motion raising its shoulder by 0.5 rad, the hand held out in front.
fn shoulder_lift_motion() -> (Robot, Vec<f64>, Vec<f64>) {
    let a = vec![0.2, 0.5, 0.0, 0.0, 1.0, 0.0, 1.0, 0.0];
    let mut b = a.clone();
    b[1] += 0.5;
    (Robot::builtin("fetch").unwrap(), a, b)
}

/// A 1 mm grain where Fetch's left finger is halfway between two states of the motion
/// `a` → `b` the search's resolution apart, both of them clear of it: the first such place
/// from `a`, or from `b` when `near_end`.
fn grain_between_states(robot: &Robot, a: &[f64], b: &[f64], near_end: bool) -> Environment {
    use ember_engine::collision::exact::ExactChecker;
    use ember_engine::collision::Shape;
    use ember_engine::world::Object;
    let n = (robot.distance(a, b) / DEFAULT_RESOLUTION).ceil() as usize;
    let finger = robot.link_index("l_gripper_finger_link").unwrap();
    let state = |t: f64| {
        let mut q = vec![0.0; a.len()];
        robot.interpolate(a, b, t, &mut q);
        q
    };
    let places: Vec<usize> = match near_end {
        false => (1..n - 1).collect(),
        true => (1..n).rev().collect(),
    };
    let places_again = places.clone();
    places
        .into_iter()
        .map(|k| {
            // The centre of the finger's collision shape.
            let at = robot
                .link_poses(&state((k as f64 + 0.5) / n as f64))
                .unwrap()[finger]
                * robot.links()[finger].collision[0].origin;
            let p = at.translation.vector;
            Environment::from_objects([Object {
                name: "grain".into(),
                shape: Shape::Sphere { radius: 1e-3 },
                pose: Pose::translation(p.x, p.y, p.z),
            }])
            .unwrap()
        })
        .zip(places_again)
        .find(|(env, k)| {
            let mut exact = ExactChecker::new(robot, env);
            exact.motion_contact(a, b, DEFAULT_RESOLUTION).is_none()
                && exact
                    .contact(&state((*k as f64 + 0.5) / n as f64))
                    .is_some()
        })
        .map(|(env, _)| env)
        .expect("a grain between two checked states")
}

/// A grain that a finger sweeps through between two states the search's resolution apart:
/// the validation at that resolution passes the motion; eight times finer (`validating_at`)
/// or certified it finds the grain.
#[test]
fn a_finer_validation_finds_a_graze_between_checked_states() {
    use ember_engine::collision::exact::ExactChecker;
    use ember_engine::planning::validity::Validity;
    use ember_engine::world::Object;
    let (robot, a, b) = shoulder_lift_motion();
    let grain = grain_between_states(&robot, &a, &b, false);
    let path = [a.clone(), b.clone()];
    let mut coarse = Validity::new(&robot, &grain, DEFAULT_RESOLUTION, 0.0);
    assert_eq!(coarse.path_contact(&path), None, "between the states");
    let mut fine = Validity::new(&robot, &grain, DEFAULT_RESOLUTION, 0.0)
        .validating_at(DEFAULT_RESOLUTION / 8.0);
    assert!(fine.path_contact(&path).is_some(), "walked finer");
    let mut certified = Validity::new(&robot, &grain, DEFAULT_RESOLUTION, 0.0).certifying(true);
    assert!(certified.path_contact(&path).is_some(), "certified");
    // Moved a few centimetres off the path (where a walk 256 times finer finds it clear),
    // the grain leaves the motion certified.
    let far = [
        [0.0, 0.0, 0.05],
        [0.0, 0.0, -0.05],
        [0.05, 0.0, 0.0],
        [-0.05, 0.0, 0.0],
    ]
    .into_iter()
    .map(|[x, y, z]| {
        Environment::from_objects(grain.objects().iter().map(|o| Object {
            pose: Pose::translation(x, y, z) * o.pose,
            ..o.clone()
        }))
        .unwrap()
    })
    .find(|env| {
        let mut exact = ExactChecker::new(&robot, env);
        exact
            .motion_contact(&a, &b, DEFAULT_RESOLUTION / 256.0)
            .is_none()
    })
    .expect("a grain clear of the motion");
    let mut certified = Validity::new(&robot, &far, DEFAULT_RESOLUTION, 0.0).certifying(true);
    assert_eq!(certified.path_contact(&path), None, "certified clear");
    assert_eq!(certified.uncertified(), 0);
}

/// A plan whose path grazes a grain between the search's states: returned as it is by
/// default; with `certify` the graze is found, the paths are refused, and the plan is searched
/// again finer (`refined`) for a path certified clear.
#[test]
fn a_certified_plan_searches_again_past_a_graze() {
    use ember_engine::planning::validity::Validity;
    let (robot, a, b) = shoulder_lift_motion();
    // Next to the goal, where the exact geometry decides (the finger's spheres touch the
    // grain there), so the search takes the motion.
    let grain = grain_between_states(&robot, &a, &b, true);
    let request = |certify| PlanRequest {
        start: a.clone(),
        goal: Goal::Joints(vec![b.clone()]),
        params: PlannerParams {
            certify,
            ..Default::default()
        },
    };
    let mut check = Validity::new(&robot, &grain, DEFAULT_RESOLUTION, 0.0).certifying(true);
    let plain = planning::plan(&robot, &grain, &request(false), &mut UniformSampler).unwrap();
    assert!(!plain.stats.refined);
    assert!(
        check.path_contact(&plain.path).is_some(),
        "no graze to find"
    );
    let res = planning::plan(&robot, &grain, &request(true), &mut UniformSampler).unwrap();
    assert!(res.stats.refined, "not searched again");
    assert_eq!(check.path_contact(&res.path), None);
}

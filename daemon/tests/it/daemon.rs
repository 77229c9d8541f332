//! Cross-process tests: a real `ember run` process and this test process as its client, over a
//! real iceoryx2 service. Each test runs its own instance name.

use ember_engine::collision::checker::DEFAULT_RESOLUTION;
use ember_engine::planning::path_is_valid;
use ember_engine::robot::Robot;
use ember_engine::scene::Scene;
use ember_sdk::launch::launch;
use ember_sdk::wire::{self, Method, PlanRequestHeader, Point, ShapeKind, PROTOCOL_VERSION};
use ember_sdk::{Client, PlanCall, Status};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

pub const TUCK: [f64; 8] = [0.1, 1.32, 1.40, -0.2, 1.72, 0.0, 1.66, 0.0];
pub const FREE_GOAL: [f64; 8] = [0.3, 0.2, -0.6, 0.0, 0.6, 0.0, 0.0, 0.0];

pub struct Daemon {
    pub child: Child,
    pub instance: String,
    pub db_dir: PathBuf,
    /// The recording file the daemon announced.
    pub recording: PathBuf,
}

impl Daemon {
    /// A daemon of its own instance, not monitored over Zenoh (tests stay independent of
    /// whatever listens on the default Zenoh port).
    pub fn start(tag: &str) -> Daemon {
        Self::start_args(tag, &["--no-monitor"])
    }

    /// A daemon of its own instance, not monitored, configured by `toml` (written to a file
    /// in a temporary folder, returned for the test to remove).
    pub fn start_configured(tag: &str, toml: &str) -> (Daemon, PathBuf) {
        let dir = std::env::temp_dir().join(format!("ember-{tag}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let config = dir.join("emberd.toml");
        std::fs::write(&config, toml).unwrap();
        let d = Self::start_args(tag, &["--no-monitor", "--config", config.to_str().unwrap()]);
        (d, dir)
    }

    /// A daemon of its own instance, with extra `ember run` arguments.
    pub fn start_args(tag: &str, extra: &[&str]) -> Daemon {
        let instance = format!("it-{tag}-{}", std::process::id());
        let db_dir = std::env::temp_dir().join(format!("ember-db-{instance}"));
        Self::start_with(instance, db_dir, extra)
    }

    pub fn start_with(instance: String, db_dir: PathBuf, extra: &[&str]) -> Daemon {
        let (child, ready) = launch(
            Command::new(env!("CARGO_BIN_EXE_ember"))
                .args([
                    "run",
                    "--instance",
                    &instance,
                    "--db-dir",
                    db_dir.to_str().unwrap(),
                    "--record-dir",
                    db_dir.join("recordings").to_str().unwrap(),
                ])
                .args(extra)
                .stderr(match std::env::var_os("EMBER_TEST_DAEMON_LOG") {
                    Some(_) => Stdio::inherit(),
                    None => Stdio::null(),
                }),
        )
        .expect("ember run starts");
        assert_eq!(ready.instance, instance);
        let recording = ready.recording.unwrap_or_default();
        Daemon {
            child,
            instance,
            db_dir,
            recording,
        }
    }

    pub fn client(&self) -> Client {
        let deadline = Instant::now() + Duration::from_secs(10);
        loop {
            match Client::connect(&self.instance) {
                Ok(c) => return c,
                Err(e) if Instant::now() > deadline => panic!("cannot connect: {e}"),
                Err(_) => std::thread::sleep(Duration::from_millis(20)),
            }
        }
    }

    pub fn signal(&self, sig: &str) {
        Command::new("kill")
            .args([sig, &self.child.id().to_string()])
            .status()
            .unwrap();
    }
}

impl Drop for Daemon {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
        let _ = std::fs::remove_dir_all(&self.db_dir);
    }
}

/// Replays `file` into daemon `d` with `--check`: all `plans` plans come back bit for bit, and
/// every recorded trajectory too.
pub fn replay_check(file: &std::path::Path, d: &Daemon, plans: usize) {
    let out = crate::ember(&[
        "replay",
        file.to_str().unwrap(),
        "--instance",
        &d.instance,
        "--check",
    ]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success() && text.contains(&format!("plans reproduced: {plans}/{plans}")),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    if let Some(line) = text
        .lines()
        .find(|l| l.starts_with("trajectories reproduced: "))
    {
        let (k, n) = line["trajectories reproduced: ".len()..]
            .split_once('/')
            .expect("k/n");
        assert_eq!(k, n, "{text}");
    }
}

pub fn table_scene() -> Scene {
    Scene::load(crate::fixtures().join("moveit/scene.yaml")).unwrap()
}

/// Publishes the fixture's table scene as object updates.
pub fn publish_table(client: &Client) {
    for o in table_scene().objects {
        let (shape, dims) = match o.shape {
            ember_engine::collision::Shape::Box { half_extents: h } => {
                (ShapeKind::Box, [2.0 * h[0], 2.0 * h[1], 2.0 * h[2]])
            }
            ember_engine::collision::Shape::Cylinder {
                radius,
                half_length,
            } => (ShapeKind::Cylinder, [radius, 2.0 * half_length, 0.0]),
            _ => unreachable!(),
        };
        let t = o.pose.translation.vector;
        let q = o.pose.rotation.coords;
        client
            .publish_object(&o.name, shape, dims, [t.x, t.y, t.z, q.x, q.y, q.z, q.w])
            .unwrap();
    }
}

pub fn wait_for(
    client: &Client,
    what: &str,
    f: impl Fn(&wire::StatusReply) -> bool,
) -> wire::StatusReply {
    let deadline = Instant::now() + Duration::from_secs(10);
    loop {
        let s = client.status(Duration::from_secs(2)).unwrap();
        if f(&s) {
            return s;
        }
        assert!(
            Instant::now() < deadline,
            "timed out waiting for {what}: {s:?}"
        );
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// A collision-free configuration with the hand right behind the can on the fixture's table.
pub fn goal_near_can() -> Vec<f64> {
    let robot = Robot::builtin("fetch").unwrap();
    let env = table_scene().environment().unwrap();
    let mut checker = ember_engine::collision::SphereChecker::new(&robot, &env);
    let goal = ember_engine::planning::PoseGoal {
        link: None,
        pose: ember_engine::Pose::translation(0.66, 0.1, 0.86),
        position_tolerance: 0.005,
        orientation_tolerance: 0.05,
    };
    let mut rng = <ember_engine::planning::PlannerRng as rand::SeedableRng>::seed_from_u64(8);
    ember_engine::planning::ik::solve(&mut checker, &goal, None, &Default::default(), &mut rng)
        .unwrap()[0]
        .clone()
}

/// A uniform joint-goal request from the tuck pose.
pub fn uniform_call(goal: Vec<f64>, seed: u64) -> PlanCall {
    PlanCall {
        start: TUCK.to_vec(),
        goals: vec![goal],
        pose: None,
        method: Method::Uniform,
        time_limit_s: 10.0,
        seed,
        trajectory: None,
    }
}

fn call(goal: [f64; 8]) -> PlanCall {
    uniform_call(goal.to_vec(), 3)
}

#[test]
fn objects_and_clouds_change_the_world_and_plans_come_back_valid() {
    let d = Daemon::start("world");
    let client = d.client();
    publish_table(&client);
    wait_for(&client, "objects", |s| s.world_objects == 3);
    // A goal through the table is refused now that the table is known.
    let through = [0.0, 0.0, 0.1, 0.0, 0.0, 0.0, 0.0, 0.0];
    let reply = client
        .plan(&call(through), Duration::from_secs(20))
        .unwrap();
    assert_eq!(reply.status, Status::GoalInCollision, "{}", reply.message());
    // A free goal is planned; the path is valid in the same scene.
    let reply = client
        .plan(&call(FREE_GOAL), Duration::from_secs(20))
        .unwrap();
    assert_eq!(reply.status, Status::Ok, "{}", reply.message());
    let robot = Robot::builtin("fetch").unwrap();
    let env = table_scene().environment().unwrap();
    assert!(path_is_valid(&robot, &env, &reply.path, DEFAULT_RESOLUTION));
    assert_eq!(reply.path.first().unwrap(), &TUCK.to_vec());
    assert_eq!(reply.path.last().unwrap(), &FREE_GOAL.to_vec());
    // Same seed, same world: the same path.
    let again = client
        .plan(&call(FREE_GOAL), Duration::from_secs(20))
        .unwrap();
    assert_eq!(again.path, reply.path);
    // A cloud goes into the map: a wall seen from the head.
    let n = 200 * 200;
    client
        .publish_cloud(
            "head_camera",
            [0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            ember_sdk::client::now_ns(),
            n,
            |i| Point {
                x: 1.5,
                y: -0.5 + (i % 200) as f32 * 0.005,
                z: -0.5 + (i / 200) as f32 * 0.005,
            },
        )
        .unwrap();
    let s = wait_for(&client, "the cloud", |s| s.clouds == 1);
    assert!(s.map_blocks > 100, "{s:?}");
    // Removing the table makes the goal through it free.
    client
        .publish_object(
            "table",
            ShapeKind::Remove,
            [0.0; 3],
            [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
        )
        .unwrap();
    wait_for(&client, "removal", |s| s.world_objects == 2);
    let reply = client
        .plan(&call(through), Duration::from_secs(20))
        .unwrap();
    assert_eq!(reply.status, Status::Ok, "{}", reply.message());
}

#[test]
fn every_bad_input_gets_its_own_status_and_the_daemon_keeps_serving() {
    let d = Daemon::start("bad");
    let client = d.client();
    publish_table(&client);
    wait_for(&client, "objects", |s| s.world_objects == 3);
    let header = PlanRequestHeader {
        version: PROTOCOL_VERSION,
        dof: 8,
        goal_kind: 0,
        goal_count: 1,
        method: Method::Uniform as u32,
        flags: 0,
        time_limit_s: 5.0,
        seed: 1,
        pose: [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
        position_tolerance: 0.0,
        orientation_tolerance: 0.0,
        request_id: 0,
    };
    let good: Vec<f64> = TUCK.iter().chain(FREE_GOAL.iter()).copied().collect();
    let t = Duration::from_secs(20);
    let status = |h: PlanRequestHeader, v: &[f64]| client.plan_raw(h, v, t).unwrap().status;

    assert_eq!(
        status(
            PlanRequestHeader {
                version: 99,
                ..header
            },
            &good
        ),
        Status::VersionMismatch
    );
    assert_eq!(
        status(PlanRequestHeader { dof: 7, ..header }, &good[..14]),
        Status::WrongDof
    );
    assert_eq!(status(header, &good[..12]), Status::BadRequest);
    assert_eq!(
        status(
            PlanRequestHeader {
                method: 77,
                ..header
            },
            &good
        ),
        Status::BadRequest
    );
    assert_eq!(
        status(
            PlanRequestHeader {
                flags: 1 << 7,
                ..header
            },
            &good
        ),
        Status::BadRequest,
        "unknown flag bits are refused"
    );
    // A trajectory request: two scaling factors close the payload, each in (0, 1] or 0.
    let timed = PlanRequestHeader {
        flags: ember_sdk::wire::FLAG_TRAJECTORY,
        ..header
    };
    assert_eq!(status(timed, &good), Status::BadRequest, "factors missing");
    let fast: Vec<f64> = good.iter().copied().chain([1.5, 1.0]).collect();
    let reply = client.plan_raw(timed, &fast, t).unwrap();
    assert_eq!(reply.status, Status::BadRequest);
    assert_eq!(
        reply.message(),
        "velocity scaling factor 1.5 is outside (0, 1]"
    );
    let nan_factor: Vec<f64> = good.iter().copied().chain([0.5, f64::NAN]).collect();
    assert_eq!(status(timed, &nan_factor), Status::NotFinite);
    let mut nan = good.clone();
    nan[3] = f64::NAN;
    assert_eq!(status(header, &nan), Status::NotFinite);
    let mut inf = good.clone();
    inf[12] = f64::INFINITY;
    assert_eq!(status(header, &inf), Status::NotFinite);
    let mut out = good.clone();
    out[4] = 3.0; // elbow_flex beyond 2.251
    assert_eq!(status(header, &out), Status::InvalidStart);
    let mut goal_out = good.clone();
    goal_out[8] = 1.0; // torso beyond 0.386
    assert_eq!(status(header, &goal_out), Status::InvalidGoal);
    let through = [0.0, 0.0, 0.1, 0.0, 0.0, 0.0, 0.0, 0.0];
    let start_in: Vec<f64> = through.iter().chain(FREE_GOAL.iter()).copied().collect();
    assert_eq!(status(header, &start_in), Status::StartInCollision);
    let pose_header = PlanRequestHeader {
        goal_kind: 1,
        goal_count: 0,
        pose: [3.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        position_tolerance: 0.01,
        orientation_tolerance: 0.1,
        ..header
    };
    assert_eq!(status(pose_header, &TUCK), Status::UnreachablePose);

    // Bad sensor data and objects are dropped and counted.
    let before = client.status(t).unwrap().rejected;
    client
        .publish_object(
            "bad",
            ShapeKind::Box,
            [f64::NAN, 1.0, 1.0],
            [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
        )
        .unwrap();
    client
        .publish_object(
            "bad2",
            ShapeKind::Box,
            [-1.0, 1.0, 1.0],
            [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
        )
        .unwrap();
    client
        .publish_cloud(
            "cam",
            [f64::NAN, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
            0,
            10,
            |_| Point::default(),
        )
        .unwrap();
    client.publish_joints(&[0.0; 5]).unwrap();
    // An absurd object: a 1e300 m box (beyond ten times the map bounds).
    client
        .publish_object(
            "huge",
            ShapeKind::Box,
            [1e300, 1.0, 1.0],
            [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
        )
        .unwrap();
    wait_for(&client, "rejections", |s| s.rejected == before + 5);

    // And it still plans.
    assert_eq!(status(header, &good), Status::Ok);
}

fn assert_modes<'a>(files: impl IntoIterator<Item = &'a PathBuf>, expected: u32) {
    use std::os::unix::fs::PermissionsExt;
    for f in files {
        let mode = std::fs::metadata(f).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, expected, "{}: {mode:o}", f.display());
    }
}

#[test]
fn the_configured_file_mode_applies_to_databases_and_recordings() {
    let (mut d, dir) = Daemon::start_configured("mode", "file_mode = \"0640\"\n");
    let client = d.client();
    publish_table(&client);
    wait_for(&client, "objects", |s| s.world_objects == 3);
    let mut near = call(FREE_GOAL);
    near.goals = vec![goal_near_can()];
    assert_eq!(
        client.plan(&near, Duration::from_secs(20)).unwrap().status,
        Status::Ok
    );
    wait_for(&client, "learning", |s| {
        s.spark_entries + s.flame_entries > 0
    });
    d.signal("-TERM");
    assert!(d.child.wait().unwrap().success());
    let files = ember_engine::experience::Experience::files(&d.db_dir);
    assert_modes(files.iter().chain([&d.recording]), 0o640);
    std::fs::remove_dir_all(&dir).ok();
}

/// SIGTERM the moment the ready line is out: a clean exit and a complete recording (the daemon
/// takes termination requests before it says it is ready).
#[test]
fn sigterm_at_the_ready_line_exits_cleanly() {
    for i in 0..4 {
        let mut d = Daemon::start(&format!("early{i}"));
        d.signal("-TERM");
        let code = d.child.wait().unwrap();
        assert!(code.success(), "run {i}: {code:?}");
        ember_sdk::session::Session::open(&d.recording).unwrap();
    }
}

#[test]
fn sigterm_saves_the_database_and_sigkill_allows_an_immediate_restart() {
    let d = Daemon::start("life");
    let client = d.client();
    publish_table(&client);
    wait_for(&client, "objects", |s| s.world_objects == 3);
    // Learning online from a solved plan that ends with the hand next to the can on the table.
    let mut near = call(FREE_GOAL);
    near.goals = vec![goal_near_can()];
    let r = client.plan(&near, Duration::from_secs(20)).unwrap();
    assert_eq!(r.status, Status::Ok, "{}", r.message());
    drop(client);
    let (instance, db_dir) = (d.instance.clone(), d.db_dir.clone());
    d.signal("-TERM");
    let mut d = d;
    let code = d.child.wait().unwrap();
    assert!(code.success(), "clean exit: {code:?}");
    let files = ember_engine::experience::Experience::files(&db_dir);
    assert!(files.iter().all(|f| f.exists()), "{files:?}");
    // Databases and recordings are the owner's only.
    assert_modes(files.iter().chain([&d.recording]), 0o600);
    std::mem::forget(d); // keep the database folder for the restart

    let d = Daemon::start_with(instance.clone(), db_dir.clone(), &["--no-monitor"]);
    d.signal("-KILL");
    let mut d = d;
    d.child.wait().unwrap();
    std::mem::forget(d);
    // Restarted at once under the same instance: serving again, with the saved experience.
    let d = Daemon::start_with(instance, db_dir, &["--no-monitor"]);
    let client = d.client();
    let s = client.status(Duration::from_secs(2)).unwrap();
    assert!(s.spark_entries + s.flame_entries > 0, "{s:?}");
    let r = client
        .plan(&call(FREE_GOAL), Duration::from_secs(20))
        .unwrap();
    assert_eq!(r.status, Status::Ok);
}

#[test]
fn two_daemons_run_side_by_side() {
    let a = Daemon::start("a");
    let b = Daemon::start("b");
    let (ca, cb) = (a.client(), b.client());
    publish_table(&ca);
    wait_for(&ca, "objects", |s| s.world_objects == 3);
    assert_eq!(cb.status(Duration::from_secs(2)).unwrap().world_objects, 0);
}

#[test]
fn shared_memory_is_private_to_the_user() {
    let d = Daemon::start("perm");
    let _client = d.client();
    use std::os::unix::fs::PermissionsExt;
    let mut checked = 0;
    for e in std::fs::read_dir("/dev/shm").unwrap().flatten() {
        let name = e.file_name().to_string_lossy().to_string();
        // iceoryx2's 16-byte per-prefix marker (`*.global_mgmt`) is shared by design and holds
        // no data; every segment of services and nodes must be owner-only.
        if name.starts_with("iox2") && !name.ends_with(".global_mgmt") {
            let mode = e.metadata().unwrap().permissions().mode() & 0o777;
            assert_eq!(mode & 0o077, 0, "{name} is readable by others: {mode:o}");
            checked += 1;
        }
    }
    assert!(checked > 0, "no iceoryx2 segments found in /dev/shm");
}

#[test]
fn sdk_examples_run_against_a_daemon() {
    let d = Daemon::start("examples");
    let bin_dir = PathBuf::from(env!("CARGO_BIN_EXE_ember"))
        .parent()
        .unwrap()
        .join("examples");
    for example in ["sensor_publisher", "planning_client"] {
        let exe = bin_dir.join(example);
        assert!(
            exe.exists(),
            "{} is not built: run the workspace tests (cargo test --workspace)",
            exe.display()
        );
        let out = Command::new(&exe).arg(&d.instance).output().unwrap();
        let text = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success() && text.trim_end().ends_with("ok"),
            "{example}: {text}{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
}

#[test]
fn unknown_space_in_the_configured_box_refuses_a_goal_there() {
    // A box around the gripper's place at `goal_near_can` (tip at 0.66, 0.1, 0.86), which no
    // camera has seen.
    let (d, dir) = Daemon::start_configured(
        "unknown",
        "[map]\nresolution = 0.01\n[planner]\nunknown_obstacle_min = [0.55, 0.0, 0.76]\nunknown_obstacle_max = [0.8, 0.2, 0.96]\n",
    );
    let client = d.client();
    publish_table(&client);
    wait_for(&client, "objects", |s| s.world_objects == 3);
    let mut near = call(FREE_GOAL);
    near.goals = vec![goal_near_can()];
    let reply = client.plan(&near, Duration::from_secs(20)).unwrap();
    assert_eq!(reply.status, Status::GoalInCollision, "{}", reply.message());
    // Elsewhere the daemon plans as before.
    let reply = client
        .plan(&call(FREE_GOAL), Duration::from_secs(20))
        .unwrap();
    assert_eq!(reply.status, Status::Ok, "{}", reply.message());
    // The robot standing in the box: its own volume is unseen too, so a plan from there is
    // refused until the daemon has its joint state there (the self-filter's space is then
    // observed free; no cloud is needed). All around it is still unseen, so the plan asked
    // is a small turn of the wrist.
    let at_can = goal_near_can();
    let mut turn = call(FREE_GOAL);
    turn.start = at_can.clone();
    turn.goals = vec![at_can.clone()];
    turn.goals[0][7] += 0.02;
    let reply = client.plan(&turn, Duration::from_secs(20)).unwrap();
    assert_eq!(
        reply.status,
        Status::StartInCollision,
        "{}",
        reply.message()
    );
    client.publish_joints(&at_can).unwrap();
    let s = wait_for(&client, "the joint state", |s| s.joint_states == 1);
    assert_eq!(s.clouds, 0);
    let reply = client.plan(&turn, Duration::from_secs(20)).unwrap();
    assert_eq!(reply.status, Status::Ok, "{}", reply.message());
    // A box taken on top of the hand reaches unseen space in the box: it is part of the
    // robot's volume from the attach on, observed free then, with no new joint state.
    let on_top = [0.0, 0.0, 0.1, 0.0, 0.0, 0.0, 1.0];
    client
        .attach_shape("probe", "gripper_link", ShapeKind::Box, [0.06; 3], on_top)
        .unwrap();
    let s = wait_for(&client, "the attach", |s| s.world_attached == 1);
    assert_eq!((s.joint_states, s.rejected), (1, 0));
    let reply = client.plan(&turn, Duration::from_secs(20)).unwrap();
    assert_eq!(reply.status, Status::Ok, "{}", reply.message());
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn bad_config_key_is_named() {
    let dir = std::env::temp_dir().join(format!("ember-cfg-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let cfg = dir.join("bad.toml");
    // Each bad file is refused (exit 2) with the key named.
    for (text, named) in [
        ("[map]\nresolution = -0.02\n", "map.resolution"),
        ("[planner]\nrange_typo = 1.0\n", "range_typo"),
        ("[monitor]\nmode = \"router-ish\"\n", "monitor.mode"),
        // Values that would exhaust memory or a core are refused, not obeyed.
        ("[record]\nqueue = 100000000000\n", "record.queue"),
        ("[monitor]\nstatus_hz = 1e9\n", "monitor.status_hz"),
        ("[limits]\npublishers = 0\n", "limits.publishers"),
        ("[planner]\nworkers = 1000\n", "planner.workers"),
        ("[planner]\nvalidation_refine = 0.5\n", "planner.validation_refine"),
        ("[planner]\ncertify = 1\n", "certify"),
        ("file_mode = \"0666\"\n", "file_mode"),
        ("[ingest]\nspin_us = 5000000\n", "ingest.spin_us"),
        ("file_mode = \"rw-------\"\n", "file_mode"),
        (
            "[planner]\ndefault_time_limit_s = 60.0\n",
            "planner.default_time_limit_s",
        ),
        // The unknown-space box: both corners or neither, each below the other.
        (
            "[planner]\nunknown_obstacle_min = [0.0, 0.0, 0.0]\n",
            "planner.unknown_obstacle_max",
        ),
        (
            "[planner]\nunknown_obstacle_min = [0.0, 0.0, 1.0]\nunknown_obstacle_max = [1.0, 1.0, 0.5]\n",
            "planner.unknown_obstacle_min",
        ),
    ] {
        std::fs::write(&cfg, text).unwrap();
        let out = Command::new(env!("CARGO_BIN_EXE_ember"))
            .args(["run", "--config", cfg.to_str().unwrap()])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            out.status.code() == Some(2) && err.contains(named) && err.contains("bad.toml"),
            "{text}: {err}"
        );
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_plan_flagged_no_learn_leaves_the_database_alone() {
    let d = Daemon::start("nolearn");
    let client = d.client();
    publish_table(&client);
    wait_for(&client, "objects", |s| s.world_objects == 3);
    let goal: [f64; 8] = goal_near_can().try_into().unwrap();
    // Learning follows the reply; a later plan's retrieval waits for it, so after the next
    // reply the counts include every earlier lesson.
    let entries_after_next_plan = |c: &Client| {
        let r = c
            .plan_with_flags(&call(goal), wire::FLAG_NO_LEARN, Duration::from_secs(20))
            .unwrap();
        assert_eq!(r.status, Status::Ok, "{}", r.message());
        let s = c.status(Duration::from_secs(2)).unwrap();
        s.spark_entries + s.flame_entries
    };
    let reply = client
        .plan_with_flags(&call(goal), wire::FLAG_NO_LEARN, Duration::from_secs(20))
        .unwrap();
    assert_eq!(reply.status, Status::Ok, "{}", reply.message());
    assert_eq!(
        entries_after_next_plan(&client),
        0,
        "nothing learned from a NO_LEARN plan"
    );
    let reply = client.plan(&call(goal), Duration::from_secs(20)).unwrap();
    assert_eq!(reply.status, Status::Ok, "{}", reply.message());
    assert!(
        entries_after_next_plan(&client) > 0,
        "the same plan without the flag is learned"
    );
}

#[test]
fn a_corrupt_database_is_set_aside_and_the_daemon_serves() {
    let instance = format!("it-corrupt-{}", std::process::id());
    let db_dir = std::env::temp_dir().join(format!("ember-db-{instance}"));
    std::fs::create_dir_all(&db_dir).unwrap();
    let [spark, _] = ember_engine::experience::Experience::files(&db_dir);
    std::fs::write(&spark, b"EMBEREXP not really a database").unwrap();
    let d = Daemon::start_with(instance, db_dir.clone(), &["--no-monitor"]);
    let client = d.client();
    let s = client.status(Duration::from_secs(2)).unwrap();
    assert_eq!(s.spark_entries, 0);
    // Kept beside itself, byte for byte, never overwritten.
    let aside: Vec<_> = std::fs::read_dir(&db_dir)
        .unwrap()
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.to_string_lossy().contains(".corrupt-"))
        .collect();
    assert_eq!(aside.len(), 1, "{aside:?}");
    assert_eq!(
        std::fs::read(&aside[0]).unwrap(),
        b"EMBEREXP not really a database"
    );
    let r = client
        .plan(&call(FREE_GOAL), Duration::from_secs(20))
        .unwrap();
    assert_eq!(r.status, Status::Ok, "{}", r.message());
}

#[test]
fn many_clients_publish_and_plan_at_once() {
    let d = Daemon::start("many");
    let watcher = d.client();
    // Eight clients at once: four times what the cloud service used to admit.
    std::thread::scope(|s| {
        for i in 0..8u64 {
            let d = &d;
            s.spawn(move || {
                let c = d.client();
                c.publish_cloud("cam", [0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0], 0, 100, |k| {
                    Point {
                        x: 1.5,
                        y: k as f32 * 0.01,
                        z: 0.2,
                    }
                })
                .unwrap();
                let r = c
                    .plan(
                        &uniform_call(FREE_GOAL.to_vec(), i),
                        Duration::from_secs(30),
                    )
                    .unwrap();
                assert_eq!(r.status, Status::Ok, "client {i}: {}", r.message());
            });
        }
    });
    wait_for(&watcher, "clouds", |s| s.clouds >= 1 && s.plans == 8);
}

#[test]
fn a_client_beyond_the_limit_is_told_which_limit() {
    let (d, dir) = Daemon::start_configured(
        "limits",
        "[limits]\npublishers = 2\nclients = 3\nobjects = 2\n",
    );
    let (a, _b) = (d.client(), d.client());
    let e = match Client::connect(&d.instance) {
        Err(e) => e,
        Ok(_) => panic!("a third client attached past publishers = 2"),
    };
    assert!(
        matches!(
            e,
            ember_sdk::ClientError::LimitReached {
                service: "cloud",
                kind: "publishers",
                max: 2
            }
        ),
        "{e}"
    );
    assert!(e.to_string().contains("limits.publishers"), "{e}");
    // The world holds two objects at most: the table's third is refused and counted; moving
    // one already held still works.
    publish_table(&a);
    wait_for(&a, "two objects and a rejection", |s| {
        s.world_objects == 2 && s.rejected == 1
    });
    publish_table(&a);
    wait_for(&a, "the moves", |s| s.objects == 4 && s.rejected == 2);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_client_without_a_daemon_is_told_so_and_creates_nothing() {
    let instance = format!("it-nobody-{}", std::process::id());
    for _ in 0..2 {
        let e = match Client::connect(&instance) {
            Err(e) => e,
            Ok(_) => panic!("connected to a daemon that does not exist"),
        };
        assert!(matches!(e, ember_sdk::ClientError::NoDaemon(_)), "{e}");
    }
    // The services were not created by the client: a daemon then starts with its own limits.
    let d = Daemon::start_with(
        instance.clone(),
        std::env::temp_dir().join(format!("ember-db-{instance}")),
        &["--no-monitor"],
    );
    let c = d.client();
    assert!(c.status(Duration::from_secs(2)).is_ok());
}

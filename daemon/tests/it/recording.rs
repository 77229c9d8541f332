//! Session recording: every input and answer lands in an MCAP file readable by standard tools,
//! and a daemon killed mid-recording leaves its complete chunks readable.

use crate::daemon::{goal_near_can, publish_table, wait_for, Daemon, FREE_GOAL, TUCK};
use ember_sdk::recording;
use ember_sdk::wire::{Method, Point, ShapeKind};
use ember_sdk::{PlanCall, Status};
use std::collections::BTreeMap;
use std::time::Duration;

fn topics(bytes: &[u8]) -> (BTreeMap<String, usize>, Option<String>) {
    let mut counts = BTreeMap::new();
    let mut error = None;
    match mcap::MessageStream::new(bytes) {
        Ok(stream) => {
            for m in stream {
                match m {
                    Ok(m) => *counts.entry(m.channel.topic.clone()).or_insert(0) += 1,
                    Err(e) => {
                        error = Some(e.to_string());
                        break;
                    }
                }
            }
        }
        Err(e) => error = Some(e.to_string()),
    }
    (counts, error)
}

#[test]
fn a_session_is_recorded_and_decodes() {
    let d = Daemon::start("rec");
    let client = d.client();
    publish_table(&client);
    client.publish_joints(&TUCK).unwrap();
    client
        .publish_cloud(
            "head_camera",
            [0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            0,
            1000,
            |i| Point {
                x: 1.5,
                y: i as f32 * 0.001,
                z: 0.0,
            },
        )
        .unwrap();
    wait_for(&client, "inputs", |s| {
        s.world_objects == 3 && s.clouds == 1 && s.joint_states == 1
    });
    let call = PlanCall {
        start: TUCK.to_vec(),
        goals: vec![FREE_GOAL.to_vec()],
        pose: None,
        method: Method::Uniform,
        time_limit_s: 10.0,
        seed: 5,
        trajectory: Some((0.5, 0.0)),
    };
    let reply = client.plan(&call, Duration::from_secs(20)).unwrap();
    assert_eq!(reply.status, Status::Ok);
    // The timed trajectory came with the path: from the start to the goal, at rest at both ends.
    let timed = reply
        .trajectory
        .clone()
        .expect("a trajectory was asked for");
    assert!(
        timed.duration > 0.0 && timed.times.len() >= 2,
        "{}",
        reply.message()
    );
    assert_eq!(timed.positions[0], TUCK.to_vec());
    assert_eq!(timed.waypoint_times.len(), reply.path.len());
    assert!(timed.velocities.last().unwrap().iter().all(|v| *v == 0.0));
    let s = wait_for(&client, "the recorder", |s| s.recorded >= 8);
    assert_eq!(s.recording_dropped, 0);
    drop(client);
    d.signal("-TERM");
    let mut d = d;
    assert!(d.child.wait().unwrap().success());

    let bytes = std::fs::read(&d.recording).unwrap();
    let (counts, error) = topics(&bytes);
    assert_eq!(error, None, "a cleanly closed recording reads to the end");
    for (topic, n) in [
        ("/ember/objects", 3),
        ("/ember/joints", 1),
        ("/ember/cloud", 1),
        ("/ember/cloud_pose", 1),
        ("/ember/plan_request", 1),
        ("/ember/plan_response", 1),
        ("/ember/plan_trajectory", 1),
    ] {
        assert_eq!(counts.get(topic), Some(&n), "{topic}: {counts:?}");
    }
    // The summary and index are there: the file opens through its summary.
    let summary = mcap::Summary::read(&bytes)
        .unwrap()
        .expect("summary written on a clean stop");
    assert_eq!(summary.channels.len(), 7);
    assert!(summary
        .chunk_indexes
        .iter()
        .all(|c| c.compression == "zstd"));
    // The recorded plan is the one answered; the cloud holds the points sent.
    for m in mcap::MessageStream::new(&bytes).unwrap().flatten() {
        match m.channel.topic.as_str() {
            "/ember/plan_response" => {
                let resp: recording::PlanResponse = recording::decode(&m.data).unwrap();
                assert_eq!(resp.status, 0);
                assert_eq!(resp.path, reply.path.concat());
            }
            "/ember/plan_trajectory" => {
                let t: recording::JointTrajectory = recording::decode(&m.data).unwrap();
                assert!(t.matches(&timed), "the recorded trajectory is the one sent");
                assert_eq!(t.joint_names[0], "torso_lift_joint");
            }
            "/ember/cloud" => {
                let cloud: recording::PointCloud2 = recording::decode(&m.data).unwrap();
                let pts = cloud.xyz_points().unwrap();
                assert_eq!(pts.len(), 1000);
                assert_eq!(pts[10], [1.5, 10.0f32 * 0.001, 0.0]);
            }
            _ => {}
        }
    }
    // Kept for the independent decoder in CI (Python mcap + mcap-ros2-support).
    let keep = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("ember-session.mcap");
    std::fs::copy(&d.recording, keep).unwrap();
}

#[test]
fn a_killed_daemon_leaves_its_complete_chunks_readable() {
    let d = Daemon::start("crash");
    let client = d.client();
    publish_table(&client);
    wait_for(&client, "objects", |s| {
        s.world_objects == 3 && s.recorded >= 3
    });
    // The recorder finishes a chunk at least every second.
    std::thread::sleep(Duration::from_millis(1500));
    d.signal("-KILL");
    let mut d = d;
    d.child.wait().unwrap();
    let bytes = std::fs::read(&d.recording).unwrap();
    // Every flushed chunk reads, and the file ends cleanly (a provisional end after each flush).
    let (counts, error) = topics(&bytes);
    assert_eq!(counts.get("/ember/objects"), Some(&3), "{counts:?}");
    assert_eq!(error, None);
    assert!(bytes.ends_with(b"\x89MCAP0\r\n"));
    // `.ci/run` reads it with the Python `mcap` reader too.
    let keep =
        std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("ember-killed-session.mcap");
    std::fs::copy(&d.recording, keep).unwrap();
}

#[test]
fn replaying_a_session_reproduces_its_plans() {
    // Record a session: a table, a joint state, a cloud and two plans.
    let a = Daemon::start("rec-a");
    let client = a.client();
    publish_table(&client);
    client.publish_joints(&TUCK).unwrap();
    client
        .publish_cloud(
            "head_camera",
            [0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            0,
            2000,
            |i| Point {
                x: 1.4,
                y: (i % 50) as f32 * 0.01,
                z: (i / 50) as f32 * 0.01,
            },
        )
        .unwrap();
    wait_for(&client, "inputs", |s| s.world_objects == 3 && s.clouds == 1);
    for seed in [11, 12] {
        let call = crate::daemon::uniform_call(FREE_GOAL.to_vec(), seed);
        assert_eq!(
            client.plan(&call, Duration::from_secs(20)).unwrap().status,
            Status::Ok
        );
    }
    wait_for(&client, "the recorder", |s| s.recorded >= 9);
    drop(client);
    a.signal("-TERM");
    let mut a = a;
    assert!(a.child.wait().unwrap().success());

    // Replay it into a fresh daemon: same world, same seeds, same paths.
    let b = Daemon::start("rec-b");
    crate::daemon::replay_check(&a.recording, &b, 2);
    let s = b.client().status(Duration::from_secs(2)).unwrap();
    assert_eq!(
        (s.world_objects, s.clouds, s.joint_states),
        (3, 1, 1),
        "{s:?}"
    );

    // A damaged file is refused with a sentence naming it, or replayed up to the damage on request.
    let bytes = std::fs::read(&a.recording).unwrap();
    let cut = a.db_dir.join("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() * 2 / 3]).unwrap();
    let out = crate::ember(&["replay", cut.to_str().unwrap(), "--instance", &b.instance]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("cut.mcap") && err.contains("--allow-truncated"),
        "{err}"
    );
    let out = crate::ember(&[
        "replay",
        cut.to_str().unwrap(),
        "--instance",
        &b.instance,
        "--allow-truncated",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // Flipped bytes inside a chunk: the chunk's CRC catches them, in replay and in training.
    let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
    let chunk = summary
        .chunk_indexes
        .iter()
        .max_by_key(|c| c.compressed_size)
        .unwrap();
    let mid = (chunk.chunk_start_offset + chunk.chunk_length / 2) as usize;
    let mut flipped = bytes.clone();
    for b in &mut flipped[mid..mid + 20] {
        *b ^= 0x5a;
    }
    let bad = a.db_dir.join("flipped.mcap");
    std::fs::write(&bad, &flipped).unwrap();
    let db = a.db_dir.join("flipped-db");
    for args in [
        vec!["replay", bad.to_str().unwrap(), "--instance", &b.instance],
        vec!["train", bad.to_str().unwrap(), "--db", db.to_str().unwrap()],
    ] {
        let out = crate::ember(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            out.status.code() == Some(2) && err.contains("flipped.mcap") && err.contains("damaged"),
            "{args:?}: {err}"
        );
    }
    let out = crate::ember(&[
        "train",
        bad.to_str().unwrap(),
        "--db",
        db.to_str().unwrap(),
        "--allow-truncated",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let foreign = a.db_dir.join("foreign.mcap");
    std::fs::write(&foreign, b"this is not an mcap file").unwrap();
    let out = crate::ember(&[
        "replay",
        foreign.to_str().unwrap(),
        "--instance",
        &b.instance,
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.code() == Some(2)
            && err.contains("foreign.mcap")
            && err.contains("not a readable MCAP"),
        "{err}"
    );
}

#[test]
fn training_from_a_recording_fills_the_databases() {
    let d = Daemon::start("train");
    let client = d.client();
    publish_table(&client);
    client.publish_joints(&TUCK).unwrap();
    // The back of the can seen from behind the robot (optical z along +x): occupied voxels right
    // where the hand ends, for FLAME.
    client
        .publish_cloud(
            "head_camera",
            [0.0, 0.1, 0.8, -0.5, 0.5, -0.5, 0.5],
            0,
            1600,
            |i| {
                let (y, z) = (
                    0.07 + 0.0015 * (i % 40) as f32,
                    0.72 + 0.003 * (i / 40) as f32,
                );
                Point {
                    x: -(y - 0.1),
                    y: -(z - 0.8),
                    z: 0.865,
                }
            },
        )
        .unwrap();
    wait_for(&client, "inputs", |s| s.world_objects == 3 && s.clouds == 1);
    let call = PlanCall {
        start: TUCK.to_vec(),
        goals: vec![goal_near_can()],
        pose: None,
        method: Method::Uniform,
        time_limit_s: 10.0,
        seed: 2,
        trajectory: None,
    };
    assert_eq!(
        client.plan(&call, Duration::from_secs(20)).unwrap().status,
        Status::Ok
    );
    wait_for(&client, "the recorder", |s| s.recorded >= 7);
    drop(client);
    d.signal("-TERM");
    let mut d = d;
    assert!(d.child.wait().unwrap().success());

    let db = d.db_dir.join("trained");
    let out = crate::ember(&[
        "train",
        d.recording.to_str().unwrap(),
        "--db",
        db.to_str().unwrap(),
    ]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(text.starts_with("learned from 1 solved plans"), "{text}");
    use ember_engine::experience::{Database, Experience};
    let (exp, aside) = Experience::load_dir(&db, &Default::default(), 0.02).unwrap();
    assert!(aside.is_empty(), "{aside:?}");
    assert!(!exp.spark.is_empty(), "{text}");
    assert!(!exp.flame.is_empty(), "{text}");
}

const FIXTURE: &str = "sessions/table_session.mcap";

/// Regenerates the recorded fixture session: the table scene streamed by the simulated depth
/// camera (320×240, from the head), the joint state, and three seeded plans. Run after a planner
/// change that alters paths: `cargo test -p ember-daemon --test it -- --ignored regenerate`.
#[test]
#[ignore = "regenerates tests/fixtures/sessions/table_session.mcap"]
fn regenerate_fixture_session() {
    let d = Daemon::start("fixture");
    let client = d.client();
    publish_table(&client);
    client.publish_joints(&TUCK).unwrap();
    let env = crate::daemon::table_scene().environment().unwrap();
    let mut camera = ember_sensors::DepthCamera::new(
        ember_sensors::quarter_vga(),
        ember_sensors::NoiseModel::default(),
        1,
    );
    for (k, eye) in [[0.15, 0.0, 1.45], [0.15, 0.2, 1.45]].iter().enumerate() {
        let frame = camera.render(&env, &ember_sensors::look_at(*eye, [1.0, 0.0, 0.75]));
        let t = frame.sensor_pose.translation.vector;
        let q = frame.sensor_pose.rotation.coords;
        let pts = frame.points;
        client
            .publish_cloud(
                "head_camera_depth_optical_frame",
                [t.x, t.y, t.z, q.x, q.y, q.z, q.w],
                0,
                pts.len(),
                |i| Point {
                    x: pts[i][0],
                    y: pts[i][1],
                    z: pts[i][2],
                },
            )
            .unwrap();
        wait_for(&client, "the cloud", |s| s.clouds == k as u64 + 1);
    }
    for (seed, goal) in [
        (1, FREE_GOAL.to_vec()),
        (2, goal_near_can()),
        (3, FREE_GOAL.to_vec()),
    ] {
        let call = crate::daemon::uniform_call(goal, seed);
        assert_eq!(
            client.plan(&call, Duration::from_secs(20)).unwrap().status,
            Status::Ok
        );
    }
    wait_for(&client, "the recorder", |s| s.recorded >= 11);
    drop(client);
    d.signal("-TERM");
    let mut d = d;
    assert!(d.child.wait().unwrap().success());
    let target = crate::fixtures().join(FIXTURE);
    std::fs::create_dir_all(target.parent().unwrap()).unwrap();
    std::fs::copy(&d.recording, &target).unwrap();
}

#[test]
fn recorded_fixture_session_replays_as_recorded() {
    let fixture = crate::fixtures().join(FIXTURE);
    let d = Daemon::start("fixture-replay");
    crate::daemon::replay_check(&fixture, &d, 3);
    let s = d.client().status(Duration::from_secs(2)).unwrap();
    assert_eq!(
        (s.world_objects, s.clouds, s.joint_states),
        (3, 2, 1),
        "{s:?}"
    );
    assert!(
        s.map_blocks > 100,
        "the camera's view of the table is in the map: {s:?}"
    );
}

/// Writes a small ROS 2-style bag: a depth cloud with an extra `intensity` field, its camera
/// pose, a joint state naming every robot joint in another order, and a motion-capture pose.
fn write_ros2_bag(path: &std::path::Path) {
    use ember_sdk::recording::{
        encode, Header, JointState, PointCloud2, PointField, Pose, PoseStamped, Time,
    };
    let schemas: BTreeMap<&str, String> = recording::schemas().into_iter().collect();
    let mut w = mcap::Writer::new(std::io::BufWriter::new(
        std::fs::File::create(path).unwrap(),
    ))
    .unwrap();
    let mut channel = |topic: &str, ty: &str| {
        let s = w.add_schema(ty, "ros2msg", schemas[ty].as_bytes()).unwrap();
        w.add_channel(s, topic, "cdr", &BTreeMap::new()).unwrap()
    };
    let (cloud_ch, pose_ch, joints_ch, mocap_ch) = (
        channel("/camera/depth/points", "sensor_msgs/msg/PointCloud2"),
        channel("/camera/pose", "geometry_msgs/msg/PoseStamped"),
        channel("/joint_states", "sensor_msgs/msg/JointState"),
        channel("/mocap/table", "geometry_msgs/msg/PoseStamped"),
    );
    let header = |frame: &str| Header {
        stamp: Time {
            sec: 100,
            nanosec: 0,
        },
        frame_id: frame.into(),
    };
    let mut data = Vec::new();
    for i in 0..500 {
        for v in [
            0.01 * (i % 25) as f32,
            0.01 * (i / 25) as f32,
            1.2f32,
            7.0f32,
        ] {
            data.extend_from_slice(&v.to_le_bytes());
        }
    }
    let field = |name: &str, offset| PointField {
        name: name.into(),
        offset,
        datatype: 7,
        count: 1,
    };
    let cloud = PointCloud2 {
        header: header("camera"),
        height: 1,
        width: 500,
        fields: vec![
            field("x", 0),
            field("y", 4),
            field("z", 8),
            field("intensity", 12),
        ],
        is_bigendian: false,
        point_step: 16,
        row_step: 16 * 500,
        data,
        is_dense: true,
    };
    let camera = PoseStamped {
        header: header("base_link"),
        pose: Pose {
            position: [0.0, 0.0, 1.0],
            orientation: [-0.5, 0.5, -0.5, 0.5],
        },
    };
    let names = [
        "l_wheel_joint",
        "r_wheel_joint",
        "head_pan_joint",
        "torso_lift_joint",
        "shoulder_pan_joint",
        "shoulder_lift_joint",
        "upperarm_roll_joint",
        "elbow_flex_joint",
        "forearm_roll_joint",
        "wrist_flex_joint",
        "wrist_roll_joint",
    ];
    let positions = [0.0, 0.0, 0.0, 0.1, 1.32, 1.40, -0.2, 1.72, 0.0, 1.66, 0.0];
    let js = JointState {
        header: header(""),
        name: names.iter().map(|s| s.to_string()).collect(),
        position: positions.to_vec(),
        velocity: vec![],
        effort: vec![],
    };
    let table = PoseStamped {
        header: header("base_link"),
        pose: Pose {
            position: [1.1, 0.0, 0.7],
            orientation: [0.0, 0.0, 0.0, 1.0],
        },
    };
    for (seq, (ch, msg)) in [
        (pose_ch, encode(&camera)),
        (cloud_ch, encode(&cloud)),
        (joints_ch, encode(&js)),
        (mocap_ch, encode(&table)),
    ]
    .into_iter()
    .enumerate()
    {
        let h = mcap::records::MessageHeader {
            channel_id: ch,
            sequence: seq as u32,
            log_time: 100_000_000_000 + seq as u64,
            publish_time: 100_000_000_000,
        };
        w.write_to_known_channel(&h, &msg).unwrap();
    }
    w.finish().unwrap();
}

#[test]
fn a_ros2_bag_replays_through_a_topic_map() {
    let d = Daemon::start("ros2");
    let bag = d.db_dir.join("robot.mcap");
    std::fs::create_dir_all(&d.db_dir).unwrap();
    write_ros2_bag(&bag);
    let map = [
        "/camera/depth/points=cloud",
        "/camera/pose=cloud_pose",
        "/joint_states=joints",
        "/mocap/table=object:table:box:0.8,1.2,0.04",
    ];
    let mut args = vec![
        "replay".to_string(),
        bag.display().to_string(),
        "--instance".into(),
        d.instance.clone(),
    ];
    for m in map {
        args.push("--topic-map".into());
        args.push(m.into());
    }
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let out = crate::ember(&args);
    assert!(
        out.status.success(),
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let client = d.client();
    let s = wait_for(&client, "the bag's data", |s| {
        s.clouds == 1 && s.world_objects == 1 && s.joint_states == 1
    });
    assert_eq!(s.rejected, 0);
    // The table from motion capture is an obstacle now.
    let through = PlanCall {
        start: TUCK.to_vec(),
        goals: vec![vec![0.0, 0.0, 0.1, 0.0, 0.0, 0.0, 0.0, 0.0]],
        pose: None,
        method: Method::Uniform,
        time_limit_s: 5.0,
        seed: 1,
        trajectory: None,
    };
    assert_eq!(
        client
            .plan(&through, Duration::from_secs(20))
            .unwrap()
            .status,
        Status::GoalInCollision
    );
    // A bad mapping is refused with the entry named.
    let out = crate::ember(&[
        "replay",
        bag.to_str().unwrap(),
        "--instance",
        &d.instance,
        "--topic-map",
        "/mocap/table=object:table:cone:1",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.code() == Some(2)
            && err.contains("/mocap/table=object:table:cone:1")
            && err.contains("cone"),
        "{err}"
    );
}

#[test]
fn the_fixture_session_reads_in_process() {
    use ember_sdk::session::{Event, Session, SessionError, TopicMap};
    let session = Session::open(&crate::fixtures().join(FIXTURE)).unwrap();
    let (mut objects, mut clouds, mut requests, mut solved) = (0, 0, 0, 0);
    let mut points = 0;
    let read = session
        .for_each(
            false,
            &TopicMap::default(),
            |_, e| -> Result<(), SessionError> {
                match e {
                    Event::Object(_) => objects += 1,
                    Event::Cloud { points: p, .. } => {
                        clouds += 1;
                        points += p.len();
                    }
                    Event::PlanRequest(_) => requests += 1,
                    Event::PlanResponse(r) => {
                        solved += (r.status == 0 && r.waypoints >= 2) as usize
                    }
                    Event::Joints { .. } | Event::PlanTrajectory(_) => {}
                }
                Ok(())
            },
        )
        .unwrap();
    assert_eq!(Some(read as u64), session.message_count());
    assert_eq!((objects, clouds, requests, solved), (3, 2, 3, 3));
    assert!(
        points > 50_000,
        "two 320x240 views of the table: {points} points"
    );
}

/// A rod held at the tip that makes `goal` collide while the bare robot reaches it, free at
/// `start` (both checked exactly and with spheres): the grasp pose and the rod's size.
fn rod_that_blocks(start: &[f64], goal: &[f64]) -> (ember_engine::Pose, [f64; 3]) {
    use ember_engine::collision::{exact::ExactChecker, Shape, SphereChecker};
    use ember_engine::Pose;
    let robot = ember_engine::robot::Robot::builtin("fetch").unwrap();
    let env = crate::daemon::table_scene().environment().unwrap();
    let free = |r: &ember_engine::robot::Robot, q: &[f64]| {
        ExactChecker::new(r, &env).is_valid(q) && SphereChecker::new(r, &env).is_valid(q)
    };
    assert!(free(&robot, start) && free(&robot, goal));
    let size = [0.02, 0.02, 0.5];
    for grasp in [
        Pose::translation(0.1, 0.0, 0.0),
        Pose::translation(0.1, 0.0, 0.25),
        Pose::translation(0.1, 0.0, -0.25),
        Pose::translation(0.35, 0.0, 0.0)
            * Pose::rotation(nalgebra::Vector3::y() * std::f64::consts::FRAC_PI_2),
    ] {
        let holding = robot.with_attached(robot.tip(), "rod", Shape::cuboid(size), grasp);
        let mut exact = ExactChecker::new(&holding, &env);
        if free(&holding, start) && !exact.is_valid(goal) {
            return (grasp, size);
        }
    }
    panic!("no rod grasp blocks the goal");
}

#[test]
fn attachments_change_plans_refusals_say_why_and_sessions_replay() {
    let a = Daemon::start("att-a");
    let client = a.client();
    publish_table(&client);
    client.publish_joints(&FREE_GOAL).unwrap();
    wait_for(&client, "the table", |s| {
        s.world_objects == 3 && s.joint_states == 1
    });
    let goal = goal_near_can();
    let (grasp, size) = rod_that_blocks(&FREE_GOAL, &goal);
    let (t, q) = ember_engine::scene::pose_to_xyz_xyzw(&grasp);
    let grasp = [t[0], t[1], t[2], q[0], q[1], q[2], q[3]];
    let tip = {
        let robot = ember_engine::robot::Robot::builtin("fetch").unwrap();
        robot.links()[robot.tip()].name.clone()
    };
    let call = PlanCall {
        start: FREE_GOAL.to_vec(),
        ..crate::daemon::uniform_call(goal.clone(), 3)
    };
    let plan = |c: &PlanCall| client.plan(c, Duration::from_secs(20)).unwrap().status;
    assert_eq!(plan(&call), Status::Ok, "the bare robot reaches the goal");

    client
        .attach_shape("rod", &tip, ShapeKind::Box, size, grasp)
        .unwrap();
    let s = wait_for(&client, "the attach", |s| s.world_attached == 1);
    assert_eq!(s.world_objects, 3);
    assert_eq!(plan(&call), Status::GoalInCollision, "the rod blocks it");

    // Each refused change names its reason; the world stays as it was.
    let slab = [0.9, 0.9, 0.9];
    let refusals: [(&dyn Fn(), Status); 5] = [
        (
            &|| client.attach("rod", &tip, grasp).unwrap(),
            Status::AlreadyAttached,
        ),
        (
            &|| client.attach("table_top", "no_such_link", grasp).unwrap(),
            Status::UnknownLink,
        ),
        (
            &|| client.attach("ghost", &tip, grasp).unwrap(),
            Status::UnknownObject,
        ),
        (
            &|| client.detach("ghost", grasp).unwrap(),
            Status::NotAttached,
        ),
        (
            &|| {
                client
                    .attach_shape("slab", &tip, ShapeKind::Box, slab, grasp)
                    .unwrap()
            },
            Status::AttachCollides,
        ),
    ];
    for (send, status) in refusals {
        let before = client.status(Duration::from_secs(2)).unwrap();
        send();
        let s = wait_for(&client, "the refusal", |s| {
            s.rejected == before.rejected + 1
        });
        assert_eq!(s.last_rejection_status, status as u32, "{s:?}");
        let why = ember_sdk::wire::name_str(&s.last_rejection);
        assert!(!why.is_empty(), "{status:?}");
        assert_eq!((s.world_objects, s.world_attached), (3, 1), "{why}");
    }

    // Put down out of the way, the rod is a world object and the goal is reachable again.
    client
        .detach("rod", [2.5, 1.5, 0.3, 0.0, 0.0, 0.0, 1.0])
        .unwrap();
    wait_for(&client, "the detach", |s| {
        s.world_attached == 0 && s.world_objects == 4
    });
    assert_eq!(plan(&call), Status::Ok);
    wait_for(&client, "the recorder", |s| s.recorded >= 14);
    drop(client);
    a.signal("-TERM");
    let mut a = a;
    assert!(a.child.wait().unwrap().success());

    // Replayed into a fresh daemon: the same world after each change, the same three answers.
    let b = Daemon::start("att-b");
    crate::daemon::replay_check(&a.recording, &b, 3);
    let s = b.client().status(Duration::from_secs(2)).unwrap();
    assert_eq!((s.world_objects, s.world_attached, s.rejected), (4, 0, 5));
}

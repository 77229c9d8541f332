//! `world`: the world model under many tracked objects, as the daemon's ingest keeps it. Adds
//! `--objects` spheres on a 15 × 15 grid of layers 0.1 m apart (close enough to pair with their
//! neighbours), then moves `--updates` of them by 1 cm, each move followed by a snapshot (what
//! ingest does per batch). Ends with
//! `RESULT world objects=<n> pairs=<n> add_ms=<f> update_snapshot_ms=<f>` (the last: all the
//! updates with their snapshots).
//!
//! Then ingest against the map's size: the map is grown by walls of points seen from many
//! poses, and after each growth step one camera-sized cloud (320 × 240 points on a wall 1.5 m
//! ahead) is folded in and snapshotted as the daemon's ingest thread does, `--repeats` times,
//! once with the previous snapshot still held (as a plan in flight holds it) and once without.
//! One line per size: `RESULT world_ingest blocks=<n> memory_mb=<f> held_ms=<f> free_ms=<f>
//! unknown_box=<0|1> joints=<0|1>` (medians; with `--unknown-box`, unknown space in that box is
//! an obstacle for planning, so each cloud also remakes the planner's copy of the map and its
//! grids; with `--joints`, each cloud is self-filtered at that joint state and the robot's
//! volume in the box is observed free). With `--joints`, also the joint states themselves:
//! `joint_same_us=` (the median joint state where the robot stands, as it streams them
//! standing still: with an unknown box, not looked at again), `joint_moved_ms=` (the median
//! joint state with the
//! torso 3 mm higher than the last, and the snapshot when it freed voxels) and
//! `joint_moved_freeing=` (how many of those freed voxels).

use ember_engine::collision::Shape;
use ember_engine::robot::Robot;
use ember_engine::world::map::MapParams;
use ember_engine::world::model::{World, WorldParams};
use ember_engine::world::Object;
use ember_engine::Pose;
use std::sync::Arc;
use std::time::Instant;

#[derive(clap::Args)]
pub struct Args {
    /// Objects to add.
    #[arg(long, default_value_t = 3000)]
    objects: usize,
    /// Moves, each followed by a snapshot.
    #[arg(long, default_value_t = 100)]
    updates: usize,
    /// Map growth steps for the ingest measurement (0: skip it).
    #[arg(long, default_value_t = 5)]
    map_steps: usize,
    /// Clouds measured per map size and mode.
    #[arg(long, default_value_t = 9)]
    repeats: usize,
    /// For the ingest measurement: unknown space in this box is an obstacle, as emberd's
    /// `planner.unknown_obstacle_min/max` make it (`X0,Y0,Z0,X1,Y1,Z1`, metres).
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    unknown_box: Option<Vec<f64>>,
    /// For the ingest measurement: the built-in Fetch's joint state (8 values), so each cloud
    /// is self-filtered at it and, with `--unknown-box`, the robot's volume in the box is
    /// observed free, as emberd does once joint states come in.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    joints: Option<Vec<f64>>,
}

/// `w × h` points on a wall `d` metres ahead of a sensor (optical frame: z forward), spanning
/// `span` metres, rippled so that neighbouring clouds do not coincide.
fn wall(w: usize, h: usize, d: f32, span: f32, phase: f32) -> Vec<[f32; 3]> {
    (0..w * h)
        .map(|i| {
            let (u, v) = (
                (i % w) as f32 / w as f32 - 0.5,
                (i / w) as f32 / h as f32 - 0.5,
            );
            [u * span, v * span, d + 0.05 * (7.0 * u + phase).sin()]
        })
        .collect()
}

/// The ingest measurement (see the module docs).
fn ingest(args: &Args) -> anyhow::Result<()> {
    let mut world = World::new(&WorldParams {
        map: MapParams {
            bounds: Some(([-2.0, -2.0, -0.1], [3.0, 2.0, 2.5])),
            discretize: true,
            ..MapParams::default()
        },
        use_map: true,
        carve_padding: Some(0.02),
        unknown_obstacles: args
            .unknown_box
            .as_ref()
            .map(|b| ([b[0], b[1], b[2]], [b[3], b[4], b[5]])),
        self_filter_padding: 0.03,
    });
    let robot = Robot::builtin("fetch").expect("built-in");
    if let Some(q) = &args.joints {
        robot.validate(q)?;
        world.set_joints(&robot, q.clone());
    }
    // A head camera looking ahead (optical z along the base's x).
    let camera = Pose::translation(0.15, 0.0, 1.0)
        * Pose::rotation(nalgebra::Vector3::y() * std::f64::consts::FRAC_PI_2);
    let mut pose_k = 0usize;
    for step in 0..args.map_steps {
        // Grow: walls seen from poses turning around the robot and climbing.
        for _ in 0..(4usize << step) {
            pose_k += 1;
            let yaw = pose_k as f64 * 0.7;
            let pitch = 0.4 + 0.6 * ((pose_k as f64 * 0.37).sin());
            let from = Pose::translation(0.0, 0.0, 0.3 + 0.05 * (pose_k % 30) as f64)
                * Pose::rotation(nalgebra::Vector3::z() * yaw)
                * Pose::rotation(
                    nalgebra::Vector3::y() * (std::f64::consts::FRAC_PI_2 + pitch - 0.4),
                );
            let points = wall(
                160,
                120,
                1.0 + (pose_k % 5) as f32 * 0.4,
                2.5,
                pose_k as f32,
            );
            world.insert_cloud(&robot, &points, &from);
        }
        let blocks = world.snapshot().map.block_count();
        let memory_mb = world.snapshot().map.memory_bytes() as f64 / 1e6;
        let mut time = |hold: bool| {
            let mut held = Some(Arc::new(world.snapshot()));
            let mut ms: Vec<f64> = (0..args.repeats)
                .map(|r| {
                    let points = wall(320, 240, 1.5, 1.6, r as f32 * 0.3);
                    let t = Instant::now();
                    world.insert_cloud(&robot, &points, &camera);
                    let snap = Arc::new(world.snapshot());
                    let elapsed = t.elapsed().as_secs_f64() * 1e3;
                    held = hold.then_some(snap);
                    elapsed
                })
                .collect();
            drop(held);
            ember_sdk::stats::median(&mut ms)
        };
        let (held_ms, free_ms) = (time(true), time(false));
        println!(
            "map of {blocks} blocks ({memory_mb:.1} MB): a {}-point cloud folded in and snapshotted in {held_ms:.2} ms with the last snapshot held, {free_ms:.2} ms without",
            320 * 240
        );
        let joint_keys = match &args.joints {
            Some(q) => {
                let (look_us, moved_ms, freeing) =
                    joint_states(&mut world, &robot, q, args.repeats);
                println!(
                    "a joint state where the robot stands: {look_us:.1} µs; moved (the torso up 3 mm; {freeing} of {} freed voxels), with the snapshot when it did: {moved_ms:.2} ms",
                    args.repeats
                );
                format!(" joint_same_us={look_us:.2} joint_moved_ms={moved_ms:.3} joint_moved_freeing={freeing}")
            }
            None => String::new(),
        };
        println!(
            "RESULT world_ingest blocks={blocks} memory_mb={memory_mb:.2} held_ms={held_ms:.3} free_ms={free_ms:.3} unknown_box={} joints={}{joint_keys}",
            u8::from(args.unknown_box.is_some()),
            u8::from(args.joints.is_some())
        );
    }
    Ok(())
}

/// Joint states at `q` and moved from it (see the module docs): the median time of one at
/// `q` (where the robot stands: with an unknown box, within the tolerance of the last state
/// looked at, so not looked at again),
/// and of one with the torso raised 3 mm more each time (the arm's new volume in the box freed)
/// followed, when it freed voxels, by the snapshot that carries them; and how many did. Leaves
/// the joint state at `q`.
fn joint_states(world: &mut World, robot: &Robot, q: &[f64], repeats: usize) -> (f64, f64, usize) {
    let mut look: Vec<f64> = (0..repeats)
        .map(|_| {
            let t = Instant::now();
            std::hint::black_box(world.set_joints(robot, q.to_vec()));
            t.elapsed().as_secs_f64() * 1e6
        })
        .collect();
    let mut freeing = 0;
    let mut moved: Vec<f64> = (1..=repeats)
        .map(|r| {
            let mut up = q.to_vec();
            up[0] = (up[0] + 0.003 * r as f64).min(robot.variables()[0].upper);
            let t = Instant::now();
            if world.set_joints(robot, up) {
                freeing += 1;
                std::hint::black_box(world.snapshot());
            }
            t.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    world.set_joints(robot, q.to_vec());
    (
        ember_sdk::stats::median(&mut look),
        ember_sdk::stats::median(&mut moved),
        freeing,
    )
}

fn object(k: usize, dx: f64) -> Object {
    Object {
        name: format!("o{k}"),
        shape: Shape::Sphere { radius: 0.03 },
        pose: Pose::translation(
            0.5 + (k % 15) as f64 * 0.1 + dx,
            -0.7 + ((k / 15) % 15) as f64 * 0.1,
            0.2 + (k / 225) as f64 * 0.1,
        ),
    }
}

pub fn run(args: Args) -> anyhow::Result<()> {
    if let Some(b) = &args.unknown_box {
        anyhow::ensure!(
            b.len() == 6 && (0..3).all(|a| b[a] < b[a + 3]),
            "--unknown-box takes X0,Y0,Z0,X1,Y1,Z1 with each min below its max, got {b:?}"
        );
    }
    let mut world = World::new(&WorldParams {
        map: MapParams::default(),
        use_map: false,
        carve_padding: None,
        unknown_obstacles: None,
        self_filter_padding: 0.03,
    });
    let t = Instant::now();
    for k in 0..args.objects {
        world.upsert_object(object(k, 0.0));
    }
    let add_ms = t.elapsed().as_secs_f64() * 1e3;
    let pairs = world.snapshot().pairs.len();
    let t = Instant::now();
    for u in 0..args.updates {
        world.upsert_object(object((u * 29) % args.objects.max(1), 0.01));
        std::hint::black_box(world.snapshot());
    }
    let update_ms = t.elapsed().as_secs_f64() * 1e3;
    println!(
        "{} objects, {pairs} SPARK pairs: added in {add_ms:.1} ms; {} moves, each with a snapshot, in {update_ms:.1} ms",
        args.objects, args.updates
    );
    println!(
        "RESULT world objects={} pairs={pairs} add_ms={add_ms:.2} update_snapshot_ms={update_ms:.2}",
        args.objects
    );
    ingest(&args)?;
    Ok(())
}

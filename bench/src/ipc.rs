//! `ipc`: the hand-off costs of the daemon. Starts a real `ember run` (from the same target
//! folder), then
//! - publishes 640×480 clouds written straight into shared memory and reads, from the daemon's
//!   status service, the time from hand-off to receipt in the daemon (p50/p99);
//! - sends the same plan request through the daemon and to the engine in this process (both
//!   timed, for reference), and times requests the daemon answers before planning (a protocol
//!   version mismatch): their round trip is what the transport adds to an in-process call, and
//!   is the reported overhead (p50/p99).
//!
//! - first, measures the idle daemon's CPU use (a client connected, nothing sent).
//!
//! Flags: `--clouds N` (default 100), `--plans N` (default 300), `--idle-s S` (5),
//! `--ingest-spin-us U` (the daemon's `ingest.spin_us`, 0). Ends with
//! `RESULT ipc cloud_p50_us=<f> cloud_p99_us=<f> plan_overhead_p50_us=<f> plan_overhead_p99_us=<f> idle_cpu_pct=<f>`.

use crate::daemon::DaemonProcess;
use ember_engine::planning::{self, Goal, PlanRequest, PlannerParams, UniformSampler};
use ember_engine::robot::Robot;
use ember_engine::world::Environment;
use ember_sdk::wire::{Method, Point};
use ember_sdk::{Client, PlanCall, Status};
use std::time::{Duration, Instant};

#[derive(clap::Args)]
pub struct Args {
    /// Clouds to publish.
    #[arg(long, default_value_t = 100)]
    clouds: usize,
    /// Plan requests to time.
    #[arg(long, default_value_t = 300)]
    plans: usize,
    /// Seconds the idle daemon's CPU use is measured over.
    #[arg(long, default_value_t = 5)]
    idle_s: u64,
    /// The daemon's `ingest.spin_us`.
    #[arg(long, default_value_t = 0)]
    ingest_spin_us: u64,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let config = format!(
        "[experience]\nonline_learning = false\n[ingest]\nspin_us = {}\n",
        args.ingest_spin_us
    );
    let daemon = DaemonProcess::start("ipc", &config, &["--no-monitor"])?;
    // Idle: connected client, nothing sent, for a few seconds.
    let idle_pct = {
        let _client = Client::connect(&daemon.instance)?;
        std::thread::sleep(Duration::from_secs(1));
        let (c0, t0) = (daemon.cpu_seconds(), Instant::now());
        std::thread::sleep(Duration::from_secs(args.idle_s));
        match (c0, daemon.cpu_seconds()) {
            (Some(a), Some(b)) => (b - a) / t0.elapsed().as_secs_f64() * 100.0,
            _ => f64::NAN,
        }
    };
    println!(
        "idle daemon (a client connected, nothing sent, {} s): {idle_pct:.2}% of a core",
        args.idle_s
    );
    measure(
        &daemon.instance,
        &args,
        &daemon.dir.join("recordings"),
        idle_pct,
    )
}

fn measure(
    instance: &str,
    args: &Args,
    recordings: &std::path::Path,
    idle_pct: f64,
) -> anyhow::Result<()> {
    let client = Client::connect(instance)?;
    let t = Duration::from_secs(10);
    // Clouds: a wall 1.5 m ahead, 640×480 points, one every 50 ms.
    let n = 640 * 480;
    for k in 0..args.clouds {
        client.publish_cloud(
            "head_camera",
            [0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            0,
            n,
            |i| Point {
                x: 1.5,
                y: -0.8 + (i % 640) as f32 * 0.0025,
                z: -0.6 + (i / 640) as f32 * 0.0025 + (k % 2) as f32 * 0.001,
            },
        )?;
        let deadline = Instant::now() + t;
        while client.status(t)?.clouds < (k + 1) as u64 {
            anyhow::ensure!(
                Instant::now() < deadline,
                "the daemon did not take cloud {k}"
            );
            std::thread::sleep(Duration::from_millis(1));
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    let s = client.status(t)?;
    let (cloud_p50, cloud_p99) = (s.cloud_latency_p50_us, s.cloud_latency_p99_us);

    // Recording under load: a burst of clouds as fast as the daemon takes them.
    let before = client.status(t)?;
    let burst = Instant::now();
    for k in 0..args.clouds {
        client.publish_cloud(
            "head_camera",
            [0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            0,
            n,
            |i| Point {
                x: 1.5 + (k % 3) as f32 * 0.01,
                y: -0.8 + (i % 640) as f32 * 0.0025,
                z: -0.6 + (i / 640) as f32 * 0.0025,
            },
        )?;
        std::thread::sleep(Duration::from_millis(5));
    }
    let deadline = Instant::now() + Duration::from_secs(60);
    let after = loop {
        let s = client.status(t)?;
        if s.recorded + s.recording_dropped >= before.recorded + s.clouds - before.clouds
            || Instant::now() > deadline
        {
            break s;
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let secs = burst.elapsed().as_secs_f64();
    let taken = after.clouds - before.clouds;
    let written = after.recorded - before.recorded;
    let dropped = after.recording_dropped - before.recording_dropped;
    let disk: u64 = std::fs::read_dir(recordings)?
        .flatten()
        .filter_map(|e| e.metadata().ok())
        .map(|m| m.len())
        .sum();
    let per_cloud = disk as f64 / (s.clouds + taken).max(1) as f64;
    println!(
        "recording under load: {taken} clouds taken in {secs:.1} s ({:.1} clouds/s, {:.0} MB/s raw), {written} recorded, {dropped} dropped; {:.2} MB on disk per cloud (zstd) = {:.0} MB per minute at 30 Hz",
        taken as f64 / secs,
        taken as f64 * n as f64 * 12.0 / 1e6 / secs,
        per_cloud / 1e6,
        per_cloud * 30.0 * 60.0 / 1e6
    );

    // Plans: an empty world (the map is not an obstacle by default).
    let robot = Robot::builtin("fetch")?;
    let env = Environment::new();
    let start = robot.named_state("tuck").expect("named").to_vec();
    // A small wrist turn: solved by the direct connection, so the planner's own time is small
    // and steady and the difference is the transport.
    let mut goal = start.clone();
    goal[7] += 0.3;
    let call = PlanCall {
        start: start.clone(),
        goals: vec![goal.clone()],
        pose: None,
        method: Method::Uniform,
        time_limit_s: 5.0,
        seed: 1,
        trajectory: None,
    };
    let request = PlanRequest {
        start,
        goal: Goal::Joints(vec![goal]),
        params: PlannerParams {
            seed: 1,
            time_limit: Duration::from_secs(5),
            ..Default::default()
        },
    };
    // Warm both paths, then time each in its own loop (interleaving them lets one path's cache
    // misses land on the other).
    for _ in 0..20 {
        client.plan(&call, t)?;
        planning::plan(&robot, &env, &request, &mut UniformSampler)?;
    }
    let mut round = Vec::new();
    for _ in 0..args.plans {
        let t0 = Instant::now();
        let reply = client.plan(&call, t)?;
        round.push(t0.elapsed().as_secs_f64() * 1e6);
        anyhow::ensure!(
            reply.status == Status::Ok,
            "plan failed: {}",
            reply.message()
        );
    }
    let mut local = Vec::new();
    for _ in 0..args.plans {
        let t1 = Instant::now();
        planning::plan(&robot, &env, &request, &mut UniformSampler)?;
        local.push(t1.elapsed().as_secs_f64() * 1e6);
    }
    let pct = ember_sdk::stats::quantile;
    let (rt50, rt99) = (pct(&mut round, 0.5), pct(&mut round, 0.99));
    let (lt50, lt99) = (pct(&mut local, 0.5), pct(&mut local, 0.99));
    // The transport alone: requests the daemon refuses before planning (wrong protocol version),
    // whose in-process equivalent costs nothing.
    let mut bare = Vec::new();
    let header = ember_sdk::wire::PlanRequestHeader {
        version: 0,
        dof: 8,
        goal_count: 1,
        ..Default::default()
    };
    let values: Vec<f64> = call.start.iter().chain(&call.goals[0]).copied().collect();
    for _ in 0..args.plans {
        let t0 = Instant::now();
        let reply = client.plan_raw(header, &values, t)?;
        bare.push(t0.elapsed().as_secs_f64() * 1e6);
        anyhow::ensure!(
            reply.status == Status::VersionMismatch,
            "unexpected status {:?}",
            reply.status
        );
    }
    let (o50, o99) = (pct(&mut bare, 0.5), pct(&mut bare, 0.99));
    println!("cloud 640x480 ({:.1} MB), {} clouds: hand-off to receipt in the daemon p50 {cloud_p50:.1} us, p99 {cloud_p99:.1} us", n as f64 * 12.0 / 1e6, args.clouds);
    println!("plan, {} requests each: round trip p50 {rt50:.1} / p99 {rt99:.1} us, in-process p50 {lt50:.1} / p99 {lt99:.1} us", args.plans);
    println!("plan round trip of a request refused before planning (the transport's cost): p50 {o50:.1} us, p99 {o99:.1} us");
    println!("RESULT ipc cloud_p50_us={cloud_p50:.1} cloud_p99_us={cloud_p99:.1} plan_overhead_p50_us={o50:.1} plan_overhead_p99_us={o99:.1} idle_cpu_pct={idle_pct:.2} ingest_spin_us={}", args.ingest_spin_us);
    Ok(())
}

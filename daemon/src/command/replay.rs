//! `ember replay FILE...`: feeds a recorded session into a running daemon through the SDK —
//! objects, joint states, clouds (with their sensor poses) and plan requests, in recorded order,
//! as fast as possible or at a multiple of real time. Before each plan request, and before it
//! exits, it waits until the daemon has taken everything sent before it, so the world matches
//! the recording and no input leaves with the replay's publishers; with
//! `--check` each reply is compared with the recorded one (same seed, same world: same path,
//! and the same timed trajectory when the request asked for one).

use super::group_order;
use crate::cli::ReplayArgs;
use ember_sdk::session::{Event, Session, TopicMap};
use ember_sdk::wire::Point;
use ember_sdk::Client;
use std::process::ExitCode;
use std::time::{Duration, Instant};

/// Inputs the daemon has taken (applied or rejected).
fn taken(client: &Client) -> anyhow::Result<u64> {
    let s = client.status(Duration::from_secs(5))?;
    Ok(s.objects + s.rejected + s.clouds + s.joint_states)
}

/// Waits until at most `ahead` of the `sent` inputs are still on their way to the daemon, so
/// none is lost to a full subscriber queue (the cloud queue holds 2, joint states 16). A daemon
/// that stops taking inputs for 60 s is an error.
fn wait_taken(client: &Client, base: u64, sent: u64, ahead: u64) -> anyhow::Result<()> {
    let deadline = Instant::now() + Duration::from_secs(60);
    while taken(client)? + ahead < base + sent {
        anyhow::ensure!(
            Instant::now() < deadline,
            "the daemon took no input for 60 s ({} of {sent} taken)",
            taken(client)? - base
        );
        std::thread::sleep(Duration::from_micros(200));
    }
    Ok(())
}

pub fn run(args: ReplayArgs) -> anyhow::Result<ExitCode> {
    let client = Client::connect(&args.instance).map_err(|e| match e {
        ember_sdk::ClientError::NoDaemon(_) => anyhow::anyhow!(
            "cannot reach the daemon: {e} (start it with `ember run --instance {}`)",
            args.instance
        ),
        e => anyhow::anyhow!("cannot attach to the daemon: {e}"),
    })?;
    let robot = super::load_robot(&args.robot.spec("fetch"))?;
    let topics = TopicMap::parse(&args.topic_map)?;
    let base = taken(&client)?;
    let started = Instant::now();
    let mut sent = 0u64;
    let (mut plans, mut reproduced, mut messages) = (0usize, 0usize, 0usize);
    // Replies by their request's receive stamp, until the recorded answer is reached: the
    // recorded response may come after later requests (workers answer in any order).
    let mut replies: std::collections::HashMap<u64, (Vec<f64>, u32)> = Default::default();
    let mut trajectories: std::collections::HashMap<u64, ember_sdk::wire::TrajectoryBlock> =
        Default::default();
    let (mut timed, mut timed_reproduced) = (0usize, 0usize);
    for file in &args.files {
        let session = Session::open(file)?;
        let mut clock: Option<(u64, Instant)> = None;
        messages += session.for_each(args.allow_truncated, &topics, |log_ns, event| -> anyhow::Result<()> {
            if let Some(speed) = args.speed {
                let (t0, w0) = *clock.get_or_insert((log_ns, Instant::now()));
                let due = Duration::from_secs_f64(log_ns.saturating_sub(t0) as f64 / 1e9 / speed);
                if let Some(wait) = due.checked_sub(w0.elapsed()) {
                    std::thread::sleep(wait);
                }
            }
            match event {
                Event::Object(u) => {
                    wait_taken(&client, base, sent, 8)?;
                    client.publish_object_raw(u)?;
                    sent += 1;
                }
                Event::Joints { names, positions, .. } => {
                    let Some(q) = group_order(&robot, &names, &positions) else {
                        return Ok(()); // Not the robot's joints: nothing to send.
                    };
                    wait_taken(&client, base, sent, 8)?;
                    client.publish_joints(&q)?;
                    sent += 1;
                }
                Event::Cloud { frame_id, stamp_ns, pose, points } => {
                    wait_taken(&client, base, sent, 0)?;
                    client.publish_cloud(&frame_id, pose, stamp_ns, points.len(), |i| Point {
                        x: points[i][0],
                        y: points[i][1],
                        z: points[i][2],
                    })?;
                    sent += 1;
                }
                Event::PlanRequest(r) => {
                    // The world must hold everything recorded before the request.
                    wait_taken(&client, base, sent, 0)?;
                    let header = r.request;
                    let timeout = Duration::from_secs_f64(r.request.time_limit_s.max(1.0) + 30.0);
                    let reply = client.plan_raw(header, &r.values, timeout)?;
                    let stamp = r.header.stamp.ns();
                    replies.insert(stamp, (reply.path.concat(), reply.header.status));
                    if let Some(t) = reply.trajectory {
                        trajectories.insert(stamp, t);
                    }
                    plans += 1;
                }
                Event::PlanResponse(recorded) => {
                    if let Some((path, status)) = replies.remove(&recorded.header.stamp.ns()) {
                        if status == recorded.status && path == recorded.path {
                            reproduced += 1;
                        } else if args.check {
                            eprintln!("plan {plans}: reply differs from the recording (status {status} vs {})", recorded.status);
                        }
                    }
                }
                Event::PlanTrajectory(recorded) => {
                    timed += 1;
                    match trajectories.remove(&recorded.header.stamp.ns()) {
                        Some(t) if recorded.matches(&t) => {
                            timed_reproduced += 1;
                        }
                        _ if args.check => eprintln!("plan {plans}: trajectory differs from the recording"),
                        _ => {}
                    }
                }
            }
            Ok(())
        })?;
    }
    // The last inputs may still be on their way: a publisher that goes away with samples
    // its subscriber has not taken yet can take them with it.
    wait_taken(&client, base, sent, 0)?;
    println!(
        "messages replayed: {messages} in {:.1} s",
        started.elapsed().as_secs_f64()
    );
    println!("plans reproduced: {reproduced}/{plans}");
    if timed > 0 {
        println!("trajectories reproduced: {timed_reproduced}/{timed}");
    }
    Ok(
        if args.check && (reproduced != plans || timed_reproduced != timed) {
            ExitCode::from(1)
        } else {
            ExitCode::SUCCESS
        },
    )
}

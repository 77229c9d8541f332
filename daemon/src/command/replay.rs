//! `ember replay FILE...`: feeds a recorded session into a running daemon through the SDK —
//! objects, joint states, clouds (with their sensor poses) and plan requests, in recorded order,
//! as fast as possible or at a multiple of real time. Before each plan request it waits until the
//! daemon has taken everything sent before it, so the world matches the recording; with
//! `--check` each reply is compared with the recorded one (same seed, same world: same path).

use crate::cli::ReplayArgs;
use ember_sdk::recording::{
    self, ObjectUpdate as RecObject, PlanRequest, PlanResponse, PointCloud2, PoseStamped,
};
use ember_sdk::wire::{self, ObjectUpdate, PlanRequestHeader, Point, PROTOCOL_VERSION};
use ember_sdk::Client;
use std::collections::BTreeMap;
use std::process::ExitCode;
use std::time::{Duration, Instant};

/// Inputs the daemon has taken (applied or rejected).
fn taken(client: &Client) -> anyhow::Result<u64> {
    let s = client.status(Duration::from_secs(5))?;
    Ok(s.objects + s.rejected + s.clouds + s.joint_states)
}

pub fn run(args: ReplayArgs) -> anyhow::Result<ExitCode> {
    let client = Client::connect(&args.instance).map_err(|e| {
        anyhow::anyhow!(
            "cannot reach the daemon: {e} (start it with `ember run --instance {}`)",
            args.instance
        )
    })?;
    let base = taken(&client)?;
    let mut sent = 0u64;
    let mut counts: BTreeMap<String, usize> = BTreeMap::new();
    let (mut plans, mut reproduced) = (0usize, 0usize);
    let mut pending_cloud: Option<PointCloud2> = None;
    let mut last_reply: Option<(u64, Vec<f64>, u32)> = None;
    for file in &args.files {
        let bytes = std::fs::read(file)
            .map_err(|e| anyhow::anyhow!("cannot read {}: {e}", file.display()))?;
        if !bytes.starts_with(mcap::MAGIC) {
            anyhow::bail!(
                "{}: not a readable MCAP file (no MCAP magic at the start)",
                file.display()
            );
        }
        let stream = mcap::MessageStream::new(&bytes)
            .map_err(|e| anyhow::anyhow!("{}: not a readable MCAP file: {e}", file.display()))?;
        let mut first_log: Option<(u64, Instant)> = None;
        for message in stream {
            let m = match message {
                Ok(m) => m,
                Err(e) if args.allow_truncated => {
                    eprintln!("{}: stopping at damaged data ({e}); what came before was replayed", file.display());
                    break;
                }
                Err(e) => anyhow::bail!("{}: damaged after {} messages: {e} (use --allow-truncated to replay what is intact)", file.display(), counts.values().sum::<usize>()),
            };
            if let Some(speed) = args.speed {
                let (t0, w0) = *first_log.get_or_insert((m.log_time, Instant::now()));
                let due =
                    Duration::from_secs_f64(m.log_time.saturating_sub(t0) as f64 / 1e9 / speed);
                if let Some(wait) = due.checked_sub(w0.elapsed()) {
                    std::thread::sleep(wait);
                }
            }
            let topic = m.channel.topic.as_str();
            let bad = |e: String| {
                anyhow::anyhow!("{}: {topic} message {}: {e}", file.display(), m.sequence)
            };
            match topic {
                "/ember/objects" => {
                    let o: RecObject = recording::decode(&m.data).map_err(bad)?;
                    client.publish_object_raw(ObjectUpdate {
                        version: PROTOCOL_VERSION,
                        shape: o.shape,
                        stamp_ns: o.header.stamp.ns(),
                        id: wire::name(&o.id),
                        dims: o.dims,
                        pose: o.pose.to_wire(),
                    })?;
                    sent += 1;
                }
                "/ember/joints" => {
                    let js: recording::JointState = recording::decode(&m.data).map_err(bad)?;
                    client.publish_joints(&js.position)?;
                    sent += 1;
                }
                "/ember/cloud" => pending_cloud = Some(recording::decode(&m.data).map_err(bad)?),
                "/ember/cloud_pose" => {
                    let pose: PoseStamped = recording::decode(&m.data).map_err(bad)?;
                    if let Some(cloud) = pending_cloud
                        .take()
                        .filter(|c| c.header.stamp == pose.header.stamp)
                    {
                        let pts = cloud
                            .xyz_points()
                            .ok_or_else(|| bad("cloud without float32 x, y, z".into()))?;
                        client.publish_cloud(
                            &cloud.header.frame_id,
                            pose.pose.to_wire(),
                            cloud.header.stamp.ns(),
                            pts.len(),
                            |i| Point {
                                x: pts[i][0],
                                y: pts[i][1],
                                z: pts[i][2],
                            },
                        )?;
                        sent += 1;
                    }
                }
                "/ember/plan_request" => {
                    let r: PlanRequest = recording::decode(&m.data).map_err(bad)?;
                    // The world must hold everything recorded before the request.
                    let deadline = Instant::now() + Duration::from_secs(60);
                    while taken(&client)? < base + sent && Instant::now() < deadline {
                        std::thread::sleep(Duration::from_millis(2));
                    }
                    let header = PlanRequestHeader {
                        version: r.version,
                        dof: r.dof,
                        goal_kind: r.goal_kind,
                        goal_count: r.goal_count,
                        method: r.method,
                        flags: 0,
                        time_limit_s: r.time_limit_s,
                        seed: r.seed,
                        pose: r.pose,
                        position_tolerance: r.position_tolerance,
                        orientation_tolerance: r.orientation_tolerance,
                    };
                    let reply = client.plan_raw(
                        header,
                        &r.values,
                        Duration::from_secs_f64(r.time_limit_s.max(1.0) + 30.0),
                    )?;
                    last_reply = Some((
                        r.header.stamp.ns(),
                        reply.path.concat(),
                        reply.header.status,
                    ));
                    plans += 1;
                }
                "/ember/plan_response" => {
                    let recorded: PlanResponse = recording::decode(&m.data).map_err(bad)?;
                    if let Some((stamp, path, status)) = last_reply.take() {
                        if stamp == recorded.header.stamp.ns()
                            && status == recorded.status
                            && path == recorded.path
                        {
                            reproduced += 1;
                        } else if args.check {
                            eprintln!("plan {plans}: reply differs from the recording (status {status} vs {})", recorded.status);
                        }
                    }
                }
                _ => {}
            }
            *counts.entry(topic.to_string()).or_insert(0) += 1;
        }
    }
    for (topic, n) in &counts {
        println!("{topic}: {n}");
    }
    println!("plans reproduced: {reproduced}/{plans}");
    Ok(if args.check && reproduced != plans {
        ExitCode::from(1)
    } else {
        ExitCode::SUCCESS
    })
}

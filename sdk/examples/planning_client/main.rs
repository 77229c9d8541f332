//! A planning client to copy into a robot stack: asks a running `emberd` for a joint-space plan
//! and for a pose-goal plan, and checks the answers.
//!
//! Run: `ember run --instance demo` in one terminal, then
//! `cargo run -p ember-sdk --example planning_client -- demo`.

use ember_sdk::wire::Method;
use ember_sdk::{Client, PlanCall, Status};
use std::time::Duration;

fn main() -> anyhow::Result<()> {
    let instance = std::env::args().nth(1).unwrap_or_else(|| "default".into());
    let client = Client::connect(&instance)?;
    let tuck = vec![0.1, 1.32, 1.40, -0.2, 1.72, 0.0, 1.66, 0.0];
    let call = PlanCall {
        start: tuck.clone(),
        goals: vec![vec![0.3, 0.2, -0.6, 0.0, 0.6, 0.0, 0.0, 0.0]],
        pose: None,
        method: Method::Auto,
        time_limit_s: 5.0,
        seed: 7,
        // Timed under the robot's joint limits, at the daemon's configured scaling (0, 0).
        trajectory: Some((0.0, 0.0)),
    };
    let reply = client.plan(&call, Duration::from_secs(10))?;
    println!(
        "joint goal: {:?}, {} waypoints, {:.0} us in the daemon ({})",
        reply.status,
        reply.path.len(),
        reply.header.total_us,
        reply.message()
    );
    anyhow::ensure!(reply.status == Status::Ok, "joint goal not solved");
    let trajectory = reply
        .trajectory
        .as_ref()
        .filter(|t| !t.times.is_empty())
        .ok_or_else(|| anyhow::anyhow!("no trajectory: {}", reply.message()))?;
    println!(
        "trajectory: executes in {:.2} s, {} samples (positions, velocities, accelerations)",
        trajectory.duration,
        trajectory.times.len()
    );

    // The wrist 70 cm ahead, 1 m up, gripper level: a pose goal (x y z qx qy qz qw, tolerances).
    let pose_call = PlanCall {
        goals: vec![],
        pose: Some(([0.7, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0], 0.01, 0.05)),
        trajectory: None,
        ..call
    };
    let reply = client.plan(&pose_call, Duration::from_secs(10))?;
    println!(
        "pose goal: {:?}, {} waypoints ({})",
        reply.status,
        reply.path.len(),
        reply.message()
    );
    anyhow::ensure!(reply.status == Status::Ok, "pose goal not solved");

    // A bad request gets its status, not a crash.
    let bad = PlanCall {
        start: vec![0.0; 5],
        ..pose_call
    };
    let reply = client.plan(&bad, Duration::from_secs(10))?;
    println!(
        "wrong joint count: {:?} ({})",
        reply.status,
        reply.message()
    );
    anyhow::ensure!(reply.status == Status::WrongDof);
    println!("ok");
    Ok(())
}

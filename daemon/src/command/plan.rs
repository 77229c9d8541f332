//! `ember plan`: one plan for a scene file and a request file.

use crate::cli::PlanArgs;
use ember_engine::planning::{self, PlanRequest, PlannerParams, UniformSampler};
use ember_engine::scene::{moveit, Scene};
use ember_engine::trajectory::TimingParams;
use std::process::ExitCode;
use std::time::{Duration, Instant};

pub fn run(args: PlanArgs) -> anyhow::Result<ExitCode> {
    let robot = super::load_robot(&args.robot.spec("fetch"))?;
    let scene = Scene::load(&args.scene)?;
    let text = std::fs::read_to_string(&args.request)
        .map_err(|e| anyhow::anyhow!("cannot read {}: {e}", args.request.display()))?;
    let request = moveit::request_from_yaml(&text, &args.request.display().to_string(), &robot)?;
    let env = scene
        .environment()
        .map_err(|e| anyhow::anyhow!("{}: {e}", args.scene.display()))?;
    // Joints outside the group take the start state's values; objects the scene attaches (held
    // in the gripper) become part of the robot.
    let robot = scene
        .robot_with(&robot, &request.start_joints)
        .map_err(|e| anyhow::anyhow!("{}: {e}", args.scene.display()))?;
    let time_limit = args
        .time_limit
        .or(request.allowed_planning_time)
        .unwrap_or(10.0);
    let max = ember_engine::scene::moveit::MAX_PLANNING_TIME_S;
    anyhow::ensure!(
        time_limit > 0.0 && time_limit <= max,
        "--time-limit must be in (0, {max}] s, got {time_limit}"
    );
    let timing = (!args.no_trajectory).then_some(TimingParams {
        velocity_scaling: args.velocity_scaling.or(request.scaling.0).unwrap_or(1.0),
        acceleration_scaling: args
            .acceleration_scaling
            .or(request.scaling.1)
            .unwrap_or(1.0),
        max_deviation: args.max_deviation,
        sample_period: args.sample_period,
        default_acceleration: args.default_acceleration,
    });
    let req = PlanRequest {
        start: request.start,
        goal: request.goal,
        params: PlannerParams {
            seed: args.seed,
            time_limit: Duration::from_secs_f64(time_limit),
            max_iterations: args
                .max_iterations
                .unwrap_or(PlannerParams::default().max_iterations),
            simplify: !args.no_simplify,
            certify: !args.no_certify,
            timing,
            ..Default::default()
        },
    };
    let t = Instant::now();
    let outcome = planning::plan(&robot, &env, &req, &mut UniformSampler);
    let total_ms = t.elapsed().as_secs_f64() * 1e3;
    match outcome {
        Ok(res) => {
            let s = &res.stats;
            let trajectory = match &res.trajectory {
                Some(Ok(t)) => {
                    if let Some(out) = &args.trajectory_out {
                        std::fs::write(out, moveit::trajectory_to_yaml(t))
                            .map_err(|e| anyhow::anyhow!("cannot write {}: {e}", out.display()))?;
                    }
                    Some(t)
                }
                Some(Err(e)) => {
                    eprintln!("warning: the path could not be timed: {e}");
                    None
                }
                None => None,
            };
            if args.json {
                let v = serde_json::json!({
                    "status": "solved",
                    "path": res.path,
                    "trajectory": trajectory.map(|t| serde_json::json!({
                        "joint_names": t.joint_names, "duration_s": t.duration,
                        "times": t.times, "positions": t.positions,
                        "velocities": t.velocities, "accelerations": t.accelerations,
                        "waypoint_times": t.waypoint_times,
                    })),
                    "total_ms": total_ms,
                    "certified": !args.no_certify,
                    "stats": {
                        "iterations": s.iterations, "tree_nodes": s.tree_nodes,
                        "config_checks": s.config_checks, "motion_checks": s.motion_checks,
                        "ik_ms": s.ik_s * 1e3, "search_ms": s.search_s * 1e3,
                        "sample_ms": s.sample_s * 1e3, "check_ms": s.check_s * 1e3,
                        "neighbour_ms": s.neighbour_s * 1e3, "validate_ms": s.validate_s * 1e3,
                        "other_ms": s.other_s() * 1e3, "simplify_ms": s.simplify_s * 1e3,
                        "length_before": s.length_before, "length_after": s.length_after,
                        "timing_ms": s.timing_s * 1e3,
                        "uncertified": s.uncertified, "refined": s.refined,
                    }
                });
                println!("{v}");
            } else {
                println!("status: solved ({} waypoints)", res.path.len());
                println!(
                    "time: {total_ms:.3} ms total = ik {:.3} + search {:.3} (sampling {:.3}, checking {:.3}, neighbours {:.3}, other {:.3}) + simplify {:.3} + exact validation {:.3}",
                    s.ik_s * 1e3, s.search_s * 1e3, s.sample_s * 1e3, s.check_s * 1e3, s.neighbour_s * 1e3, s.other_s() * 1e3, s.simplify_s * 1e3, s.validate_s * 1e3
                );
                println!(
                    "search: {} iterations, {} tree nodes, {} configuration checks, {} edge checks",
                    s.iterations, s.tree_nodes, s.config_checks, s.motion_checks
                );
                println!(
                    "length: {:.3} before simplification, {:.3} after",
                    s.length_before, s.length_after
                );
                if !args.no_certify {
                    println!(
                        "certified clear between its states ({} segments left uncertified, checked 32 times finer)",
                        s.uncertified
                    );
                }
                let names: Vec<&str> = robot.variables().iter().map(|v| v.name.as_str()).collect();
                println!("joints: {}", names.join(" "));
                for (i, q) in res.path.iter().enumerate() {
                    let vals: Vec<String> = q.iter().map(|v| format!("{v:.5}")).collect();
                    let at = trajectory.map_or(String::new(), |t| {
                        format!("  (t = {:.3} s)", t.waypoint_times[i])
                    });
                    println!("{i:4}: {}{at}", vals.join(" "));
                }
                if let Some(t) = trajectory {
                    println!(
                        "trajectory: executes in {:.3} s, {} samples every {} s (timed in {:.3} ms)",
                        t.duration,
                        t.times.len(),
                        args.sample_period,
                        s.timing_s * 1e3
                    );
                }
            }
            Ok(ExitCode::SUCCESS)
        }
        Err(e) => {
            if args.json {
                println!(
                    "{}",
                    serde_json::json!({"status": e.kind(), "message": e.to_string(), "total_ms": total_ms})
                );
            } else {
                println!("status: {} ({e})", e.kind());
            }
            Ok(ExitCode::from(1))
        }
    }
}

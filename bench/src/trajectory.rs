//! `trajectory`: time-optimal parameterisation time per path, and the durations against
//! TOPP-RA's reference implementation (PyPI `toppra`) on the same geometric paths and limits,
//! in the same run.
//!
//! Paths: random ones for Fetch and Panda (`--waypoints` each, uniform within the limits),
//! and the solution paths of our `shelf_zero` test set (`--problems ROOT`, default
//! `ember-data/problems`, generated there when missing, as `paper` does: planner paths through
//! a shelf scene, simplified). Each path
//! is timed with the built-in robot's limits, corners blended within 0.05. `toppra` gets the
//! blended path itself (sampled every 0.005 of arc length, spline-interpolated) with the same
//! limits. With `--export FILE` the paths, limits, our durations and our trajectories sampled
//! at 100 Hz are written as JSON (what `tests/python/compare_toppra.py` checks in CI).
//!
//! Ends with `RESULT trajectory set=<kind> paths=<n> waypoints=<mean> median_us=<f>
//! p95_us=<f> median_duration_s=<f> toppra_median_us=<f> duration_ratio_median=<ours/toppra>
//! duration_ratio_max=<f>` per kind.

use ember_engine::problems::Task;
use ember_engine::robot::Robot;
use ember_engine::trajectory::{time_parameterize, TimingParams, Trajectory};
use ember_sdk::stats::summary;
use rand::{Rng, SeedableRng};
use std::path::PathBuf;
use std::time::Instant;

#[derive(clap::Args)]
pub struct Args {
    /// Random paths per robot.
    #[arg(long, default_value_t = 20)]
    paths: usize,
    /// Waypoints per random path.
    #[arg(long, default_value_t = 10)]
    waypoints: usize,
    /// Folder of the problem sets; the `shelf_zero` test set's solution paths are timed too
    /// (generated there first when missing).
    #[arg(long, default_value = "ember-data/problems")]
    problems: PathBuf,
    /// Planner paths taken from that set.
    #[arg(long, default_value_t = 20)]
    planned: usize,
    /// Write paths, limits and our trajectories (100 Hz) as JSON.
    #[arg(long)]
    export: Option<PathBuf>,
    /// Skip the toppra peer.
    #[arg(long)]
    no_peer: bool,
}

struct Case {
    kind: String,
    robot: String,
    path: Vec<Vec<f64>>,
}

fn random_paths(robot: &Robot, name: &str, n: usize, waypoints: usize, seed: u64) -> Vec<Case> {
    let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(seed);
    (0..n)
        .map(|_| Case {
            kind: format!("random_{name}"),
            robot: name.into(),
            path: (0..waypoints)
                .map(|_| {
                    robot
                        .variables()
                        .iter()
                        .map(|v| rng.random_range(v.lower..v.upper))
                        .collect()
                })
                .collect(),
        })
        .collect()
}

fn planned_paths(robot: &Robot, root: &std::path::Path, n: usize) -> anyhow::Result<Vec<Case>> {
    let set = crate::paper::problem_set(robot, root, "shelf_zero", Task::Pick, true, n)?;
    Ok(set
        .problems
        .into_iter()
        .filter_map(|p| p.path)
        .map(|path| Case {
            kind: format!("planned_{}", set.name),
            robot: "fetch".into(),
            path,
        })
        .collect())
}

/// Per-joint velocity and acceleration limits the trajectory used.
fn limits(robot: &Robot, p: &TimingParams) -> (Vec<f64>, Vec<f64>) {
    robot
        .limits()
        .iter()
        .map(|l| {
            (
                l.velocity.unwrap_or(0.0) * p.velocity_scaling,
                l.acceleration.unwrap_or(p.default_acceleration) * p.acceleration_scaling,
            )
        })
        .unzip()
}

/// The blended path sampled every `step` of arc length (its ends included).
fn dense(t: &Trajectory, step: f64) -> (Vec<f64>, Vec<Vec<f64>>) {
    let path = t.path();
    let n = (path.length() / step).ceil().max(1.0) as usize;
    let dof = t.joint_names.len();
    let (mut q, mut dq, mut ddq) = (vec![0.0; dof], vec![0.0; dof], vec![0.0; dof]);
    let mut ss = Vec::with_capacity(n + 1);
    let mut qs = Vec::with_capacity(n + 1);
    for k in 0..=n {
        let s = path.length() * k as f64 / n as f64;
        path.eval(s, s, &mut q, &mut dq, &mut ddq);
        ss.push(s);
        qs.push(q.clone());
    }
    (ss, qs)
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let fetch = Robot::builtin("fetch")?;
    let panda = Robot::builtin("panda")?;
    let params = TimingParams::default();
    let mut cases = random_paths(&fetch, "fetch", args.paths, args.waypoints, 1);
    cases.extend(random_paths(&panda, "panda", args.paths, args.waypoints, 2));
    if args.planned > 0 {
        cases.extend(planned_paths(&fetch, &args.problems, args.planned)?);
    }
    // Time each path (best of five, so one preemption does not count).
    let mut timed = Vec::new();
    let mut us = Vec::new();
    for c in &cases {
        let robot = if c.robot == "fetch" { &fetch } else { &panda };
        let mut best = f64::INFINITY;
        let mut out = None;
        for _ in 0..5 {
            let t0 = Instant::now();
            let t = time_parameterize(robot, &c.path, &params)?;
            best = best.min(t0.elapsed().as_secs_f64() * 1e6);
            out = Some(t);
        }
        us.push(best);
        timed.push(out.expect("timed"));
    }
    let doc: Vec<serde_json::Value> = cases
        .iter()
        .zip(&timed)
        .map(|(c, t)| {
            let robot = if c.robot == "fetch" { &fetch } else { &panda };
            let (v, a) = limits(robot, &params);
            let (ss, qs) = dense(t, 0.005);
            let samples: Vec<f64> = (0..=((t.duration / 0.01).floor() as usize))
                .map(|k| k as f64 * 0.01)
                .collect();
            let states: Vec<_> = samples.iter().map(|&x| t.state_at(x)).collect();
            serde_json::json!({
                "kind": c.kind, "robot": c.robot, "waypoints": c.path.len(),
                "velocity": v, "acceleration": a, "duration": t.duration,
                "s": ss, "q": qs,
                "times": samples,
                "positions": states.iter().map(|s| &s.0).collect::<Vec<_>>(),
                "velocities": states.iter().map(|s| &s.1).collect::<Vec<_>>(),
                "accelerations": states.iter().map(|s| &s.2).collect::<Vec<_>>(),
            })
        })
        .collect();
    let json = serde_json::Value::Array(doc);
    let export = args
        .export
        .clone()
        .unwrap_or_else(|| std::env::temp_dir().join("ember-trajectories.json"));
    std::fs::write(&export, json.to_string())?;
    // The peer on the same paths.
    let peer: Option<serde_json::Value> = if args.no_peer {
        None
    } else {
        let python = crate::python::venv("toppra-venv", &["toppra"], "import toppra")?;
        let script =
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../tests/python/compare_toppra.py");
        let out = std::process::Command::new(python)
            .arg(&script)
            .arg(&export)
            .arg("--json")
            .output()?;
        anyhow::ensure!(
            out.status.success(),
            "toppra peer failed: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        Some(serde_json::from_slice(&out.stdout)?)
    };
    let mut kinds: Vec<&str> = cases.iter().map(|c| c.kind.as_str()).collect();
    kinds.dedup();
    println!(
        "{:<28} {:>5} {:>9} {:>10} {:>9} {:>11} {:>12} {:>10} {:>9}",
        "set",
        "paths",
        "waypoints",
        "median_us",
        "p95_us",
        "duration_s",
        "toppra_us",
        "ratio_med",
        "ratio_max"
    );
    let mut lines = Vec::new();
    for kind in kinds {
        let idx: Vec<usize> = (0..cases.len())
            .filter(|&i| cases[i].kind == kind)
            .collect();
        let mut t_us: Vec<f64> = idx.iter().map(|&i| us[i]).collect();
        let mut dur: Vec<f64> = idx.iter().map(|&i| timed[i].duration).collect();
        let waypoints =
            idx.iter().map(|&i| cases[i].path.len()).sum::<usize>() as f64 / idx.len() as f64;
        let (med, _, p95) = summary(&mut t_us);
        let (dmed, _, _) = summary(&mut dur);
        let (mut tus, mut ratios) = (Vec::new(), Vec::new());
        if let Some(p) = &peer {
            for &i in &idx {
                let r = &p["paths"][i];
                tus.push(r["toppra_us"].as_f64().unwrap_or(f64::NAN));
                ratios.push(timed[i].duration / r["toppra_duration"].as_f64().unwrap_or(f64::NAN));
            }
        }
        let (tmed, _, _) = summary(&mut tus);
        let (rmed, _, _) = summary(&mut ratios);
        let rmax = ratios.iter().copied().fold(f64::NAN, f64::max);
        println!(
            "{kind:<28} {:>5} {waypoints:>9.1} {med:>10.1} {p95:>9.1} {dmed:>11.3} {tmed:>12.1} {rmed:>10.4} {rmax:>9.4}",
            idx.len()
        );
        lines.push(format!(
            "RESULT trajectory set={kind} paths={} waypoints={waypoints:.1} median_us={med:.1} \
             p95_us={p95:.1} median_duration_s={dmed:.3} toppra_median_us={tmed:.1} \
             duration_ratio_median={rmed:.4} duration_ratio_max={rmax:.4}",
            idx.len()
        ));
    }
    if let Some(p) = &peer {
        println!("toppra {}", p["toppra_version"]);
    }
    for l in lines {
        println!("{l}");
    }
    Ok(())
}

//! `paths --problems DIR... --paths FILE...`: returned paths (any planner's) checked on Ember's exact
//! geometry at a fine step: how many touch the scene or the robot itself.
//!
//! FILE holds one JSON object a line, `{"set", "index", "joints", "path"}` and optionally
//! `"continuous"`, as `plan --paths-out` and `bench/vamp_paths_peer.py --dump` write them;
//! `joints` names the robot's group joints in the path's order. Each edge is checked as the
//! planner moved along it (straight, the `continuous` joints the short way round, whichever
//! the checking robot's joints are), states at most `--step` apart (configuration-space
//! distance, default 0.01), ends included, on the exact geometry (the meshes' convex parts,
//! the SRDF's self pairs), with the joints outside the group at the request's start values.
//! Prints `TOUCH file= set= index= at=start|goal|between edge=<k> t=<f> contact=<what>` for
//! each path that touches something (its first contact), then per file and set
//! `RESULT paths file= set= paths= touching= between= skipped=` (`between`: start and goal
//! free, a state between them not; `skipped`: problems the folders do not hold). The same
//! count on FCL, the meshes' own triangles, is `bench/path_truth.py`'s.

use ember_engine::collision::exact::ExactChecker;
use ember_engine::problems::{Problem, ProblemSet};
use ember_engine::robot::RobotArgs;
use std::collections::{BTreeMap, HashMap};
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    /// Problem folders (sceneNNNN.yaml + requestNNNN.yaml each), named as the paths' sets.
    #[arg(long, num_args = 1.., required = true)]
    problems: Vec<PathBuf>,
    /// The robot whose exact geometry checks the paths.
    #[command(flatten)]
    robot: RobotArgs,
    /// Largest configuration-space distance between checked states.
    #[arg(long, default_value_t = 0.01)]
    step: f64,
    /// Path files (JSON lines).
    #[arg(long, num_args = 1.., required = true)]
    paths: Vec<PathBuf>,
}

#[derive(serde::Deserialize)]
struct Record {
    set: String,
    index: usize,
    joints: Vec<String>,
    /// Joints whose edges went the short way round in the planner's model (none: straight).
    #[serde(default)]
    continuous: Vec<String>,
    path: Vec<Vec<f64>>,
}

/// The first state along the edge `a` → `b` in contact, at most `step` apart, ends included,
/// moving as the planner did (`wraps`: the joints that went the short way round), whatever
/// the checking robot's joints are: `(t, contact)`.
fn edge_contact(
    exact: &mut ExactChecker,
    (a, b): (&[f64], &[f64]),
    wraps: &[bool],
    step: f64,
) -> Option<(f64, ember_engine::collision::checker::Contact)> {
    use std::f64::consts::{PI, TAU};
    let d: Vec<f64> = a
        .iter()
        .zip(b)
        .zip(wraps)
        .map(|((x, y), &w)| match w {
            true => (y - x + PI).rem_euclid(TAU) - PI,
            false => y - x,
        })
        .collect();
    let n = (d.iter().map(|v| v * v).sum::<f64>().sqrt() / step)
        .ceil()
        .max(1.0) as usize;
    let mut q = a.to_vec();
    (0..=n).find_map(|i| {
        let t = i as f64 / n as f64;
        for (k, v) in q.iter_mut().enumerate() {
            *v = a[k] + d[k] * t;
        }
        exact.contact(&q).map(|c| (t, c))
    })
}

/// Per set: paths, touching, touching between free ends, skipped.
type Counts = BTreeMap<String, [usize; 4]>;

pub fn run(args: Args) -> anyhow::Result<()> {
    anyhow::ensure!(args.step > 0.0, "--step must be positive");
    let robot = args.robot.spec("fetch").load()?;
    let sets: Vec<ProblemSet> = args
        .problems
        .iter()
        .map(|d| ProblemSet::load(d, &robot))
        .collect::<Result<_, _>>()?;
    let problems: HashMap<(&str, usize), &Problem> = sets
        .iter()
        .flat_map(|s| s.problems.iter().map(move |p| ((&s.name[..], p.index), p)))
        .collect();
    let names: Vec<&str> = robot.variables().iter().map(|v| &v.name[..]).collect();
    let mut results = Vec::new();
    for file in &args.paths {
        let label = file.file_name().unwrap_or_default().to_string_lossy();
        let text = std::fs::read_to_string(file)
            .map_err(|e| anyhow::anyhow!("cannot read {}: {e}", file.display()))?;
        let mut counts = Counts::new();
        for (n, line) in text.lines().enumerate() {
            let rec: Record = serde_json::from_str(line)
                .map_err(|e| anyhow::anyhow!("{} line {}: {e}", file.display(), n + 1))?;
            let c = counts.entry(rec.set.clone()).or_default();
            let Some(p) = problems.get(&(&rec.set[..], rec.index)) else {
                c[3] += 1;
                continue;
            };
            // The path's columns in the robot's variable order.
            let order: Vec<usize> = names
                .iter()
                .map(|n| rec.joints.iter().position(|j| j == n))
                .collect::<Option<_>>()
                .ok_or_else(|| {
                    anyhow::anyhow!(
                        "{} line {}: joints {:?} are not the group's {names:?}",
                        file.display(),
                        n + 1,
                        rec.joints
                    )
                })?;
            let path: Vec<Vec<f64>> = rec
                .path
                .iter()
                .map(|w| order.iter().map(|&k| w[k]).collect())
                .collect();
            let wraps: Vec<bool> = names
                .iter()
                .map(|n| rec.continuous.iter().any(|c| c == n))
                .collect();
            let r = p.scene.robot_with(&robot, &p.request.start_joints)?;
            let env = p.scene.environment()?;
            let mut exact = ExactChecker::new(&r, &env);
            c[0] += 1;
            let hit = path.windows(2).enumerate().find_map(|(k, w)| {
                edge_contact(&mut exact, (&w[0], &w[1]), &wraps, args.step)
                    .map(|(t, what)| (k, t, what))
            });
            let Some((edge, t, what)) = hit else {
                continue;
            };
            let at = if exact.contact(&path[0]).is_some() {
                "start"
            } else if exact.contact(&path[path.len() - 1]).is_some() {
                "goal"
            } else {
                "between"
            };
            c[1] += 1;
            c[2] += (at == "between") as usize;
            println!(
                "TOUCH file={label} set={} index={} at={at} edge={edge} t={t:.3} contact={what}",
                rec.set, rec.index
            );
        }
        for (set, [paths, touching, between, skipped]) in counts {
            results.push(format!(
                "RESULT paths file={label} set={set} paths={paths} touching={touching} \
                 between={between} skipped={skipped}"
            ));
        }
    }
    for line in results {
        println!("{line}");
    }
    Ok(())
}

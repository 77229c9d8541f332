//! `plan --problems DIR...`: the uniform planner over MoveIt-style problem folders.
//!
//! Flags: `--robot` (default: the folder's `config.yaml`, else fetch), `--time-limit S` per
//! problem (default 10), `--seed N`, `--no-simplify`, `--range R`. For each folder prints success and
//! planning-time statistics (planning = IK + search; simplification reported apart) and ends
//! with `RESULT plan set=<folder> n=<problems> solved=<count> median_ms=<f> mean_ms=<f>
//! p95_ms=<f>`; a failure counts as the time limit in the mean, as in the paper.

use crate::stats::summary;
use ember_engine::planning::{self, PlanRequest, PlannerParams, UniformSampler};
use ember_engine::problems::ProblemSet;
use ember_engine::robot::Robot;
use std::path::PathBuf;
use std::time::{Duration, Instant};

#[derive(clap::Args)]
pub struct Args {
    /// Problem folders (sceneNNNN.yaml + requestNNNN.yaml each).
    #[arg(long, num_args = 1.., required = true)]
    problems: Vec<PathBuf>,
    /// Robot (built-in name or robot file); default from the folder's config.yaml, else fetch.
    #[arg(long)]
    robot: Option<String>,
    /// Time limit per problem, seconds.
    #[arg(long, default_value_t = 10.0)]
    time_limit: f64,
    /// Planner seed (each problem uses seed + index).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Skip path simplification.
    #[arg(long)]
    no_simplify: bool,
    /// RRT-Connect range (longest extension); default: the planner's.
    #[arg(long)]
    range: Option<f64>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let mut results = Vec::new();
    println!(
        "{:<22} {:>5} {:>6} {:>10} {:>10} {:>10} {:>12}",
        "set", "n", "solved", "median_ms", "mean_ms", "p95_ms", "simplify_ms"
    );
    for dir in &args.problems {
        let robot_name = args
            .robot
            .clone()
            .or_else(|| ProblemSet::robot_of(dir))
            .unwrap_or_else(|| "fetch".into());
        let robot = Robot::from_spec(&robot_name)?;
        let set = ProblemSet::load(dir, &robot)?;
        let mut times = Vec::new();
        let mut simplify = Vec::new();
        let mut solved = 0;
        for p in &set.problems {
            let env = p.scene.environment()?;
            let req = PlanRequest {
                start: p.request.start.clone(),
                goal: p.request.goal.clone(),
                params: PlannerParams {
                    seed: args.seed + p.index as u64,
                    time_limit: Duration::from_secs_f64(args.time_limit),
                    simplify: !args.no_simplify,
                    range: args.range.unwrap_or(PlannerParams::default().range),
                    ..Default::default()
                },
            };
            let t = Instant::now();
            match planning::plan(&robot, &env, &req, &mut UniformSampler) {
                Ok(res) => {
                    let total = t.elapsed().as_secs_f64();
                    solved += 1;
                    times.push((total - res.stats.simplify_s) * 1e3);
                    simplify.push(res.stats.simplify_s * 1e3);
                }
                Err(_) => times.push(args.time_limit * 1e3),
            }
        }
        let n = set.problems.len();
        let (median, mean, p95) = summary(&mut times);
        let (simp, _, _) = summary(&mut simplify);
        println!(
            "{:<22} {:>5} {:>6} {:>10.3} {:>10.3} {:>10.3} {:>12.3}",
            set.name, n, solved, median, mean, p95, simp
        );
        results.push((set.name, n, solved, median, mean, p95));
    }
    for (name, n, solved, median, mean, p95) in results {
        println!("RESULT plan set={name} n={n} solved={solved} median_ms={median:.3} mean_ms={mean:.3} p95_ms={p95:.3}");
    }
    Ok(())
}

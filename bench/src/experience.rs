//! `experience --train DIR --test DIR...`: the paper's experiment. Learns SPARK and FLAME
//! databases from the training set's solved paths, then plans every test problem with uniform
//! sampling, SPARK and FLAME, and compares.
//!
//! Flags: `--train-count N` (use the first N training problems; default all), `--time-limit S`
//! per plan (default 10; a failure counts as the limit in the mean, as in the paper),
//! `--interpolate STEP` (also test path states every STEP for criticality), `--seed N`,
//! `--db DIR` (save the databases there), `--sigma`, `--lambda`, `--d-radius` (override the
//! paper's hyperparameters), `--range R` (RRT-Connect range). Planning time includes retrieval (primitive
//! extraction for SPARK, database lookups for both); the FLAME map itself is rendered from the
//! test scene beforehand, as the daemon keeps it up to date incrementally. Ends with one line per
//! test set and method: `RESULT experience set=<folder> method=<uniform|spark|flame> n=<n>
//! solved=<k> mean_ms=<f> median_ms=<f> retrieval_us=<f>`.

use crate::learning::{plan_sets, prepare, train_one, EvalOptions, Method};
use ember_engine::experience::{Database, Experience, ExperienceParams};
use ember_engine::planning::PlannerParams;
use ember_engine::problems::ProblemSet;
use ember_engine::robot::Robot;
use ember_engine::world::map::MapParams;
use std::path::PathBuf;
use std::time::Instant;

#[derive(clap::Args)]
pub struct Args {
    /// Training problem folder (with pathNNNN.yaml solutions).
    #[arg(long)]
    train: PathBuf,
    /// Test problem folders.
    #[arg(long, num_args = 1.., required = true)]
    test: Vec<PathBuf>,
    /// Use only the first N training problems.
    #[arg(long)]
    train_count: Option<usize>,
    /// Time limit per plan, seconds.
    #[arg(long, default_value_t = 10.0)]
    time_limit: f64,
    /// Also test path states every STEP (configuration distance) for criticality.
    #[arg(long)]
    interpolate: Option<f64>,
    /// Planner seed (each problem uses seed + index).
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Save the learned databases in this folder.
    #[arg(long)]
    db: Option<PathBuf>,
    /// Override σ (default 0.2, the paper's).
    #[arg(long)]
    sigma: Option<f64>,
    /// Override λ (default 0.5).
    #[arg(long)]
    lambda: Option<f64>,
    /// Override SPARK's retrieval radius (default 0.4).
    #[arg(long)]
    d_radius: Option<f64>,
    /// RRT-Connect range (default: the planner's).
    #[arg(long)]
    range: Option<f64>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let robot_name = ProblemSet::robot_of(&args.train).unwrap_or_else(|| "fetch".into());
    let robot = Robot::from_spec(&robot_name)?;
    let train = ProblemSet::load(&args.train, &robot)?;
    let defaults = ExperienceParams::default();
    let params = ExperienceParams {
        sigma: args.sigma.unwrap_or(defaults.sigma),
        lambda: args.lambda.unwrap_or(defaults.lambda),
        d_radius: args.d_radius.unwrap_or(defaults.d_radius),
        ..defaults
    };
    let mut experience = Experience::new(params.clone(), MapParams::default().resolution);
    let count = args
        .train_count
        .unwrap_or(train.problems.len())
        .min(train.problems.len());
    let t = Instant::now();
    for (i, p) in train.problems.iter().take(count).enumerate() {
        train_one(&robot, p, args.interpolate, &mut experience)?;
        if (i + 1) % 50 == 0 || i + 1 == count {
            eprint!(
                "\rtraining: {}/{count} problems ({:.0} s)",
                i + 1,
                t.elapsed().as_secs_f64()
            );
        }
    }
    eprintln!();
    println!(
        "trained on {count} problems of {} in {:.1} s: SPARK {} entries / {} configurations, FLAME {} entries / {} configurations",
        train.name,
        t.elapsed().as_secs_f64(),
        experience.spark.len(),
        experience.spark.configurations(),
        experience.flame.len(),
        experience.flame.configurations()
    );
    if let Some(dir) = &args.db {
        experience.save_dir(dir)?;
        println!("databases saved in {}", dir.display());
    }

    let mut results = Vec::new();
    println!(
        "{:<22} {:<8} {:>5} {:>6} {:>10} {:>10} {:>13} {:>9} {:>9}",
        "set",
        "method",
        "n",
        "solved",
        "mean_ms",
        "median_ms",
        "retrieval_us",
        "entries",
        "samplers"
    );
    let options = EvalOptions {
        time_limit: args.time_limit,
        seed: args.seed,
        range: args.range.unwrap_or(PlannerParams::default().range),
    };
    for dir in &args.test {
        let set = ProblemSet::load(dir, &robot)?;
        let cases = prepare(&robot, &set.problems)?;
        let runs = Method::ALL.map(|m| (m, &experience));
        let outcomes = plan_sets(&cases, &runs, &options);
        for (method, o) in Method::ALL.into_iter().zip(outcomes) {
            println!(
                "{:<22} {:<8} {:>5} {:>6} {:>10.3} {:>10.3} {:>13.1} {:>9.1} {:>9.1}",
                set.name,
                method.name(),
                o.n,
                o.solved,
                o.mean_ms,
                o.median_ms,
                o.retrieval_us,
                o.entries,
                o.samplers
            );
            results.push(format!(
                "RESULT experience set={} method={} n={} {}",
                set.name,
                method.name(),
                o.n,
                o.result_keys()
            ));
        }
    }
    for r in results {
        println!("{r}");
    }
    Ok(())
}

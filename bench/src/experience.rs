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

use crate::stats::summary;
use ember_engine::experience::database::Retrieval;
use ember_engine::experience::primitive::{octoboxes, spark_pairs};
use ember_engine::experience::train::learn;
use ember_engine::experience::{ExperienceParams, FlameDb, GlobalSampler, SparkDb};
use ember_engine::planning::{self, PlanRequest, PlannerParams, Sampler, UniformSampler};
use ember_engine::problems::ProblemSet;
use ember_engine::robot::Robot;
use ember_engine::scene::Scene;
use ember_engine::world::map::{MapParams, OccupancyMap};
use ember_sensors::{quarter_vga, sensed_map};
use std::path::PathBuf;
use std::time::{Duration, Instant};

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

/// Where the sensed views look: the centre of the scene's objects other than the floor.
fn look_target(scene: &Scene) -> [f64; 3] {
    let pts: Vec<_> = scene
        .objects
        .iter()
        .filter(|o| o.name != "floor")
        .map(|o| o.pose.translation.vector)
        .collect();
    let n = pts.len().max(1) as f64;
    let c = pts.iter().fold(nalgebra::Vector3::zeros(), |a, p| a + p) / n;
    [c.x, c.y, c.z]
}

fn map_of(scene: &Scene) -> anyhow::Result<OccupancyMap> {
    Ok(sensed_map(
        &scene.environment()?,
        look_target(scene),
        &quarter_vga(),
        MapParams::default(),
    ))
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
    let mut spark = SparkDb::new(params.clone());
    let mut flame = FlameDb::new(params.clone(), MapParams::default().resolution);
    let count = args
        .train_count
        .unwrap_or(train.problems.len())
        .min(train.problems.len());
    let t = Instant::now();
    for (i, p) in train.problems.iter().take(count).enumerate() {
        let Some(path) = &p.path else { continue };
        let map = map_of(&p.scene)?;
        learn(
            &robot,
            &p.scene,
            Some(&map),
            path,
            args.interpolate,
            &mut spark,
            Some(&mut flame),
        );
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
        spark.len(),
        spark.configurations(),
        flame.len(),
        flame.configurations()
    );
    if let Some(dir) = &args.db {
        spark.save(dir.join("spark.emberdb"))?;
        flame.save(dir.join("flame.emberdb"))?;
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
    for dir in &args.test {
        let set = ProblemSet::load(dir, &robot)?;
        for method in ["uniform", "spark", "flame"] {
            let mut times = Vec::new();
            let mut retrieval = Vec::new();
            let mut entries = Vec::new();
            let mut samplers = Vec::new();
            let mut solved = 0;
            for p in &set.problems {
                let env = p.scene.environment()?;
                let map = if method == "flame" {
                    Some(map_of(&p.scene)?)
                } else {
                    None
                };
                let t = Instant::now();
                let r: Retrieval = match method {
                    "spark" => spark.retrieve(&spark_pairs(&p.scene, &params)),
                    "flame" => flame.retrieve(&octoboxes(map.as_ref().expect("rendered"))),
                    _ => Retrieval::default(),
                };
                let (entries_r, samplers_r) = (r.entries, r.samplers.len());
                let mut sampler: Box<dyn Sampler> = if method == "uniform" {
                    Box::new(UniformSampler)
                } else {
                    Box::new(GlobalSampler::new(r, params.sigma, params.lambda))
                };
                let retrieval_s = t.elapsed().as_secs_f64();
                let req = PlanRequest {
                    start: p.request.start.clone(),
                    goal: p.request.goal.clone(),
                    params: PlannerParams {
                        seed: args.seed + p.index as u64,
                        time_limit: Duration::from_secs_f64(args.time_limit),
                        simplify: false,
                        range: args.range.unwrap_or(PlannerParams::default().range),
                        ..Default::default()
                    },
                };
                match planning::plan(&robot, &env, &req, sampler.as_mut()) {
                    Ok(_) => {
                        solved += 1;
                        times.push(t.elapsed().as_secs_f64() * 1e3);
                    }
                    Err(_) => times.push(args.time_limit * 1e3 + retrieval_s * 1e3),
                }
                retrieval.push(retrieval_s * 1e6);
                entries.push(entries_r as f64);
                samplers.push(samplers_r as f64);
            }
            let n = set.problems.len();
            let (median, mean, _) = summary(&mut times);
            let (_, ret_mean, _) = summary(&mut retrieval);
            let (_, ent, _) = summary(&mut entries);
            let (_, smp, _) = summary(&mut samplers);
            println!(
                "{:<22} {:<8} {:>5} {:>6} {:>10.3} {:>10.3} {:>13.1} {:>9.1} {:>9.1}",
                set.name, method, n, solved, mean, median, ret_mean, ent, smp
            );
            results.push(format!(
                "RESULT experience set={} method={method} n={n} solved={solved} mean_ms={mean:.3} median_ms={median:.3} retrieval_us={ret_mean:.1}",
                set.name
            ));
        }
    }
    for r in results {
        println!("{r}");
    }
    Ok(())
}

//! `ember demo`: pick episodes in varied shelf scenes, planned in process.

use crate::cli::DemoArgs;
use ember_engine::planning::{self, Goal, PlanRequest, PlannerParams, PlannerRng, UniformSampler};
use ember_engine::problems;
use indicatif::ProgressBar;
use rand::{Rng, SeedableRng};
use std::process::ExitCode;
use std::time::Instant;

pub fn run(args: DemoArgs) -> anyhow::Result<ExitCode> {
    let robot = super::load_robot(&args.robot)?;
    let spec = problems::dataset("shelf_height_rot").expect("built-in dataset");
    let start = robot
        .named_state(spec.start_state)
        .or_else(|| {
            robot
                .named_state_names()
                .next()
                .and_then(|n| robot.named_state(n))
        })
        .ok_or_else(|| anyhow::anyhow!("robot '{}' has no named start state", robot.name()))?
        .to_vec();
    let mut rng = PlannerRng::seed_from_u64(args.seed);
    let bar = ProgressBar::new(args.episodes as u64);
    let mut latencies = Vec::new();
    let mut episodes = 0;
    let mut draws = 0;
    while episodes < args.episodes {
        draws += 1;
        anyhow::ensure!(
            draws <= 50 * args.episodes.max(1),
            "robot '{}' reached the target in none of {} shelf scenes drawn: it cannot do this task",
            robot.name(),
            draws - 1
        );
        let scene = problems::sample_scene(&spec, &mut rng);
        let env = scene.environment()?;
        let Some(goal) = problems::sample_goal(&robot, &spec, &scene, &env, &mut rng) else {
            continue; // An unreachable variation: draw another scene.
        };
        episodes += 1;
        let req = PlanRequest {
            start: start.clone(),
            goal: Goal::Joints(vec![goal]),
            params: PlannerParams {
                seed: rng.random(),
                ..Default::default()
            },
        };
        let t = Instant::now();
        if planning::plan(&robot, &env, &req, &mut UniformSampler).is_ok() {
            latencies.push(t.elapsed().as_secs_f64() * 1e3);
        }
        bar.inc(1);
    }
    bar.finish_and_clear();
    let solved = latencies.len();
    latencies.sort_by(f64::total_cmp);
    let median = latencies.get(solved / 2).copied().unwrap_or(f64::NAN);
    let mean = latencies.iter().sum::<f64>() / solved.max(1) as f64;
    println!("method   episodes  solved  median_ms  mean_ms");
    println!("uniform  {episodes:8}  {solved:6}  {median:9.2}  {mean:7.2}");
    println!("RESULT demo method=uniform episodes={episodes} solved={solved} median_ms={median:.3} mean_ms={mean:.3} retrieval_us=0");
    Ok(ExitCode::SUCCESS)
}

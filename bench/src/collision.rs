//! `collision`: forward kinematics and full configuration checks (self + environment) for
//! Fetch in the nominal small-shelf scene (10 objects), over random configurations.
//!
//! Flags: `--configs N` configurations per batch (default 1000), `--batches N` (default 200).
//! Prints per-call medians over batches; ends with
//! `RESULT collision fk_ns=<median> check_ns=<median>`.

use crate::stats::summary;
use ember_engine::collision::SphereChecker;
use ember_engine::planning::PlannerRng;
use ember_engine::problems;
use ember_engine::robot::Robot;
use ember_engine::Pose;
use rand::SeedableRng;
use std::hint::black_box;
use std::time::Instant;

#[derive(clap::Args)]
pub struct Args {
    /// Configurations per timed batch.
    #[arg(long, default_value_t = 1000)]
    configs: usize,
    /// Timed batches (the median batch is reported).
    #[arg(long, default_value_t = 200)]
    batches: usize,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let robot = Robot::builtin("fetch")?;
    let spec = problems::dataset("shelf_zero").expect("built in");
    let scene = problems::sample_scene(
        &problems::DatasetSpec {
            world: problems::Variation {
                position: [0.0; 3],
                yaw: 0.0,
            },
            object_variations: vec![],
            ..spec
        },
        &mut PlannerRng::seed_from_u64(0),
    );
    let env = scene.environment()?;
    let mut rng = PlannerRng::seed_from_u64(1);
    let configs: Vec<Vec<f64>> = (0..args.configs)
        .map(|_| {
            let mut q = vec![0.0; robot.dof()];
            robot.sample_uniform(&mut rng, &mut q);
            q
        })
        .collect();

    let mut poses = vec![Pose::identity(); robot.links().len()];
    let mut fk = Vec::with_capacity(args.batches);
    for _ in 0..args.batches {
        let t = Instant::now();
        for q in &configs {
            robot.forward_kinematics(black_box(q), &mut poses);
            black_box(&poses);
        }
        fk.push(t.elapsed().as_secs_f64() * 1e9 / configs.len() as f64);
    }

    let mut checker = SphereChecker::new(&robot, &env);
    let valid = configs.iter().filter(|q| checker.is_valid(q)).count();
    let mut check = Vec::with_capacity(args.batches);
    for _ in 0..args.batches {
        let t = Instant::now();
        for q in &configs {
            black_box(checker.is_valid(black_box(q)));
        }
        check.push(t.elapsed().as_secs_f64() * 1e9 / configs.len() as f64);
    }
    let (fk_med, fk_mean, fk_p95) = summary(&mut fk);
    let (ck_med, ck_mean, ck_p95) = summary(&mut check);
    println!(
        "Fetch, {} objects, {} spheres, {} self-collision pairs; {} random configurations ({:.0}% valid)",
        env.objects().len(),
        robot.spheres().len(),
        robot.self_collision_pairs().len(),
        configs.len(),
        100.0 * valid as f64 / configs.len() as f64
    );
    println!(
        "{:<28} {:>10} {:>10} {:>10}",
        "per call (ns)", "median", "mean", "p95"
    );
    println!(
        "{:<28} {:>10.1} {:>10.1} {:>10.1}",
        "forward kinematics", fk_med, fk_mean, fk_p95
    );
    println!(
        "{:<28} {:>10.1} {:>10.1} {:>10.1}",
        "full check (self + env)", ck_med, ck_mean, ck_p95
    );
    println!("RESULT collision fk_ns={fk_med:.1} check_ns={ck_med:.1}");
    Ok(())
}

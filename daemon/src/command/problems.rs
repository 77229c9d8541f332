//! `ember problems`: generate problem sets as MoveIt-style YAML folders.

use crate::cli::ProblemsArgs;
use ember_engine::problems::{self, GenerateOptions};
use indicatif::{ProgressBar, ProgressStyle};
use std::process::ExitCode;

pub fn run(args: ProblemsArgs) -> anyhow::Result<ExitCode> {
    let robot = super::load_robot(&args.robot.spec("fetch"))?;
    let names = if args.dataset.is_empty() {
        vec![
            "shelf_zero".to_string(),
            "shelf_height".into(),
            "shelf_height_rot".into(),
        ]
    } else {
        args.dataset.clone()
    };
    for name in &names {
        let spec = problems::dataset(name)
            .ok_or_else(|| problems::ProblemError::UnknownDataset(name.clone()))?;
        let task = if args.place {
            problems::Task::Place
        } else {
            problems::Task::Pick
        };
        for (test, count) in [(false, args.train), (true, args.test)] {
            if count == 0 {
                continue;
            }
            let (set, seed) = (task.set_name(name, test), task.set_seed(args.seed, test));
            let dir = args.out.join(&set);
            let bar = ProgressBar::new(count as u64).with_style(
                ProgressStyle::with_template(
                    "{msg:24} [{bar:30}] {pos}/{len} ({elapsed}, eta {eta})",
                )
                .expect("valid template"),
            );
            bar.set_message(set.clone());
            let options = GenerateOptions {
                count,
                seed,
                task,
                ..Default::default()
            };
            let report = problems::generate(&robot, &spec, &options, &dir, &mut |done, _| {
                bar.set_position(done as u64)
            })?;
            bar.finish();
            println!(
                "{}: {} problems from {} candidates ({} without IK solution, {} unsolved) in {}",
                dir.display(),
                report.written,
                report.attempts,
                report.no_ik,
                report.unsolved,
                dir.display()
            );
        }
    }
    Ok(ExitCode::SUCCESS)
}

//! `ember train FILE... --db DIR`: extends the experience databases from recorded sessions.
//! The world is rebuilt in process from the recording (objects, joint states, clouds into the
//! map), and every solved plan is learned from in the world it was planned in: SPARK from the
//! objects, FLAME from the map.

use crate::cli::TrainArgs;
use crate::config::Config;
use crate::service::objects::change_of;
use ember_engine::experience::{Database, Experience, ExperienceParams};
use ember_engine::scene::pose_from_xyz_xyzw;
use ember_engine::world::model::World;
use ember_sdk::session::{Event, Session, TopicMap};
use indicatif::{ProgressBar, ProgressStyle};
use std::process::ExitCode;

pub fn run(args: TrainArgs) -> anyhow::Result<ExitCode> {
    let config = Config::load(args.config.as_deref())?;
    let robot = super::load_robot(&config.robot_spec())?;
    let (mut experience, set_aside) = Experience::load_dir(
        &args.db,
        &ExperienceParams::default(),
        config.map.resolution,
    )?;
    for s in set_aside {
        eprintln!("warning: {s}");
    }
    let (spark0, flame0) = (experience.spark.len(), experience.flame.len());
    let topics = TopicMap::parse(&args.topic_map)?;
    let mut plans = 0usize;
    for file in &args.files {
        let session = Session::open(file)?;
        let bar = ProgressBar::new(session.message_count().unwrap_or(0)).with_style(
            ProgressStyle::with_template("{msg} [{bar:30}] {pos}/{len} events")
                .expect("valid template"),
        );
        bar.set_message(file.display().to_string());
        let mut world = World::new(&config.world_params());
        let mut requests = std::collections::HashMap::new();
        let read = session.for_each(
            args.allow_truncated,
            &topics,
            |_, event| -> anyhow::Result<()> {
                bar.inc(1);
                match event {
                    Event::Object(u) => {
                        // What the daemon refused, it refused too: the world is unchanged.
                        if let Ok(change) = change_of(&u) {
                            let _ = world.apply(&robot, change);
                        }
                    }
                    Event::Joints {
                        names, positions, ..
                    } => {
                        if let Some(q) = super::group_order(&robot, &names, &positions)
                            .filter(|q| robot.validate(q).is_ok())
                        {
                            world.set_joints(&robot, q);
                        }
                    }
                    Event::Cloud {
                        pose: p, points, ..
                    } => {
                        if let Some(sensor) =
                            pose_from_xyz_xyzw([p[0], p[1], p[2]], [p[3], p[4], p[5], p[6]])
                        {
                            world.insert_cloud(&robot, &points, &sensor);
                        }
                    }
                    // The world a plan was planned in is the one at its request (inputs may be
                    // recorded between a request and its response).
                    Event::PlanRequest(r) => {
                        requests.insert(r.header.stamp.ns(), world.snapshot());
                    }
                    Event::PlanResponse(r) => {
                        let dof = r.dof as usize;
                        let at_request = requests.remove(&r.header.stamp.ns());
                        if r.status == 0 && dof == robot.dof() && !r.path.is_empty() {
                            let path: Vec<Vec<f64>> =
                                r.path.chunks_exact(dof).map(<[f64]>::to_vec).collect();
                            let snap = at_request.unwrap_or_else(|| world.snapshot());
                            experience.learn(
                                snap.robot(&robot),
                                &snap.scene,
                                Some((&snap.map, &snap.octoboxes)),
                                &path,
                                args.interpolate,
                            );
                            plans += 1;
                        }
                    }
                    Event::PlanTrajectory(_) => {}
                }
                Ok(())
            },
        )?;
        bar.finish_and_clear();
        if session.message_count().is_some_and(|n| (read as u64) < n) {
            eprintln!(
                "{}: damaged after {read} messages; learned from what came before",
                file.display()
            );
        }
    }
    experience.save_dir(&args.db)?;
    for file in Experience::files(&args.db) {
        config.apply_file_mode(&file)?;
    }
    let (spark, flame) = (&experience.spark, &experience.flame);
    println!(
        "learned from {plans} solved plans: SPARK {} entries (+{}), FLAME {} entries (+{}); saved in {}",
        spark.len(),
        spark.len() - spark0,
        flame.len(),
        flame.len() - flame0,
        args.db.display()
    );
    Ok(ExitCode::SUCCESS)
}

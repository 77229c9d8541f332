//! `ember train FILE... --db DIR`: extends the experience databases from recorded sessions.
//! The world is rebuilt in process from the recording (objects, joint states, clouds into the
//! map), and every solved plan is learned from in the world it was planned in: SPARK from the
//! objects, FLAME from the map.

use crate::cli::TrainArgs;
use crate::config::Config;
use crate::service::ingest::object_of;
use crate::world::World;
use ember_engine::experience::train::learn;
use ember_engine::experience::{ExperienceParams, FlameDb, SparkDb};
use ember_engine::scene::pose_from_xyz_xyzw;
use ember_sdk::recording::{self, PlanResponse, PointCloud2, PoseStamped};
use ember_sdk::wire::{self, ObjectUpdate, PROTOCOL_VERSION};
use indicatif::{ProgressBar, ProgressStyle};
use std::process::ExitCode;

pub fn run(args: TrainArgs) -> anyhow::Result<ExitCode> {
    let config = Config::load(args.config.as_deref())?;
    let robot = super::load_robot(&config.robot)?;
    let spark_path = args.db.join("spark.emberdb");
    let flame_path = args.db.join("flame.emberdb");
    let mut spark = if spark_path.exists() {
        SparkDb::load(&spark_path)?
    } else {
        SparkDb::new(ExperienceParams::default())
    };
    let mut flame = if flame_path.exists() {
        FlameDb::load(&flame_path)?
    } else {
        FlameDb::new(ExperienceParams::default(), config.map.resolution)
    };
    let (spark0, flame0) = (spark.len(), flame.len());
    let mut plans = 0usize;
    for file in &args.files {
        let bytes = std::fs::read(file)
            .map_err(|e| anyhow::anyhow!("cannot read {}: {e}", file.display()))?;
        if !bytes.starts_with(mcap::MAGIC) {
            anyhow::bail!(
                "{}: not a readable MCAP file (no MCAP magic at the start)",
                file.display()
            );
        }
        let total = mcap::Summary::read(&bytes)
            .ok()
            .flatten()
            .and_then(|s| s.stats)
            .map_or(0, |s| s.message_count);
        let bar = ProgressBar::new(total).with_style(
            ProgressStyle::with_template("{msg} [{bar:30}] {pos}/{len} messages")
                .expect("valid template"),
        );
        bar.set_message(file.display().to_string());
        let mut world = World::new(&config);
        let mut pending_cloud: Option<PointCloud2> = None;
        for message in mcap::MessageStream::new(&bytes)? {
            let m = match message {
                Ok(m) => m,
                Err(e) => {
                    bar.println(format!(
                        "{}: stopping at damaged data ({e})",
                        file.display()
                    ));
                    break;
                }
            };
            bar.inc(1);
            let bad = |e: String| {
                anyhow::anyhow!(
                    "{}: {} message {}: {e}",
                    file.display(),
                    m.channel.topic,
                    m.sequence
                )
            };
            match m.channel.topic.as_str() {
                "/ember/objects" => {
                    let o: recording::ObjectUpdate = recording::decode(&m.data).map_err(bad)?;
                    let u = ObjectUpdate {
                        version: PROTOCOL_VERSION,
                        shape: o.shape,
                        stamp_ns: 0,
                        id: wire::name(&o.id),
                        dims: o.dims,
                        pose: o.pose.to_wire(),
                    };
                    match object_of(&u) {
                        Ok(Some(obj)) => world.upsert_object(obj),
                        Ok(None) => {
                            world.remove_object(&o.id);
                        }
                        Err(_) => {} // The daemon rejected it too.
                    }
                }
                "/ember/joints" => {
                    let js: recording::JointState = recording::decode(&m.data).map_err(bad)?;
                    if robot.validate(&js.position).is_ok() {
                        world.set_joints(js.position);
                    }
                }
                "/ember/cloud" => pending_cloud = Some(recording::decode(&m.data).map_err(bad)?),
                "/ember/cloud_pose" => {
                    let pose: PoseStamped = recording::decode(&m.data).map_err(bad)?;
                    if let Some(cloud) = pending_cloud
                        .take()
                        .filter(|c| c.header.stamp == pose.header.stamp)
                    {
                        let p = pose.pose.to_wire();
                        if let (Some(points), Some(sensor)) = (
                            cloud.xyz_points(),
                            pose_from_xyz_xyzw([p[0], p[1], p[2]], [p[3], p[4], p[5], p[6]]),
                        ) {
                            world.insert_cloud(&robot, &points, &sensor);
                        }
                    }
                }
                "/ember/plan_response" => {
                    let r: PlanResponse = recording::decode(&m.data).map_err(bad)?;
                    let dof = r.dof as usize;
                    if r.status != 0 || dof != robot.dof() || r.path.is_empty() {
                        continue;
                    }
                    let path: Vec<Vec<f64>> =
                        r.path.chunks_exact(dof).map(<[f64]>::to_vec).collect();
                    let snap = world.snapshot();
                    learn(
                        &robot,
                        &snap.scene,
                        Some(&snap.map),
                        &path,
                        args.interpolate,
                        &mut spark,
                        Some(&mut flame),
                    );
                    plans += 1;
                }
                _ => {}
            }
        }
        bar.finish_and_clear();
    }
    spark.save(&spark_path)?;
    flame.save(&flame_path)?;
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

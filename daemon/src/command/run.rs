//! `ember run`: the daemon. Ingest on its own thread, planning and status on the main thread;
//! SIGINT/SIGTERM stop it cleanly (databases saved).

use crate::cli::RunArgs;
use crate::config::Config;
use crate::monitor::docs::{plan_summary, Sources};
use crate::monitor::Monitor;
use crate::recorder::{self, Record, RecorderOptions};
use crate::service::ingest::{self, SnapshotCell};
use crate::service::plan::{self, Experience};
use crate::service::Stats;
use crate::world::World;
use ember_engine::experience::file::DbError;
use ember_engine::experience::{ExperienceParams, FlameDb, SparkDb};
use ember_sdk::services;
use iceoryx2::prelude::*;
use std::path::Path;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tracing::{error, info, warn};

/// Loads a database, or starts empty; a bad file is moved aside (never overwritten) and logged.
fn load_or_new<T>(
    path: &Path,
    load: impl Fn(&Path) -> Result<T, DbError>,
    new: impl Fn() -> T,
) -> T {
    if !path.exists() {
        return new();
    }
    match load(path) {
        Ok(db) => db,
        Err(e) => {
            let aside = path.with_extension(format!("corrupt-{}", std::process::id()));
            error!("{e}; moved to {} and starting empty", aside.display());
            let _ = std::fs::rename(path, &aside);
            new()
        }
    }
}

fn save(config: &Config, exp: &mut Experience) {
    let dir = &config.experience.db_dir;
    for r in [
        exp.spark.save(dir.join("spark.emberdb")),
        exp.flame.save(dir.join("flame.emberdb")),
    ] {
        if let Err(e) = r {
            error!("saving the experience database failed: {e}");
            return;
        }
    }
    exp.dirty = false;
    info!("experience saved in {}", dir.display());
}

pub fn run(args: RunArgs) -> anyhow::Result<ExitCode> {
    let mut config = Config::load(args.config.as_deref())?;
    if let Some(i) = args.instance {
        anyhow::ensure!(
            ember_sdk::names::valid_instance(&i),
            "invalid instance name '{i}' (letters, digits, '-' and '_')"
        );
        config.instance = i;
    }
    if let Some(d) = args.db_dir {
        config.experience.db_dir = d;
    }
    if let Some(d) = args.record_dir {
        config.record.dir = d;
    }
    if args.no_record {
        config.record.enabled = false;
    }
    if args.no_monitor {
        config.monitor.enabled = false;
    }
    if !args.monitor_listen.is_empty() {
        config.monitor.listen = args.monitor_listen;
    }
    let robot = Arc::new(super::load_robot(&config.robot_spec())?);
    set_log_level(LogLevel::Error);
    let node = NodeBuilder::new()
        .create::<ipc::Service>()
        .map_err(|e| anyhow::anyhow!("cannot create the iceoryx2 node: {e:?}"))?;
    // A daemon killed with SIGKILL leaves its resources behind: reclaim them before serving.
    let _ = node.try_cleanup_dead_nodes();
    let plan_service = services::plan(&node, &config.instance).map_err(anyhow::Error::msg)?;
    let server = plan_service
        .server_builder()
        .initial_max_slice_len(robot.dof() * 64)
        .allocation_strategy(AllocationStrategy::PowerOfTwo)
        .create()
        .map_err(|e| {
            anyhow::anyhow!(
                "cannot serve instance '{}' (is another daemon serving it?): {e:?}",
                config.instance
            )
        })?;
    let status_server = services::status(&node, &config.instance)
        .map_err(anyhow::Error::msg)?
        .server_builder()
        .create()
        .map_err(|e| anyhow::anyhow!("status service: {e:?}"))?;

    let db_dir = config.experience.db_dir.clone();
    let mut experience = Experience {
        spark: load_or_new(
            &db_dir.join("spark.emberdb"),
            |p| SparkDb::load(p),
            || SparkDb::new(ExperienceParams::default()),
        ),
        flame: load_or_new(
            &db_dir.join("flame.emberdb"),
            |p| FlameDb::load(p),
            || FlameDb::new(ExperienceParams::default(), config.map.resolution),
        ),
        dirty: false,
    };
    let snapshot: SnapshotCell = Arc::new(Mutex::new(Arc::new(World::new(&config).snapshot())));
    let stats = Arc::new(Stats::default());
    let stop = Arc::new(AtomicBool::new(false));
    let (recorder, recorder_thread, recording) = if config.record.enabled {
        let (r, t, path) = recorder::start(RecorderOptions {
            dir: config.record.dir.clone(),
            max_file_bytes: (config.record.max_file_mb * 1e6) as u64,
            max_file_duration: Duration::from_secs_f64(config.record.max_file_s),
            queue: config.record.queue,
            chunk_bytes: 4 << 20,
        })?;
        (Some(r), Some(t), path.display().to_string())
    } else {
        (None, None, "off".to_string())
    };
    let (ready_tx, ready_rx) = std::sync::mpsc::channel();
    let ingest = {
        let (config, robot, snapshot, stats, stop, rec) = (
            config.clone(),
            robot.clone(),
            snapshot.clone(),
            stats.clone(),
            stop.clone(),
            recorder.clone(),
        );
        std::thread::Builder::new()
            .name("ingest".into())
            .spawn(move || ingest::run(config, robot, snapshot, stats, stop, ready_tx, rec))?
    };
    if ready_rx.recv().is_err() {
        return match ingest.join() {
            Ok(Err(e)) => Err(e.context("ingest could not start")),
            _ => Err(anyhow::anyhow!("ingest could not start")),
        };
    }
    {
        let mut st = stats.inner.lock().expect("stats lock");
        st.spark_entries = experience.spark.len() as u64;
        st.flame_entries = experience.flame.len() as u64;
    }
    let monitor = if config.monitor.enabled {
        let sources = Sources::new(
            &config,
            &robot,
            stats.clone(),
            snapshot.clone(),
            recorder.as_ref().map(|r| r.stats().clone()),
        );
        // Monitoring is secondary: without it the daemon still serves (and says so).
        match Monitor::start(&config.monitor, sources) {
            Ok(m) => Some(m),
            Err(e) => {
                error!("monitoring off: {e:#}");
                None
            }
        }
    } else {
        None
    };
    let started = Instant::now();
    let mut last_save = Instant::now();
    println!(
        "emberd ready: instance '{}', robot {} ({} joints), experience {} SPARK / {} FLAME entries, monitoring {}, recording {}",
        config.instance,
        robot.name(),
        robot.dof(),
        experience.spark.len(),
        experience.flame.len(),
        if monitor.is_some() { config.monitor.listen.join(",") } else { "off".into() },
        recording,
    );
    use std::io::Write;
    std::io::stdout().flush().ok();

    // Poll without sleeping for a while after each request (a client streaming requests gets
    // them picked up within microseconds), then sleep in short waits.
    let mut last_request = Instant::now() - Duration::from_secs(1);
    loop {
        let busy = last_request.elapsed() < Duration::from_millis(20);
        let wait = if busy {
            Duration::ZERO
        } else {
            Duration::from_micros(50)
        };
        if node.wait(wait).is_err() {
            info!("termination requested");
            break;
        }
        if busy {
            std::thread::yield_now();
        }
        while let Ok(Some(active)) = server.receive() {
            last_request = Instant::now();
            let h = *active.user_header();
            let values: &[f64] = active.payload();
            let recv_ns = ember_sdk::client::now_ns();
            let a = plan::answer(&config, &robot, &snapshot, &mut experience, &h, values);
            let seq = {
                let mut st = stats.inner.lock().expect("stats lock");
                st.plans += 1;
                st.solved += (a.header.status == 0) as u64;
                st.plan_latency_us.push(a.header.total_us);
                st.spark_entries = experience.spark.len() as u64;
                st.flame_entries = experience.flame.len() as u64;
                st.plans
            };
            if a.header.status != 0 {
                warn!(
                    "plan request refused or failed: {}",
                    plan::message(&a.header)
                );
            }
            let flat = a.payload();
            match active.loan_slice_uninit(flat.len()) {
                Ok(mut response) => {
                    *response.user_header_mut() = a.header;
                    let response = response.write_from_slice(&flat);
                    if let Err(e) = response.send() {
                        warn!("sending a plan response failed: {e:?}");
                    }
                }
                Err(e) => warn!("loaning a plan response failed: {e:?}"),
            }
            // Recorded after the reply is out: recording never delays an answer.
            if let Some(r) = &recorder {
                r.record(Record::PlanRequest {
                    recv_ns,
                    request: plan::request_message(recv_ns, &h, values),
                });
                r.record(Record::PlanResponse {
                    recv_ns: ember_sdk::client::now_ns(),
                    response: plan::response_message(recv_ns, &a),
                });
                if let Some(trajectory) = plan::trajectory_message(recv_ns, &robot, &a) {
                    r.record(Record::PlanTrajectory {
                        recv_ns: ember_sdk::client::now_ns(),
                        trajectory,
                    });
                }
            }
            if let Some(m) = &monitor {
                m.plan(plan_summary(&config.instance, seq, recv_ns, &h, &a));
            }
        }
        while let Ok(Some(active)) = status_server.receive() {
            let mut reply = plan::status(&stats, &robot, started);
            if let Some(r) = &recorder {
                reply.recorded = r.stats().written.load(std::sync::atomic::Ordering::Relaxed);
                reply.recording_dropped =
                    r.stats().dropped.load(std::sync::atomic::Ordering::Relaxed);
            }
            if let Err(e) = active.send_copy(reply) {
                warn!("sending status failed: {e:?}");
            }
        }
        if experience.dirty && last_save.elapsed().as_secs_f64() >= config.experience.save_every_s {
            save(&config, &mut experience);
            last_save = Instant::now();
        }
    }
    stop.store(true, Ordering::Relaxed);
    match ingest.join() {
        Ok(Err(e)) => error!("ingest stopped with an error: {e:#}"),
        Err(_) => error!("ingest thread panicked"),
        Ok(Ok(())) => {}
    }
    if experience.dirty {
        save(&config, &mut experience);
    }
    // Watchers see the daemon leave (liveliness token undeclared).
    drop(monitor);
    // The last handle gone, the recorder writes the summary and index and stops.
    drop(recorder);
    if let Some(t) = recorder_thread {
        let _ = t.join();
    }
    println!("emberd stopped");
    Ok(ExitCode::SUCCESS)
}

//! `ember run`: the daemon. Wires the services together: ingest on its own thread, plans on
//! a pool of workers, the plan, status and cancel ports on the main thread; SIGINT/SIGTERM
//! stop it cleanly (plans in flight cancelled and answered, databases saved).

use crate::cli::RunArgs;
use crate::config::Config;
use crate::monitor::docs::Sources;
use crate::monitor::Monitor;
use crate::recorder::{self, RecorderOptions};
use crate::service::cancel::CancelPort;
use crate::service::ingest::Ingest;
use crate::service::plan::workers::work;
use crate::service::plan::{Job, PlanContext, PlanPort, Reply};
use crate::service::status::StatusPort;
use crate::service::{SnapshotCell, Stats, IDLE_WAIT};
use ember_engine::experience::{Database, Experience, ExperienceParams};
use ember_engine::world::model::World;
use ember_sdk::launch::Ready;
use ember_sdk::services::{self, Open, Wake};
use iceoryx2::prelude::*;
use iceoryx2_bb_posix::signal::SignalHandler;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{mpsc, Arc, Mutex, RwLock};
use std::time::{Duration, Instant};
use tracing::{error, info};

/// Saves the experience into the configured folder (errors are logged: the daemon serves on).
fn save(config: &Config, experience: &mut Experience) {
    let dir = &config.experience.db_dir;
    match experience.save_dir(dir) {
        Ok(()) => info!("experience saved in {}", dir.display()),
        Err(e) => error!("saving the experience database failed: {e}"),
    }
    for file in Experience::files(dir) {
        if let Err(e) = config.apply_file_mode(&file) {
            error!("setting the mode of {}: {e}", file.display());
        }
    }
}

/// The configuration with the command line's overrides.
fn config_of(args: &RunArgs) -> anyhow::Result<Config> {
    let mut config = Config::load(args.config.as_deref())?;
    if let Some(i) = &args.instance {
        anyhow::ensure!(
            ember_sdk::names::valid_instance(i),
            "invalid instance name '{i}' (letters, digits, '-' and '_')"
        );
        config.instance = i.clone();
    }
    if let Some(d) = &args.db_dir {
        config.experience.db_dir = d.clone();
    }
    if let Some(d) = &args.record_dir {
        config.record.dir = d.clone();
    }
    if args.no_record {
        config.record.enabled = false;
    }
    if args.no_monitor {
        config.monitor.enabled = false;
    }
    if !args.monitor_listen.is_empty() {
        config.monitor.listen = args.monitor_listen.clone();
    }
    Ok(config)
}

pub fn run(args: RunArgs) -> anyhow::Result<ExitCode> {
    let config = config_of(&args)?;
    let robot = Arc::new(super::load_robot(&config.robot_spec())?);
    // Where an obstacle could hide inside a link, worked out now rather than by the first plan.
    let t = std::time::Instant::now();
    ember_engine::collision::batch::prepare_validation(&robot, &[config.map.resolution]);
    info!(
        "validation prepared in {:.1} ms",
        t.elapsed().as_secs_f64() * 1e3
    );
    set_log_level(LogLevel::Error);
    let node = NodeBuilder::new()
        .create::<ipc::Service>()
        .map_err(|e| anyhow::anyhow!("cannot create the iceoryx2 node: {e:?}"))?;
    // A daemon killed with SIGKILL leaves its resources behind: reclaim them before serving.
    let _ = node.try_cleanup_dead_nodes();
    let limits = config.limits.get();
    let mut plans = PlanPort::open(&node, &config.instance, limits, robot.dof())?;
    let status = StatusPort::open(&node, &config.instance, limits)?;
    let cancel = CancelPort::open(&node, &config.instance, limits)?;
    // Clients (and the planning workers) notify this after sending: the loop below sleeps on it.
    let wake = services::wake(&node, &config.instance, Wake::Requests, Open::Serve(limits))
        .map_err(anyhow::Error::msg)?
        .listener_builder()
        .create()
        .map_err(|e| anyhow::anyhow!("requests wake-up listener: {e:?}"))?;

    let (experience, set_aside) = Experience::load_dir(
        &config.experience.db_dir,
        &ExperienceParams::default(),
        config.map.resolution,
    )?;
    for s in set_aside {
        error!("{s}");
    }
    let snapshot: SnapshotCell = Arc::new(Mutex::new(Arc::new(
        World::new(&config.world_params()).snapshot(),
    )));
    let stats = Arc::new(Stats::default());
    stats.learned(&experience);
    let stop = Arc::new(AtomicBool::new(false));
    let (recorder, recorder_thread, recording) = if config.record.enabled {
        let (r, t, path) = recorder::start(RecorderOptions {
            dir: config.record.dir.clone(),
            max_file_bytes: (config.record.max_file_mb * 1e6) as u64,
            max_file_duration: Duration::from_secs_f64(config.record.max_file_s),
            queue: config.record.queue,
            chunk_bytes: 4 << 20,
            file_mode: config.file_mode(),
        })?;
        (Some(r), Some(t), Some(path))
    } else {
        (None, None, None)
    };
    let (ready_tx, ready_rx) = std::sync::mpsc::channel();
    let ingest = Ingest {
        config: config.clone(),
        robot: robot.clone(),
        snapshot: snapshot.clone(),
        stats: stats.clone(),
        stop: stop.clone(),
        recorder: recorder.clone(),
    };
    let ingest = std::thread::Builder::new()
        .name("ingest".into())
        .spawn(move || ingest.run(ready_tx))?;
    if ready_rx.recv().is_err() {
        return match ingest.join() {
            Ok(Err(e)) => Err(e.context("ingest could not start")),
            _ => Err(anyhow::anyhow!("ingest could not start")),
        };
    }
    let sources = Arc::new(Sources::new(
        &config,
        &robot,
        stats.clone(),
        snapshot.clone(),
        recorder.as_ref().map(|r| r.stats().clone()),
    ));
    let monitor = if config.monitor.enabled {
        // Monitoring is secondary: without it the daemon still serves (and says so).
        match Monitor::start(&config.monitor, sources.clone()) {
            Ok(m) => Some(m),
            Err(e) => {
                error!("monitoring off: {e:#}");
                None
            }
        }
    } else {
        None
    };
    let mut last_save = Instant::now();
    let ready = Ready {
        instance: config.instance.clone(),
        robot: robot.name().to_string(),
        dof: robot.dof(),
        spark_entries: experience.spark.len(),
        flame_entries: experience.flame.len(),
        monitoring: match monitor {
            Some(_) => config.monitor.listen.join(","),
            None => "off".into(),
        },
        recording,
    };
    // SIGINT/SIGTERM: from here on iceoryx2's handler records them (before the ready line, so
    // a signal sent on seeing it is never the default, fatal one); the loop below looks each
    // round, then cancels the plans in flight (each ends as `cancelled` within milliseconds),
    // answers them and stops.
    let mut terminate = SignalHandler::termination_requested();
    println!("{ready}");
    use std::io::Write;
    std::io::stdout().flush().ok();

    let cx = PlanContext {
        config: &config,
        robot: &robot,
        snapshot: &snapshot,
        stats: &stats,
        recorder: recorder.as_ref(),
        monitor: monitor.as_ref(),
    };
    let experience = RwLock::new(experience);
    let (job_tx, job_rx) = mpsc::channel::<Job>();
    let job_rx = Mutex::new(job_rx);
    let (reply_tx, reply_rx) = mpsc::channel::<Reply>();
    let workers = config.planner.worker_count();
    info!("planning on {workers} worker thread(s)");
    std::thread::scope(|scope| -> anyhow::Result<()> {
        for i in 0..workers {
            let (cx, experience, job_rx, reply_tx) = (&cx, &experience, &job_rx, reply_tx.clone());
            std::thread::Builder::new()
                .name(format!("planner-{i}"))
                .spawn_scoped(scope, move || work(cx, experience, job_rx, reply_tx))?;
        }
        drop(reply_tx);
        // Poll without sleeping for a while after each plan request (a client streaming
        // requests gets them picked up within microseconds), then sleep until a client or a
        // worker notifies (or the idle wait ends: clients that do not notify, the stop flag).
        let mut last_request = Instant::now() - Duration::from_secs(1);
        while !terminate {
            if last_request.elapsed() < Duration::from_millis(20) {
                std::thread::yield_now();
                let _ = wake.try_wait(|_| {});
            } else {
                let _ = wake.timed_wait(|_| {}, IDLE_WAIT);
            }
            while let Ok(r) = reply_rx.try_recv() {
                plans.reply(r);
            }
            if plans.take(&stats, &job_tx) > 0 {
                last_request = Instant::now();
            }
            status.serve(&sources);
            cancel.serve(&stats.in_flight);
            terminate |= SignalHandler::termination_requested();
            if last_save.elapsed().as_secs_f64() >= config.experience.save_every_s {
                let mut experience = experience
                    .write()
                    .unwrap_or_else(std::sync::PoisonError::into_inner);
                if experience.is_dirty() {
                    save(&config, &mut experience);
                }
                last_save = Instant::now();
            }
        }
        info!("termination requested");
        // Plans in flight (and queued) end as `cancelled` and are answered before the exit.
        stats.in_flight.cancel_all();
        drop(job_tx);
        for r in reply_rx.iter() {
            plans.reply(r);
        }
        Ok(())
    })?;
    let mut experience = experience
        .into_inner()
        .unwrap_or_else(std::sync::PoisonError::into_inner);
    stop.store(true, Ordering::Relaxed);
    match ingest.join() {
        Ok(Err(e)) => error!("ingest stopped with an error: {e:#}"),
        Err(_) => error!("ingest thread panicked"),
        Ok(Ok(())) => {}
    }
    if experience.is_dirty() {
        save(&config, &mut experience);
    }
    // Watchers see the daemon leave (liveliness token undeclared).
    drop(monitor);
    // The last handle gone, the recorder writes the summary and index and stops.
    drop(recorder);
    drop(sources);
    if let Some(t) = recorder_thread {
        let _ = t.join();
    }
    println!("emberd stopped");
    Ok(ExitCode::SUCCESS)
}

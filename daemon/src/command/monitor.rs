//! `ember monitor`: watch daemons over Zenoh. A live terminal view of one or every instance, or
//! `--once --json`: the status of each instance that answers, as a JSON array (exit 1 if none).

use crate::cli::MonitorArgs;
use crate::monitor::session::{self, SessionOptions};
use ember_sdk::monitor::{instance_of, key, PlanSummary, StatusDoc};
use std::collections::BTreeMap;
use std::io::Write;
use std::process::ExitCode;
use std::sync::mpsc::{channel, RecvTimeoutError, Sender};
use std::time::{Duration, Instant};
use zenoh::sample::{Sample, SampleKind};
use zenoh::{Session, Wait};

pub fn run(args: MonitorArgs) -> anyhow::Result<ExitCode> {
    anyhow::ensure!(
        args.instance == "*" || ember_sdk::names::valid_instance(&args.instance),
        "invalid instance name '{}'",
        args.instance
    );
    anyhow::ensure!(
        args.timeout.is_finite() && args.timeout > 0.0,
        "--timeout must be a positive number of seconds"
    );
    let session = session::open(&SessionOptions {
        mode: &args.mode,
        listen: &[],
        connect: &args.connect,
        multicast_scouting: args.scout,
        base: args.zenoh_config.as_deref(),
    })?;
    if args.once {
        once(&session, &args)
    } else {
        live(&session, &args)
    }
}

/// Statuses of the instances that answer within the timeout, by instance.
pub fn query_status(
    session: &Session,
    instance: &str,
    timeout: Duration,
) -> anyhow::Result<BTreeMap<String, StatusDoc>> {
    let deadline = Instant::now() + timeout;
    let mut found = BTreeMap::new();
    // A session just opened may still be connecting, and peers of the first daemon reached are
    // learnt by gossip a moment later: ask in rounds until a round finds nobody new (after
    // someone answered) or the deadline.
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        if left.is_zero() {
            break;
        }
        let before = found.len();
        let replies = session
            .get(key(instance, "status"))
            .timeout(left.min(Duration::from_millis(300)))
            .wait()
            .map_err(|e| anyhow::anyhow!("zenoh query: {e}"))?;
        while let Ok(reply) = replies.recv() {
            if let Ok(sample) = reply.result() {
                match serde_json::from_slice::<StatusDoc>(&sample.payload().to_bytes()) {
                    Ok(doc) => {
                        found.insert(doc.instance.clone(), doc);
                    }
                    Err(e) => eprintln!(
                        "ignoring a malformed status from {}: {e}",
                        sample.key_expr()
                    ),
                }
            }
        }
        if before > 0 && found.len() == before {
            break;
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    Ok(found)
}

fn once(session: &Session, args: &MonitorArgs) -> anyhow::Result<ExitCode> {
    let found = query_status(
        session,
        &args.instance,
        Duration::from_secs_f64(args.timeout),
    )?;
    let docs: Vec<&StatusDoc> = found.values().collect();
    println!("{}", serde_json::to_string_pretty(&docs)?);
    if docs.is_empty() {
        eprintln!(
            "no Ember instance answered within {} s on {:?}",
            args.timeout, args.connect
        );
        return Ok(ExitCode::from(1));
    }
    Ok(ExitCode::SUCCESS)
}

enum Event {
    Status(Box<StatusDoc>),
    Plan(Box<PlanSummary>),
    Alive(String, bool),
}

fn forward<T: serde::de::DeserializeOwned>(
    tx: &Sender<Event>,
    sample: &Sample,
    wrap: impl Fn(Box<T>) -> Event,
) {
    if let Ok(v) = serde_json::from_slice::<T>(&sample.payload().to_bytes()) {
        let _ = tx.send(wrap(Box::new(v)));
    }
}

/// What the live view shows of one instance.
#[derive(Default)]
struct Watched {
    alive: bool,
    status: Option<StatusDoc>,
    plans: Vec<PlanSummary>,
}

fn live(session: &Session, args: &MonitorArgs) -> anyhow::Result<ExitCode> {
    let (tx, rx) = channel();
    let z = |e: zenoh::Error| anyhow::anyhow!("zenoh: {e}");
    let t = tx.clone();
    let _status = session
        .declare_subscriber(key(&args.instance, "status"))
        .callback(move |s| forward(&t, &s, Event::Status))
        .wait()
        .map_err(z)?;
    let t = tx.clone();
    let _plans = session
        .declare_subscriber(key(&args.instance, "plans"))
        .callback(move |s| forward(&t, &s, Event::Plan))
        .wait()
        .map_err(z)?;
    let t = tx;
    let _alive = session
        .liveliness()
        .declare_subscriber(key(&args.instance, "alive"))
        .history(true)
        .callback(move |s| {
            if let Some(i) = instance_of(s.key_expr().as_str()) {
                let _ = t.send(Event::Alive(i.to_string(), s.kind() == SampleKind::Put));
            }
        })
        .wait()
        .map_err(z)?;
    // Whether this watcher authenticates; each instance says whether it admits only peers that
    // do (the `auth` column): what reaches us through such an instance came from them.
    let who = match session::Authentication::of(args.zenoh_config.as_deref())?.user {
        Some(u) => format!("authenticated as '{u}'"),
        None => "unauthenticated".to_string(),
    };
    let mut watched: BTreeMap<String, Watched> = BTreeMap::new();
    let mut next_draw = Instant::now();
    loop {
        match rx.recv_timeout(next_draw.saturating_duration_since(Instant::now())) {
            Ok(Event::Status(doc)) => {
                let w = watched.entry(doc.instance.clone()).or_default();
                w.alive = true;
                w.status = Some(*doc);
            }
            Ok(Event::Plan(p)) => {
                let w = watched.entry(p.instance.clone()).or_default();
                w.plans.push(*p);
                let n = w.plans.len();
                w.plans.drain(..n.saturating_sub(5));
            }
            Ok(Event::Alive(i, alive)) => watched.entry(i).or_default().alive = alive,
            Err(RecvTimeoutError::Timeout) => {
                draw(&watched, &args.connect, &who);
                next_draw = Instant::now() + Duration::from_secs(1);
            }
            Err(RecvTimeoutError::Disconnected) => return Ok(ExitCode::SUCCESS),
        }
    }
}

fn draw(watched: &BTreeMap<String, Watched>, connect: &[String], who: &str) {
    let mut out = String::from("\x1b[2J\x1b[H");
    out += &format!(
        "ember monitor: {} instance(s) via {}, {who}   (Ctrl-C to quit)\n\n",
        watched.len(),
        connect.join(",")
    );
    out += &format!(
        "{:<14} {:<6} {:<6} {:>8} {:>8} {:>8} {:>9} {:>11} {:>9} {:>15} {:>10} {:>8}\n",
        "instance",
        "state",
        "auth",
        "uptime",
        "cloud/s",
        "objects",
        "map MB",
        "spark/flame",
        "plans",
        "p50/p99 ms",
        "in flight",
        "dropped"
    );
    for (name, w) in watched {
        let state = if w.alive { "up" } else { "gone" };
        match &w.status {
            Some(s) => {
                out += &format!(
                    "{:<14} {:<6} {:<6} {:>7.0}s {:>8.1} {:>8} {:>9.1} {:>11} {:>9} {:>15} {:>10} {:>8}\n",
                    name,
                    state,
                    match s.monitor_auth.as_str() {
                        "" => "?",
                        a => a,
                    },
                    s.uptime_s,
                    s.inputs.cloud_hz,
                    s.world.objects,
                    s.map.memory_bytes as f64 / 1e6,
                    format!(
                        "{}/{}",
                        s.experience.spark_entries, s.experience.flame_entries
                    ),
                    format!("{}/{}", s.plans.solved, s.plans.total),
                    format!(
                        "{:.1}/{:.1}",
                        s.plans.latency_p50_ms, s.plans.latency_p99_ms
                    ),
                    // How many, and how long the oldest has run: a stuck planner shows here.
                    match s.plans.in_flight {
                        0 => "0".to_string(),
                        n => format!("{n} ({:.1}s)", s.plans.oldest_in_flight_ms / 1e3),
                    },
                    s.recording.dropped + s.monitor_dropped,
                );
            }
            None => out += &format!("{name:<14} {state:<6} (waiting for status)\n"),
        }
    }
    for (name, w) in watched {
        if w.plans.is_empty() {
            continue;
        }
        out += &format!("\nlast plans of {name}:\n");
        for p in &w.plans {
            let executes = if p.duration_s > 0.0 {
                format!(", executes in {:.2} s", p.duration_s)
            } else {
                String::new()
            };
            out += &format!(
                "  #{:<6} {:<8} {:<7} {:<18} {:>9.2} ms  retrieval {:>8.1} µs  {} waypoints{executes}\n",
                p.seq,
                p.goal,
                p.method,
                p.status_name,
                p.total_us / 1e3,
                p.retrieval_us,
                p.waypoints
            );
        }
    }
    if watched.is_empty() {
        out += "\n(no instance seen yet: is a daemon running with monitoring on, and listening where --connect points?)\n";
    }
    let mut stdout = std::io::stdout().lock();
    let _ = stdout.write_all(out.as_bytes());
    let _ = stdout.flush();
}

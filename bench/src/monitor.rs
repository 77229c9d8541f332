//! `monitor`: what monitoring over Zenoh costs the planner. Starts two real daemons, one
//! publishing over Zenoh to a watcher in this process (subscribed to every key, so every
//! publication really goes out) and one with `--no-monitor`; both get the same map (a few
//! 640×480 clouds, so the map snapshots are not empty) and then the same plan requests,
//! alternating between the two so machine noise lands on both alike.
//!
//! Flags: `--plans N` (default 1000 per daemon). Ends with
//! `RESULT monitor plan_p50_us_on=<f> plan_p99_us_on=<f> plan_p50_us_off=<f> plan_p99_us_off=<f>`.

use crate::daemon::DaemonProcess;
use ember_sdk::stats::quantile;
use ember_sdk::wire::{Method, Point};
use ember_sdk::{Client, PlanCall, Status};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};
use zenoh::Wait;

#[derive(clap::Args)]
pub struct Args {
    /// Plan requests per daemon.
    #[arg(long, default_value_t = 1000)]
    plans: usize,
}

const CONFIG: &str = "[experience]\nonline_learning = false\n";

pub fn run(args: Args) -> anyhow::Result<()> {
    let port = std::net::TcpListener::bind("127.0.0.1:0")?
        .local_addr()?
        .port();
    let endpoint = format!("tcp/127.0.0.1:{port}");
    let on = DaemonProcess::start(
        "monitor-on",
        CONFIG,
        &["--no-record", "--monitor-listen", &endpoint],
    )?;
    let off = DaemonProcess::start("monitor-off", CONFIG, &["--no-record", "--no-monitor"])?;

    // The watcher: every key of the monitored daemon.
    let mut config = zenoh::Config::default();
    let set = |c: &mut zenoh::Config, k: &str, v: &str| {
        c.insert_json5(k, v).map_err(|e| anyhow::anyhow!("{e}"))
    };
    set(
        &mut config,
        "connect/endpoints",
        &format!("[\"{endpoint}\"]"),
    )?;
    set(&mut config, "scouting/multicast/enabled", "false")?;
    let session = zenoh::open(config)
        .wait()
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let received = Arc::new(AtomicU64::new(0));
    let bytes = Arc::new(AtomicU64::new(0));
    let (r, b) = (received.clone(), bytes.clone());
    let _sub = session
        .declare_subscriber(format!("ember/{}/**", on.instance))
        .callback(move |s| {
            r.fetch_add(1, Ordering::Relaxed);
            b.fetch_add(s.payload().len() as u64, Ordering::Relaxed);
        })
        .wait()
        .map_err(|e| anyhow::anyhow!("{e}"))?;

    let clients = [
        Client::connect(&on.instance)?,
        Client::connect(&off.instance)?,
    ];
    let t = Duration::from_secs(10);
    for client in &clients {
        for k in 0..5u64 {
            client.publish_cloud(
                "head_camera",
                [0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
                0,
                640 * 480,
                |i| Point {
                    x: 1.5 + (i % 7) as f32 * 0.02,
                    y: -0.8 + (i % 640) as f32 * 0.0025,
                    z: -0.6 + (i / 640) as f32 * 0.0025 + k as f32 * 0.001,
                },
            )?;
            let deadline = Instant::now() + t;
            while client.status(t)?.clouds <= k {
                anyhow::ensure!(
                    Instant::now() < deadline,
                    "the daemon did not take cloud {k}"
                );
                std::thread::sleep(Duration::from_millis(5));
            }
        }
    }

    // A short joint move planned in full (IK-free, a few collision checks): the planner's own
    // time stays small, so what monitoring adds would show.
    let start = vec![0.1, 1.32, 1.40, -0.2, 1.72, 0.0, 1.66, 0.0];
    let mut goal = start.clone();
    goal[7] += 0.3;
    let call = PlanCall {
        start,
        goals: vec![goal],
        pose: None,
        method: Method::Uniform,
        time_limit_s: 5.0,
        seed: 1,
        trajectory: None,
    };
    for client in &clients {
        for _ in 0..50 {
            client.plan(&call, t)?;
        }
    }
    let started = Instant::now();
    let mut times = [Vec::new(), Vec::new()];
    for _ in 0..args.plans {
        for (client, v) in clients.iter().zip(&mut times) {
            let t0 = Instant::now();
            let reply = client.plan(&call, t)?;
            v.push(t0.elapsed().as_secs_f64() * 1e6);
            anyhow::ensure!(
                reply.status == Status::Ok,
                "plan failed: {}",
                reply.message()
            );
        }
    }
    let secs = started.elapsed().as_secs_f64();
    let [mut on_t, mut off_t] = times;
    let (on50, on99) = (quantile(&mut on_t, 0.5), quantile(&mut on_t, 0.99));
    let (off50, off99) = (quantile(&mut off_t, 0.5), quantile(&mut off_t, 0.99));
    println!(
        "watcher received {} publications ({:.1} kB) in {secs:.1} s: a summary per plan, status, objects, map",
        received.load(Ordering::Relaxed),
        bytes.load(Ordering::Relaxed) as f64 / 1e3
    );
    println!(
        "plan round trip, {} requests each, alternating: monitoring on p50 {on50:.1} / p99 {on99:.1} us, off p50 {off50:.1} / p99 {off99:.1} us ({:+.1}% at p50)",
        args.plans,
        (on50 / off50 - 1.0) * 100.0
    );
    println!(
        "RESULT monitor plan_p50_us_on={on50:.1} plan_p99_us_on={on99:.1} plan_p50_us_off={off50:.1} plan_p99_us_off={off99:.1}"
    );
    Ok(())
}

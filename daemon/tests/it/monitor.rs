//! Monitoring over Zenoh: a real daemon process publishing on loopback, watched from this test
//! process (a real Zenoh session) and by `ember monitor` (a third process).

use crate::daemon::{publish_table, wait_for, Daemon, FREE_GOAL, TUCK};
use ember_sdk::monitor::{key, MapSnapshot, PlanSummary, StatusDoc};
use ember_sdk::wire::{Method, Point};
use ember_sdk::{PlanCall, Status};
use std::process::Command;
use std::sync::mpsc::{channel, Receiver};
use std::time::{Duration, Instant};
use zenoh::sample::SampleKind;
use zenoh::{Session, Wait};

/// A loopback endpoint on a port nobody uses right now.
fn free_endpoint() -> String {
    let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    format!("tcp/127.0.0.1:{}", l.local_addr().unwrap().port())
}

fn watcher(endpoint: &str) -> Session {
    let mut c = zenoh::Config::default();
    c.insert_json5("mode", "\"peer\"").unwrap();
    c.insert_json5("connect/endpoints", &format!("[\"{endpoint}\"]"))
        .unwrap();
    c.insert_json5("scouting/multicast/enabled", "false")
        .unwrap();
    zenoh::open(c).wait().unwrap()
}

/// The first item of `rx` that satisfies `f`, within 10 s.
fn next<T: std::fmt::Debug>(rx: &Receiver<T>, what: &str, f: impl Fn(&T) -> bool) -> T {
    let deadline = Instant::now() + Duration::from_secs(10);
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        match rx.recv_timeout(left) {
            Ok(v) if f(&v) => return v,
            Ok(_) => {}
            Err(_) => panic!("timed out waiting for {what}"),
        }
    }
}

fn get(session: &Session, key: &str) -> Vec<u8> {
    let replies = session
        .get(key)
        .timeout(Duration::from_secs(5))
        .wait()
        .unwrap();
    let reply = replies.recv().expect("an answer");
    reply.result().unwrap().payload().to_bytes().to_vec()
}

/// `ember monitor --once --json` of `instance` through `endpoint` (with a Zenoh config file).
fn monitor_once(
    endpoint: &str,
    instance: &str,
    zenoh_config: Option<&std::path::Path>,
) -> std::process::Output {
    let mut c = Command::new(env!("CARGO_BIN_EXE_ember"));
    c.args(["monitor", "--once", "--json", "--timeout", "3"])
        .args(["--connect", endpoint, "--instance", instance]);
    if let Some(z) = zenoh_config {
        c.arg("--zenoh-config").arg(z);
    }
    c.output().unwrap()
}

/// The statuses `ember monitor --once --json` printed (it must have succeeded).
fn statuses(out: &std::process::Output) -> Vec<StatusDoc> {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

#[test]
fn a_watcher_sees_status_plans_objects_map_and_liveliness() {
    let endpoint = free_endpoint();
    let d = Daemon::start_args("zenoh", &["--monitor-listen", &endpoint]);
    let z = watcher(&endpoint);
    let (alive_tx, alive_rx) = channel();
    let _alive = z
        .liveliness()
        .declare_subscriber(key(&d.instance, "alive"))
        .history(true)
        .callback(move |s| alive_tx.send(s.kind() == SampleKind::Put).unwrap())
        .wait()
        .unwrap();
    let (status_tx, status_rx) = channel();
    let _status = z
        .declare_subscriber(key(&d.instance, "status"))
        .callback(move |s| {
            let _ = status_tx.send(serde_json::from_slice::<StatusDoc>(&s.payload().to_bytes()));
        })
        .wait()
        .unwrap();
    let (plans_tx, plans_rx) = channel();
    let _plans = z
        .declare_subscriber(key(&d.instance, "plans"))
        .callback(move |s| {
            let _ = plans_tx.send(serde_json::from_slice::<PlanSummary>(
                &s.payload().to_bytes(),
            ));
        })
        .wait()
        .unwrap();
    let (objects_tx, objects_rx) = channel();
    let _objects = z
        .declare_subscriber(key(&d.instance, "objects"))
        .callback(move |s| {
            let _ = objects_tx.send(s.payload().try_to_string().unwrap().to_string());
        })
        .wait()
        .unwrap();
    next(&alive_rx, "the daemon's liveliness token", |up| *up);

    // Objects and a plan through the iceoryx2 services show up on Zenoh.
    let client = d.client();
    publish_table(&client);
    wait_for(&client, "objects", |s| s.world_objects == 3);
    let json = next(&objects_rx, "the objects", |j| j.contains("\"table\""));
    let scene: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!(scene["objects"].as_array().unwrap().len(), 3, "{json}");
    let reply = client
        .plan(
            &PlanCall {
                start: TUCK.to_vec(),
                goals: vec![FREE_GOAL.to_vec()],
                pose: None,
                method: Method::Uniform,
                time_limit_s: 10.0,
                seed: 3,
                trajectory: None,
            },
            Duration::from_secs(20),
        )
        .unwrap();
    assert_eq!(reply.status, Status::Ok, "{}", reply.message());
    let plan = next(&plans_rx, "a plan summary", |p| p.is_ok()).unwrap();
    assert_eq!(
        (plan.seq, plan.status, plan.status_name.as_str()),
        (1, 0, "ok")
    );
    assert_eq!(
        (plan.goal.as_str(), plan.method.as_str()),
        ("joints", "uniform")
    );
    assert_eq!(plan.waypoints as usize, reply.path.len());
    let status = next(&status_rx, "a status counting the plan", |s| {
        s.as_ref().is_ok_and(|s| s.plans.total == 1)
    })
    .unwrap();
    assert_eq!(status.instance, d.instance);
    assert_eq!((status.robot.as_str(), status.dof), ("fetch", 8));
    assert_eq!((status.world.objects, status.plans.solved), (3, 1));
    assert!(status.plans.latency_p50_ms > 0.0, "{status:?}");
    assert!(status.recording.enabled && status.recording.written > 0);

    // A cloud: the map snapshot answers on query with the wall's octoboxes.
    client
        .publish_cloud(
            "head_camera",
            [0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            ember_sdk::client::now_ns(),
            100 * 100,
            // Every hundredth point has no return (NaN), as depth cameras send them.
            |i| Point {
                x: if i % 100 == 7 { f32::NAN } else { 1.5 },
                y: -0.5 + (i % 100) as f32 * 0.01,
                z: -0.5 + (i / 100) as f32 * 0.01,
            },
        )
        .unwrap();
    wait_for(&client, "the cloud", |s| s.clouds == 1);
    let map = MapSnapshot::decode(&get(&z, &key(&d.instance, "map"))).unwrap();
    assert!((map.resolution - 0.02).abs() < 1e-6);
    // A 1 m × 1 m wall one leaf thick: about 50 × 50 occupied leaves.
    let leaves = map.occupied_leaves();
    assert!((2000..=3500).contains(&leaves), "{leaves} leaves");
    let db: serde_json::Value =
        serde_json::from_slice(&get(&z, &key(&d.instance, "database"))).unwrap();
    assert_eq!(
        db["dir"].as_str().unwrap(),
        d.db_dir.to_str().unwrap(),
        "{db}"
    );
    assert_eq!(
        db["spark_entries"].as_u64(),
        Some(status.experience.spark_entries)
    );
    assert!(db["online_learning"].as_bool().unwrap());

    // `ember monitor --once --json` in another process finds the same instance.
    let docs = statuses(&monitor_once(&endpoint, &d.instance, None));
    assert_eq!(docs.len(), 1);
    // The no-return points were dropped and counted; the rest of the cloud was used.
    assert_eq!(docs[0].inputs.invalid_points, 100);
    assert_eq!(
        (docs[0].instance.as_str(), docs[0].inputs.clouds),
        (d.instance.as_str(), 1)
    );

    // A clean stop withdraws the token; afterwards nobody answers and the monitor says so.
    d.signal("-TERM");
    next(&alive_rx, "the token's withdrawal", |up| !*up);
    let out = monitor_once(&endpoint, &d.instance, None);
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("no Ember instance answered"));
}

#[test]
fn a_killed_daemon_disappears_for_watchers() {
    let endpoint = free_endpoint();
    let d = Daemon::start_args("zenoh-kill", &["--monitor-listen", &endpoint]);
    let z = watcher(&endpoint);
    let (tx, rx) = channel();
    let _alive = z
        .liveliness()
        .declare_subscriber(key("*", "alive"))
        .history(true)
        .callback(move |s| tx.send((s.key_expr().to_string(), s.kind())).unwrap())
        .wait()
        .unwrap();
    let alive = key(&d.instance, "alive");
    next(&rx, "the token", |(k, kind)| {
        *k == alive && *kind == SampleKind::Put
    });
    d.signal("-KILL");
    next(&rx, "the token's loss", |(k, kind)| {
        *k == alive && *kind == SampleKind::Delete
    });
}

#[test]
fn a_daemon_with_monitoring_off_answers_no_watcher() {
    let d = Daemon::start("zenoh-off");
    let out = monitor_once(&free_endpoint(), &d.instance, None);
    assert_eq!(
        out.status.code(),
        Some(1),
        "nothing listens: nobody answers"
    );
}

#[test]
fn a_second_daemon_on_a_taken_port_joins_the_first_and_both_are_seen() {
    let endpoint = free_endpoint();
    let a = Daemon::start_args("zenoh-first", &["--monitor-listen", &endpoint]);
    let b = Daemon::start_args("zenoh-second", &["--monitor-listen", &endpoint]);
    let out = Command::new(env!("CARGO_BIN_EXE_ember"))
        .args(["monitor", "--once", "--json", "--timeout", "3"])
        .args(["--connect", &endpoint])
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let docs: Vec<StatusDoc> = serde_json::from_slice(&out.stdout).unwrap();
    assert!(
        docs.iter().all(|s| s.monitor_auth == "none"),
        "open sessions say so"
    );
    for d in [&a, &b] {
        assert!(
            docs.iter().any(|s| s.instance == d.instance),
            "{} missing from {:?}",
            d.instance,
            docs.iter().map(|s| &s.instance).collect::<Vec<_>>()
        );
    }
}

#[test]
fn monitoring_can_require_authentication() {
    // The daemon's Zenoh session admits only peers with a user and password from its
    // dictionary: a watcher with them reads its status (marked `usrpwd`); one without, or with
    // a wrong password, reads nothing, and so cannot have published anything either.
    let dir = std::env::temp_dir().join(format!("ember-zauth-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let dictionary = dir.join("credentials.txt");
    std::fs::write(&dictionary, "ember:s3cret\nwatcher:w4tch\n").unwrap();
    let zenoh = |user: &str, password: &str, dictionary: Option<&std::path::Path>| {
        let path = dir.join(format!("{user}-{password}.json5"));
        let dict = dictionary.map_or(String::new(), |d| {
            format!(", dictionary_file: \"{}\"", d.display())
        });
        std::fs::write(
            &path,
            format!(
                "{{ transport: {{ auth: {{ usrpwd: {{ user: \"{user}\", password: \"{password}\"{dict} }} }} }} }}"
            ),
        )
        .unwrap();
        path
    };
    let daemon_zenoh = zenoh("ember", "s3cret", Some(&dictionary));
    let config = dir.join("emberd.toml");
    std::fs::write(
        &config,
        format!("[monitor]\nzenoh_config = \"{}\"\n", daemon_zenoh.display()),
    )
    .unwrap();
    let endpoint = free_endpoint();
    let d = Daemon::start_args(
        "zenoh-auth",
        &[
            "--monitor-listen",
            &endpoint,
            "--config",
            config.to_str().unwrap(),
        ],
    );
    let watch = |z: Option<&std::path::Path>| monitor_once(&endpoint, &d.instance, z);
    let docs = statuses(&watch(Some(&zenoh("watcher", "w4tch", None))));
    assert_eq!(docs.len(), 1);
    assert_eq!(docs[0].monitor_auth, "usrpwd");
    assert_eq!(
        watch(None).status.code(),
        Some(1),
        "no credentials: nothing read"
    );
    let wrong = zenoh("watcher", "guess", None);
    assert_eq!(
        watch(Some(&wrong)).status.code(),
        Some(1),
        "a wrong password: nothing read"
    );
    std::fs::remove_dir_all(&dir).ok();
}

//! `ember demo`: the main job, run briefly as a user would; its summary and the files it writes.

use ember_engine::experience::{Database, Experience};
use ember_sdk::session::{Event, Session, SessionError, TopicMap};
use ember_sdk::wire::FLAG_NO_LEARN;
use std::collections::BTreeMap;
use std::path::PathBuf;

/// `key=value` fields of the `RESULT demo` line that has `first`.
fn result_line(stdout: &str, first: &str) -> BTreeMap<String, String> {
    named_result_line(stdout, "demo", first)
}

/// `key=value` fields of the `RESULT <name>` line that has `first`.
fn named_result_line(stdout: &str, name: &str, first: &str) -> BTreeMap<String, String> {
    let line = stdout
        .lines()
        .find(|l| l.starts_with(&format!("RESULT {name} ")) && l.contains(first))
        .unwrap_or_else(|| panic!("no RESULT line with {first} in:\n{stdout}"));
    line.split_whitespace()
        .skip(2)
        .map(|kv| {
            let (k, v) = kv.split_once('=').expect("key=value");
            (k.to_string(), v.to_string())
        })
        .collect()
}

#[test]
fn the_demo_plans_with_every_method_through_the_daemon_and_keeps_its_session() {
    let dir = std::env::temp_dir().join(format!("ember-demo-it-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let (record, db) = (dir.join("recordings"), dir.join("db"));
    let out = crate::ember(&[
        "demo",
        "--episodes",
        "3",
        "--seed",
        "2",
        "--instance",
        &format!("it-demo-{}", std::process::id()),
        "--record",
        record.to_str().unwrap(),
        "--db",
        db.to_str().unwrap(),
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // The last lines: one per method of the picks, then the files.
    let tail: Vec<&str> = stdout.lines().rev().take(4).collect();
    assert!(tail[0].starts_with("RESULT demo recording="), "{stdout}");
    for (method, line) in ["flame", "spark", "uniform"].iter().zip(&tail[1..]) {
        assert!(
            line.starts_with(&format!("RESULT demo method={method} ")),
            "{stdout}"
        );
        let r = result_line(&stdout, &format!("method={method} "));
        assert_eq!(r["episodes"], "3");
        let solved: usize = r["solved"].parse().unwrap();
        assert!(solved >= 2, "{method}: {solved} of 3 solved");
        let median: f64 = r["median_ms"].parse().unwrap();
        let mean: f64 = r["mean_ms"].parse().unwrap();
        assert!(median > 0.0 && mean > 0.0, "{method}: {median} {mean}");
        let retrieval: f64 = r["retrieval_us"].parse().unwrap();
        assert!(retrieval.is_finite() && retrieval >= 0.0);
        // No returned path touches the true world at the planner's resolution, the box only
        // the camera sees included.
        assert_eq!(r["unsafe"], "0", "{method}: {stdout}");
        assert!(r.contains_key("grazes") && r.contains_key("unseen_obstacles"));
        // Every solved plan came back timed, and the robot takes seconds, not ms, to run it.
        assert_eq!(r["timed"], r["solved"], "{method}");
        let executes: f64 = r["median_duration_s"].parse().unwrap();
        assert!(
            executes > 0.5 && executes < 60.0,
            "{method}: runs {executes} s"
        );
    }
    // One place episode (after the first pick): the can held through the daemon, put down
    // without touching the shelf.
    for method in ["flame", "spark", "uniform"] {
        let r = named_result_line(&stdout, "demo_place", &format!("method={method} "));
        assert_eq!(
            (r["episodes"].as_str(), r["solved"].as_str()),
            ("1", "1"),
            "{method}"
        );
        assert_eq!(r["unsafe"], "0", "{method}: {stdout}");
        assert_eq!(r["timed"], r["solved"], "{method}");
    }
    let files = result_line(&stdout, "recording=");
    assert_eq!(PathBuf::from(&files["database"]), db);

    // The database learned from the uniform plans only (one per solved episode at most).
    let (exp, aside) = Experience::load_dir(&db, &Default::default(), 0.02).unwrap();
    assert!(aside.is_empty(), "{aside:?}");
    assert!(exp.spark.len() + exp.flame.len() > 0, "nothing learned");

    // The recording holds the sensors' stream and every plan, flags included.
    let recording = PathBuf::from(&files["recording"]);
    assert!(recording.starts_with(&record), "{}", recording.display());
    let session = Session::open(&recording).unwrap();
    let (mut clouds, mut objects, mut joints, mut requests, mut no_learn) = (0, 0, 0, 0, 0);
    let (mut attaches, mut detaches) = (0, 0);
    let (mut solved, mut trajectories) = (0, 0);
    session
        .for_each(
            false,
            &TopicMap::default(),
            |_, e| -> Result<(), SessionError> {
                match e {
                    Event::Cloud { points, .. } => {
                        assert!(!points.is_empty());
                        clouds += 1;
                    }
                    Event::Object(u) => {
                        objects += 1;
                        let tracked = u.shape == ember_sdk::wire::ShapeKind::Tracked as u32;
                        match (u.link[0] != 0, tracked) {
                            (true, _) => attaches += 1,
                            (false, true) => detaches += 1,
                            _ => {}
                        }
                    }
                    Event::Joints { .. } => joints += 1,
                    Event::PlanRequest(r) => {
                        requests += 1;
                        no_learn += (r.request.flags & FLAG_NO_LEARN != 0) as usize;
                    }
                    Event::PlanResponse(r) => solved += (r.status == 0) as usize,
                    Event::PlanTrajectory(t) => {
                        assert!(t.points.len() >= 2);
                        trajectories += 1;
                    }
                }
                Ok(())
            },
        )
        .unwrap();
    // A placement whose ends the daemon refused was asked of the first method alone, then
    // put down and drawn again.
    let refused: usize = named_result_line(&stdout, "demo_place", "method=uniform ")
        ["placements_refused"]
        .parse()
        .unwrap();
    assert_eq!(
        (requests, no_learn),
        (12 + refused, 8 + refused),
        "(3 picks + 1 place) × 3 methods, 2 not learned; {refused} refused placements"
    );
    assert_eq!((attaches, detaches), (1 + refused, 1 + refused));
    assert!(
        clouds >= 3 && joints > 0 && objects >= 10,
        "{clouds} clouds, {joints} joint states, {objects} object updates"
    );
    assert_eq!(
        trajectories, solved,
        "every solved plan is timed and recorded"
    );

    // The session replays into a fresh daemon with every plan reproduced bit for bit (the
    // replay feeds the sensor stream without losing a cloud, and the flags keep the learning
    // as it was).
    let fresh = crate::daemon::Daemon::start("demo-replay");
    let _client = fresh.client();
    crate::daemon::replay_check(&recording, &fresh, 12 + refused);
    let _ = std::fs::remove_dir_all(dir);
}

/// `ember demo`: by default the daemon certifies every returned path between its states, so
/// none grazes the true world even between the demo's finer states; the same three picks at
/// seed 3 with `--no-certify` (the states alone) graze it.
#[test]
fn certified_demo_paths_graze_nothing() {
    let dir = std::env::temp_dir().join(format!("ember-demo-cert-{}", std::process::id()));
    let run = |certify: bool| {
        let _ = std::fs::remove_dir_all(&dir);
        let instance = format!("it-demo-cert-{}-{certify}", std::process::id());
        let db = dir.join("db");
        let mut args = vec![
            "demo",
            "--episodes",
            "3",
            "--seed",
            "3",
            "--instance",
            &instance,
        ];
        args.extend(["--no-record", "--db", db.to_str().unwrap()]);
        if !certify {
            args.push("--no-certify");
        }
        let out = crate::ember(&args);
        let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
        assert!(
            out.status.success(),
            "{stdout}{}",
            String::from_utf8_lossy(&out.stderr)
        );
        stdout
    };
    let certified = run(true);
    let plain = run(false);
    let mut plain_grazes = 0;
    for method in ["flame", "spark", "uniform"] {
        for kind in ["demo", "demo_place"] {
            let r = named_result_line(&certified, kind, &format!("method={method} "));
            let solved: usize = r["solved"].parse().unwrap();
            assert!(solved >= 1, "{kind} {method}: none solved");
            assert_eq!(
                (r["unsafe"].as_str(), r["grazes"].as_str()),
                ("0", "0"),
                "{kind} {method}: {certified}"
            );
            let r = named_result_line(&plain, kind, &format!("method={method} "));
            assert_eq!(r["unsafe"], "0", "{kind} {method}: {plain}");
            plain_grazes += r["grazes"].parse::<usize>().unwrap();
        }
    }
    assert!(
        plain_grazes > 0,
        "uncertified paths grazed nothing: {plain}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

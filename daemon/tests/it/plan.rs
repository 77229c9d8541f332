//! `ember plan` on MoveIt YAML files, good and bad.

use crate::{ember, fixtures};

fn fixture(name: &str) -> String {
    fixtures().join("moveit").join(name).display().to_string()
}

#[test]
fn plan_prints_a_solved_path() {
    let out = ember(&[
        "plan",
        "--scene",
        &fixture("scene.yaml"),
        "--request",
        &fixture("request_joint.yaml"),
        "--json",
    ]);
    let v = crate::json_output(&out);
    assert_eq!(v["status"], "solved");
    let path = v["path"].as_array().unwrap();
    assert_eq!(path.last().unwrap().as_array().unwrap().len(), 8);
    assert_eq!(path[0][0].as_f64(), Some(0.1));
}

/// `ember plan --json --no-trajectory` on the fixtures' table scene and joint goal, with `extra`.
fn plan_joint_goal(extra: &[&str]) -> std::process::Output {
    let mut args = vec!["plan", "--json", "--no-trajectory"];
    let (scene, request) = (fixture("scene.yaml"), fixture("request_joint.yaml"));
    args.extend(["--scene", &scene, "--request", &request]);
    args.extend(extra);
    ember(&args)
}

/// `--max-iterations` ends the search there, as the time limit would: the fixture's search
/// takes more than one iteration, so a cap of one leaves it unsolved, reported as a timeout.
#[test]
fn plan_stops_at_its_iteration_cap() {
    let free = crate::json_output(&plan_joint_goal(&[]));
    assert_eq!(free["status"], "solved");
    assert!(free["stats"]["iterations"].as_u64().unwrap() > 1, "{free}");
    let out = plan_joint_goal(&["--max-iterations", "1"]);
    assert_eq!(out.status.code(), Some(1));
    let capped: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON object");
    assert_eq!(capped["status"], "timeout", "{capped}");
}

/// `ember plan` certifies the returned path between its states unless told not to; a path
/// that grazes nothing comes back the same either way.
#[test]
fn plan_certifies_unless_told_not_to() {
    let run = |extra: &[&str]| crate::json_output(&plan_joint_goal(extra));
    let (certified, plain) = (run(&[]), run(&["--no-certify"]));
    assert_eq!(
        (&certified["status"], &plain["status"]),
        (&"solved".into(), &"solved".into())
    );
    assert_eq!(certified["certified"], true);
    assert_eq!(plain["certified"], false);
    assert!(certified["stats"]["uncertified"].is_u64(), "{certified}");
    assert_eq!(certified["path"], plain["path"]);
}

#[test]
fn plan_prints_and_exports_the_timed_trajectory() {
    let dir = std::env::temp_dir().join(format!("ember-traj-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let yaml = dir.join("trajectory.yaml");
    let out = ember(&[
        "plan",
        "--scene",
        &fixture("scene.yaml"),
        "--request",
        &fixture("request_joint.yaml"),
        "--json",
        "--velocity-scaling",
        "0.5",
        "--trajectory-out",
        yaml.to_str().unwrap(),
    ]);
    let v = crate::json_output(&out);
    let t = &v["trajectory"];
    let duration = t["duration_s"].as_f64().unwrap();
    let times = t["times"].as_array().unwrap();
    assert!(duration > 0.0 && times.len() >= 2, "{t}");
    assert_eq!(times.last().unwrap().as_f64(), Some(duration));
    assert_eq!(t["positions"][0], v["path"][0], "starts at the start");
    assert_eq!(
        t["waypoint_times"].as_array().unwrap().len(),
        v["path"].as_array().unwrap().len()
    );
    // The MoveIt export: every sample with its time, velocities and accelerations.
    let text = std::fs::read_to_string(&yaml).unwrap();
    let doc: serde_yaml_ng::Value = serde_yaml_ng::from_str(&text).unwrap();
    let points = doc["joint_trajectory"]["points"].as_sequence().unwrap();
    assert_eq!(points.len(), times.len());
    let last = &points[points.len() - 1];
    let secs = last["time_from_start"]["sec"].as_f64().unwrap()
        + last["time_from_start"]["nanosec"].as_f64().unwrap() * 1e-9;
    assert!((secs - duration).abs() < 1e-6);
    assert_eq!(last["velocities"].as_sequence().unwrap().len(), 8);
    assert_eq!(last["accelerations"].as_sequence().unwrap().len(), 8);
    // Half the velocity limits: slower than at full speed.
    let full = crate::json_output(&ember(&[
        "plan",
        "--scene",
        &fixture("scene.yaml"),
        "--request",
        &fixture("request_joint.yaml"),
        "--json",
    ]));
    assert!(full["trajectory"]["duration_s"].as_f64().unwrap() < duration);
    let bad = ember(&[
        "plan",
        "--scene",
        &fixture("scene.yaml"),
        "--request",
        &fixture("request_joint.yaml"),
        "--acceleration-scaling",
        "2",
    ]);
    let text = String::from_utf8_lossy(&bad.stdout);
    assert!(
        text.contains("acceleration scaling factor 2 is outside (0, 1]"),
        "{text}"
    );
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn pose_request_is_planned() {
    let out = ember(&[
        "plan",
        "--scene",
        &fixture("scene.yaml"),
        "--request",
        &fixture("request_pose.yaml"),
    ]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success() && text.starts_with("status: solved"),
        "{text}"
    );
}

#[test]
fn missing_file_is_named() {
    let out = ember(&[
        "plan",
        "--scene",
        "/nonexistent/scene.yaml",
        "--request",
        &fixture("request_joint.yaml"),
    ]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("/nonexistent/scene.yaml"), "{err}");
}

#[test]
fn bad_field_is_named() {
    let dir = std::env::temp_dir().join(format!("ember-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let bad = dir.join("bad_request.yaml");
    let text = std::fs::read_to_string(fixture("request_joint.yaml"))
        .unwrap()
        .replace("position: 0.3,", "position: high,");
    std::fs::write(&bad, text).unwrap();
    let out = ember(&[
        "plan",
        "--scene",
        &fixture("scene.yaml"),
        "--request",
        bad.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("bad_request.yaml")
            && err.contains("goal_constraints[0].joint_constraints[0].position"),
        "{err}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn planning_failure_has_its_status_and_exit_code() {
    let dir = std::env::temp_dir().join(format!("ember-cli-fail-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let req = dir.join("request.yaml");
    // Goal with the arm straight through the table.
    let mut text = std::fs::read_to_string(fixture("request_joint.yaml")).unwrap();
    for (j, v) in [
        ("torso_lift_joint", "0.0"),
        ("shoulder_pan_joint", "0.0"),
        ("shoulder_lift_joint", "0.1"),
        ("elbow_flex_joint", "0.0"),
    ] {
        let start = text.find(&format!("joint_name: {j}, position: ")).unwrap()
            + format!("joint_name: {j}, position: ").len();
        let end = start + text[start..].find(',').unwrap();
        text.replace_range(start..end, v);
    }
    std::fs::write(&req, text).unwrap();
    let out = ember(&[
        "plan",
        "--scene",
        &fixture("scene.yaml"),
        "--request",
        req.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(1));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.starts_with("status: goal_in_collision"), "{stdout}");
    std::fs::remove_dir_all(&dir).ok();
}

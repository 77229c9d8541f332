//! Robots from files through the command line: `ember robot check`, planning with a URDF and an
//! SRDF, and the daemon refusing a broken description.

include!("../../../tests/fixtures/testbot.rs");

use crate::ember;

#[test]
fn robot_check_reports_the_model_draws_it_and_writes_an_srdf() {
    let bot = testbot::write("check");
    let picture = bot.dir.join("robot.png");
    let srdf = bot.dir.join("computed.srdf");
    let out = ember(&[
        "robot",
        "check",
        bot.urdf.to_str().unwrap(),
        "--srdf",
        bot.srdf.to_str().unwrap(),
        "--package-path",
        bot.packages.to_str().unwrap(),
        "--picture",
        picture.to_str().unwrap(),
        "--state",
        "bent",
        "--write-srdf",
        srdf.to_str().unwrap(),
        "--samples",
        "2000",
    ]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for expected in [
        "group arm (3 joints), tip tool",
        "camera_joint",
        "named state bent: free",
        "link2_mm.stl",
        "tool.dae",
        "ghost_link",
        "100.00%",
    ] {
        assert!(text.contains(expected), "no '{expected}' in:\n{text}");
    }
    assert!(std::fs::metadata(&picture).unwrap().len() > 1000);
    let written = std::fs::read_to_string(&srdf).unwrap();
    assert!(
        written.contains(
            "<disable_collisions link1=\"base_link\" link2=\"link1\" reason=\"Adjacent\""
        ),
        "{written}"
    );
    assert!(
        written.contains("<group_state name=\"bent\" group=\"arm\">"),
        "{written}"
    );
    std::fs::remove_dir_all(&bot.packages).ok();
}

#[test]
fn plan_takes_a_urdf_and_an_srdf() {
    let bot = testbot::write("plan");
    let scene = bot.dir.join("scene.yaml");
    std::fs::write(
        &scene,
        "name: post\nobjects:\n  - name: post\n    shape: {type: box, size: [0.05, 0.05, 0.2]}\n    position: [0.07, 0.0, 0.9]\n    orientation: [0, 0, 0, 1]\n",
    )
    .unwrap();
    let request = bot.dir.join("request.yaml");
    std::fs::write(
        &request,
        "group_name: arm\nstart_state:\n  joint_state:\n    name: [joint1, joint2, joint3, camera_joint]\n    position: [-1.2, -0.8, 0.6, 0.5]\ngoal_constraints:\n  - joint_constraints:\n      - {joint_name: joint1, position: 0.0}\n      - {joint_name: joint2, position: 0.0}\n      - {joint_name: joint3, position: 0.0}\n",
    )
    .unwrap();
    let args = |extra: &[&str]| {
        let mut a = vec![
            "plan",
            "--scene",
            scene.to_str().unwrap(),
            "--request",
            request.to_str().unwrap(),
            "--robot",
            bot.urdf.to_str().unwrap(),
            "--srdf",
            bot.srdf.to_str().unwrap(),
            "--package-path",
            bot.packages.to_str().unwrap(),
            "--json",
        ];
        a.extend_from_slice(extra);
        ember(&a)
    };
    let v = crate::json_output(&args(&[]));
    assert_eq!(v["status"], "solved");
    // An unknown group is refused (exit 2) naming it and the SRDF's groups.
    let out = args(&["--group", "legs"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        out.status.code() == Some(2) && err.contains("'legs'") && err.contains("arm"),
        "{err}"
    );
    std::fs::remove_dir_all(&bot.packages).ok();
}

#[test]
fn the_daemon_refuses_a_broken_robot_with_one_sentence() {
    let bot = testbot::write("daemon");
    let text = std::fs::read_to_string(&bot.urdf)
        .unwrap()
        .replace("meshes/tool.dae", "meshes/lost.dae");
    std::fs::write(&bot.urdf, text).unwrap();
    let cfg = bot.dir.join("emberd.toml");
    std::fs::write(
        &cfg,
        format!(
            "robot = {:?}\nsrdf = {:?}\npackage_path = [{:?}]\n",
            bot.urdf.display().to_string(),
            bot.srdf.display().to_string(),
            bot.packages.display().to_string()
        ),
    )
    .unwrap();
    let out = ember(&[
        "run",
        "--instance",
        "broken-robot",
        "--config",
        cfg.to_str().unwrap(),
        "--no-record",
        "--no-monitor",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("lost.dae") && err.contains("link 'tool'"),
        "{err}"
    );
    assert!(!err.contains("panicked"), "{err}");
    std::fs::remove_dir_all(&bot.packages).ok();
}

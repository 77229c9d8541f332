//! `ember-bench plan --paths-out` then `ember-bench paths`, run as a user runs them on the
//! fixtures' table problems: the planner's own paths are clear, and a hand-made path by way
//! of the arm straight down through the table is counted as touching between its free ends.

mod common;

use common::key;

#[test]
fn planned_paths_are_clear_and_a_path_through_the_table_touches() {
    let dir = common::problem_folder("paths_check");
    let paths = dir.join("paths.jsonl");
    common::ember_bench([
        "plan".as_ref(),
        "--time-limit".as_ref(),
        "5".as_ref(),
        "--paths-out".as_ref(),
        paths.as_os_str(),
        "--problems".as_ref(),
        dir.as_os_str(),
    ]);
    let planned = std::fs::read_to_string(&paths).expect("paths written");
    assert_eq!(planned.lines().count(), 2, "{planned}");
    // Problem 3 again, by way of the arm straight down through the table.
    let first: serde_json::Value = serde_json::from_str(planned.lines().next().unwrap()).unwrap();
    assert_eq!(first["index"], 3, "{first}");
    let set = first["set"].clone();
    let joints = first["joints"].clone();
    let path = first["path"].as_array().unwrap();
    let through = serde_json::json!([0.0, 0.0, 0.1, 0.0, 0.0, 0.0, 0.0, 0.0]);
    let bad = serde_json::json!({
        "set": set, "index": 3, "joints": joints,
        "path": [path[0].clone(), through, path[path.len() - 1].clone()],
    });
    let handmade = dir.join("through.jsonl");
    std::fs::write(&handmade, format!("{bad}\n")).unwrap();
    let out = common::ember_bench([
        "paths".as_ref(),
        "--problems".as_ref(),
        dir.as_os_str(),
        "--paths".as_ref(),
        paths.as_os_str(),
        handmade.as_os_str(),
    ]);
    let results: Vec<&str> = out
        .lines()
        .filter(|l| l.starts_with("RESULT paths "))
        .collect();
    assert_eq!(results.len(), 2, "{out}");
    assert_eq!(key(results[0], "paths"), "2", "{out}");
    assert_eq!(key(results[0], "touching"), "0", "{out}");
    assert_eq!(key(results[1], "touching"), "1", "{out}");
    assert_eq!(key(results[1], "between"), "1", "{out}");
    let touch = out
        .lines()
        .find(|l| l.starts_with("TOUCH "))
        .expect("a TOUCH line");
    assert_eq!(key(touch, "file"), "through.jsonl", "{touch}");
    assert_eq!(key(touch, "at"), "between", "{touch}");
}

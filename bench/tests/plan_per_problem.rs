//! `ember-bench plan --per-problem` run as a user runs it, on a folder of two hand-written
//! MoveIt problems (the fixtures' table scene with a joint goal and with a pose goal): one
//! `PROBLEM` line per problem, in the folder's numbering, and the set's `RESULT plan` line
//! agreeing with them.

mod common;

/// `ember-bench plan --per-problem` on the two fixture problems, in a folder named `set`.
fn per_problem(set: &str) -> String {
    let dir = common::problem_folder(set);
    common::ember_bench([
        "plan".as_ref(),
        "--per-problem".as_ref(),
        "--time-limit".as_ref(),
        "5".as_ref(),
        "--problems".as_ref(),
        dir.as_os_str(),
    ])
}

#[test]
fn per_problem_lines_name_each_problem_and_agree_with_the_result_line() {
    let stdout = per_problem("plan_per_problem");
    let problems: Vec<&str> = stdout
        .lines()
        .filter(|l| l.starts_with("PROBLEM "))
        .collect();
    assert_eq!(problems.len(), 2, "{stdout}");
    use common::key;
    assert_eq!(key(problems[0], "index"), "3");
    assert_eq!(key(problems[1], "index"), "8");
    let solved = problems
        .iter()
        .filter(|l| key(l, "solved") == "1")
        .inspect(|l| {
            let ms: f64 = key(l, "ms").parse().expect("ms");
            let total: f64 = key(l, "total_ms").parse().expect("total_ms");
            assert!(ms > 0.0 && total >= ms, "{l}");
            key(l, "iterations").parse::<u64>().expect("iterations");
            key(l, "exact_fallbacks")
                .parse::<u64>()
                .expect("exact_fallbacks");
        })
        .count();
    let result = stdout
        .lines()
        .find(|l| l.starts_with("RESULT plan "))
        .expect("a RESULT plan line");
    assert_eq!(key(result, "n"), "2", "{result}");
    assert_eq!(key(result, "solved"), solved.to_string(), "{result}");
    assert_eq!(solved, 2, "{stdout}");
    // The solved problems' planning times, summed (each printed to a microsecond).
    let summed: f64 = problems
        .iter()
        .map(|l| key(l, "ms").parse::<f64>().expect("ms"))
        .sum();
    let sum: f64 = key(result, "solved_sum_ms").parse().expect("solved_sum_ms");
    assert!(
        (sum - summed).abs() < 0.002,
        "{sum} against {summed}: {result}"
    );
    assert!(
        stdout
            .lines()
            .last()
            .is_some_and(|l| l.starts_with("RESULT ")),
        "the RESULT lines end the output:\n{stdout}"
    );
}

/// `per_problem_vs_vamp.py --truth` joins real `--per-problem` output with VAMP's lines and an
/// `fcl_validity.py` CSV: problem 3's start and goal free on the meshes, problem 8's goal in
/// contact; VAMP solved both (hand-written lines), Ember solves both here.
#[test]
fn solved_problems_are_counted_against_the_ground_truth() {
    let stdout = per_problem("fetch_truth_fetch");
    let scratch = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"));
    let (ember, vamp, truth) = (
        scratch.join("truth_ember.txt"),
        scratch.join("truth_vamp.txt"),
        scratch.join("truth.csv"),
    );
    std::fs::write(&ember, &stdout).expect("ember.txt");
    std::fs::write(
        &vamp,
        "PROBLEM set=fetch_truth index=3 solved=1 iterations=10 tree_nodes=4 us=100.0\n\
         PROBLEM set=fetch_truth index=8 solved=1 iterations=20 tree_nodes=6 us=300.0\n",
    )
    .expect("vamp.txt");
    std::fs::write(
        &truth,
        "set,index,start_free,goal_free,start_contact,goal_contact\n\
         fetch_truth_fetch,3,1,1,,\n\
         fetch_truth_fetch,8,1,0,,self:head_pan_link|upperarm_roll_link\n",
    )
    .expect("truth.csv");
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/per_problem_vs_vamp.py");
    let out = std::process::Command::new("python3")
        .arg(script)
        .args([&ember, &vamp])
        .arg("--truth")
        .arg(&truth)
        .output()
        .expect("python3 runs");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{text}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let line = text
        .lines()
        .find(|l| l.starts_with("RESULT solved_vs_truth "))
        .unwrap_or_else(|| panic!("no solved_vs_truth line:\n{text}"));
    use common::key;
    assert_eq!(key(line, "set"), "fetch_truth", "{line}");
    assert_eq!(key(line, "truth_valid"), "1", "{line}");
    assert_eq!(key(line, "vamp_solved_valid"), "1", "{line}");
    assert_eq!(key(line, "vamp_solved_invalid"), "1", "{line}");
    assert_eq!(key(line, "ember_solved_valid"), "1", "{line}");
    assert_eq!(key(line, "ember_solved_invalid"), "1", "{line}");
}

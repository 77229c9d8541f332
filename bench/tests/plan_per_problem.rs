//! `ember-bench plan --per-problem` run as a user runs it, on a folder of two hand-written
//! MoveIt problems (the fixtures' table scene with a joint goal and with a pose goal): one
//! `PROBLEM` line per problem, in the folder's numbering, and the set's `RESULT plan` line
//! agreeing with them.

mod common;

#[test]
fn per_problem_lines_name_each_problem_and_agree_with_the_result_line() {
    let dir = common::problem_folder("plan_per_problem");
    let dir_arg = dir.as_os_str().to_owned();
    let stdout = common::ember_bench([
        "plan".as_ref(),
        "--per-problem".as_ref(),
        "--time-limit".as_ref(),
        "5".as_ref(),
        "--problems".as_ref(),
        dir_arg.as_os_str(),
    ]);
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

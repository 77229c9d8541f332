//! `ember-bench trajectory --no-peer --export FILE` run as a user runs it. The file is left in
//! cargo's test tmpdir (`ci-trajectories.json`), where CI hands it to TOPP-RA's reference
//! implementation (`tests/python/compare_toppra.py`); here each exported trajectory is checked
//! on its own: it starts at rest and can stop at its end, keeps its velocity limits, and its samples cover
//! its duration.

mod common;

#[test]
fn exported_trajectories_start_and_end_at_rest_within_their_velocity_limits() {
    let file = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("ci-trajectories.json");
    let stdout = common::ember_bench([
        "trajectory".as_ref(),
        "--no-peer".as_ref(),
        "--export".as_ref(),
        file.as_os_str(),
    ]);
    assert!(stdout.contains("RESULT trajectory "), "{stdout}");
    let doc: serde_json::Value =
        serde_json::from_slice(&std::fs::read(&file).expect("exported")).expect("JSON");
    let paths = doc.as_array().expect("an array of paths");
    assert!(paths.len() >= 10, "{} paths", paths.len());
    let floats = |v: &serde_json::Value| -> Vec<f64> {
        v.as_array()
            .expect("array")
            .iter()
            .map(|x| x.as_f64().expect("number"))
            .collect()
    };
    for (i, p) in paths.iter().enumerate() {
        let limits = floats(&p["velocity"]);
        let duration = p["duration"].as_f64().expect("duration");
        let times = floats(&p["times"]);
        let velocities: Vec<Vec<f64>> = p["velocities"]
            .as_array()
            .expect("velocities")
            .iter()
            .map(floats)
            .collect();
        assert!(duration > 0.0, "path {i}: duration {duration}");
        assert_eq!(times.len(), velocities.len(), "path {i}");
        assert!(
            times.last().is_some_and(|&t| duration - t < 0.0100001),
            "path {i}: samples end at {:?} of {duration}",
            times.last()
        );
        for (t, v) in times.iter().zip(&velocities) {
            assert_eq!(v.len(), limits.len(), "path {i}");
            for (j, (x, l)) in v.iter().zip(&limits).enumerate() {
                assert!(
                    x.abs() <= l * (1.0 + 1e-6),
                    "path {i} joint {j} at {t} s: {x} past {l}"
                );
            }
        }
        assert!(
            velocities[0].iter().all(|x| x.abs() < 1e-9),
            "path {i}: does not start at rest"
        );
        // The last sample is at most 10 ms before the end: slow enough to stop by then.
        let (last, v) = (times[times.len() - 1], &velocities[velocities.len() - 1]);
        let accelerations = floats(&p["acceleration"]);
        for (j, (x, a)) in v.iter().zip(&accelerations).enumerate() {
            assert!(
                x.abs() <= a * 1.005 * (duration - last) + 1e-9,
                "path {i} joint {j}: {x} rad/s {} s before the end",
                duration - last
            );
        }
    }
}

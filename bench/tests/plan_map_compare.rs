//! `ember-bench plan --clouds DIR --map-compare` on the fixtures' table problems with a cloud
//! of the table's top: the `RESULT plan_map` line carries the three runs (objects alone,
//! objects and the map, the map alone), and its ratios are the runs' figures divided.

mod common;

use common::key;

#[test]
fn map_compare_reports_the_map_alone_beside_the_objects() {
    let dir = common::problem_folder("plan_map_compare");
    // The table's top (0.8 × 1.2 m at x 1.1, top face at z 0.72) every 2 cm, for both
    // problems.
    let clouds = dir
        .parent()
        .expect("scratch")
        .join("plan_map_compare_clouds");
    let set = clouds.join("plan_map_compare");
    std::fs::create_dir_all(&set).expect("cloud folder");
    let mut points = Vec::new();
    for i in 0..=40 {
        for j in 0..=60 {
            points.push(format!(
                "{:.3} {:.3} 0.719",
                0.7 + 0.02 * f64::from(i),
                -0.6 + 0.02 * f64::from(j)
            ));
        }
    }
    let pcd = format!(
        "VERSION .7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH {n}\nHEIGHT 1\n\
         POINTS {n}\nDATA ascii\n{}\n",
        points.join("\n"),
        n = points.len()
    );
    for n in [3, 8] {
        std::fs::write(set.join(format!("cloud{n:04}.pcd")), &pcd).expect("cloud");
    }
    let stdout = common::ember_bench([
        "plan".as_ref(),
        "--no-simplify".as_ref(),
        "--time-limit".as_ref(),
        "5".as_ref(),
        "--problems".as_ref(),
        dir.as_os_str(),
        "--clouds".as_ref(),
        clouds.as_os_str(),
        "--map-compare".as_ref(),
    ]);
    let line = stdout
        .lines()
        .find(|l| l.starts_with("RESULT plan_map "))
        .unwrap_or_else(|| panic!("no RESULT plan_map line:\n{stdout}"));
    let num = |k: &str| -> f64 { key(line, k).parse().expect(k) };
    assert_eq!(num("n"), 2.0, "{line}");
    for k in ["solved_off", "solved_on", "solved_voxels"] {
        assert_eq!(num(k), 2.0, "{k}: {line}");
    }
    // Checks are timed on every 32nd iteration: these short searches may time none (the
    // ratio's denominator is then kept above zero, and the ratio is zero or huge).
    let (off, voxels) = (
        num("off_check_ns_per_config"),
        num("voxels_check_ns_per_config"),
    );
    let ratio = num("voxels_check_ratio");
    let want = voxels / off.max(1e-9);
    assert!(
        off >= 0.0 && voxels >= 0.0 && (ratio - want).abs() <= 0.002 * want + 0.01,
        "{ratio} against {voxels} / {off}: {line}"
    );
    assert!(num("voxels_median_ms") > 0.0 && num("voxels_median_iterations") >= 0.0);
}

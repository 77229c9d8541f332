//! Forward kinematics against independently computed link poses.

use ember_engine::robot::Robot;
use nalgebra::{Quaternion, UnitQuaternion};
use std::path::PathBuf;

struct Check {
    robot: String,
    config: String,
    q: Vec<f64>,
    link: String,
    xyz: [f64; 3],
    xyzw: [f64; 4],
}

/// The reference table shipped beside the repository (`../shared/reference/robots/*/derived/
/// fk_checks.csv`, poses computed from the upstream URDFs and cross-checked with Pinocchio).
fn reference_checks(robot: &str) -> Option<Vec<Check>> {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../shared/reference/robots")
        .join(robot)
        .join("derived/fk_checks.csv");
    let text = std::fs::read_to_string(path).ok()?;
    let mut out = Vec::new();
    for line in text.lines().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        let num = |s: &str| s.trim().parse::<f64>().unwrap();
        out.push(Check {
            robot: f[0].into(),
            config: f[1].into(),
            q: f[2].split_whitespace().map(num).collect(),
            link: f[3].into(),
            xyz: [num(f[4]), num(f[5]), num(f[6])],
            xyzw: [num(f[7]), num(f[8]), num(f[9]), num(f[10])],
        });
    }
    Some(out)
}

/// A few poses of our own, so the test means something without the reference folder.
fn own_checks() -> Vec<Check> {
    let c = |robot: &str, q: &[f64], link: &str, xyz: [f64; 3], xyzw: [f64; 4]| Check {
        robot: robot.into(),
        config: "own".into(),
        q: q.to_vec(),
        link: link.into(),
        xyz,
        xyzw,
    };
    vec![
        // Fetch, all zero: the arm points straight ahead; link offsets add up along x.
        c(
            "fetch",
            &[0.0; 8],
            "gripper_link",
            [
                -0.086875 + 0.119525 + 0.117 + 0.219 + 0.133 + 0.197 + 0.1245 + 0.1385 + 0.16645,
                0.0,
                0.37743 + 0.34858 + 0.06,
            ],
            [0.0, 0.0, 0.0, 1.0],
        ),
        // Panda, all zero: the flange points down, 0.107 below link7's origin.
        c(
            "panda",
            &[0.0; 7],
            "panda_link8",
            [0.088, 0.0, 0.333 + 0.316 + 0.384 - 0.107],
            [1.0, 0.0, 0.0, 0.0],
        ),
    ]
}

fn assert_matches(check: &Check, robot: &Robot) {
    let poses = robot.link_poses(&check.q).unwrap();
    let link = robot
        .link_index(&check.link)
        .unwrap_or_else(|| panic!("no link {}", check.link));
    let p = &poses[link];
    let t = p.translation.vector;
    for i in 0..3 {
        assert!(
            (t[i] - check.xyz[i]).abs() < 1e-6,
            "{} {} {}: position {:?} vs {:?}",
            check.robot,
            check.config,
            check.link,
            t,
            check.xyz
        );
    }
    let [x, y, z, w] = check.xyzw;
    let expect = UnitQuaternion::from_quaternion(Quaternion::new(w, x, y, z));
    assert!(
        p.rotation.angle_to(&expect) < 2e-6,
        "{} {} {}: rotation {:?} vs {:?}",
        check.robot,
        check.config,
        check.link,
        p.rotation,
        expect
    );
}

#[test]
fn fk_matches_reference_poses() {
    for name in ["fetch", "panda"] {
        let sut = Robot::builtin(name).unwrap();
        let mut checks: Vec<Check> = own_checks()
            .into_iter()
            .filter(|c| c.robot == name)
            .collect();
        match reference_checks(name) {
            Some(r) => {
                assert!(r.len() >= 9);
                checks.extend(r);
            }
            None => eprintln!("reference table for {name} not found; checking our own poses only"),
        }
        for c in &checks {
            assert_matches(c, &sut);
        }
    }
}

#[test]
fn fk_rejects_bad_configurations() {
    let sut = Robot::builtin("fetch").unwrap();
    assert!(sut.link_poses(&[0.0; 7]).is_err());
    assert!(sut.link_poses(&[f64::INFINITY; 8]).is_err());
}

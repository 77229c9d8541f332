//! Fuzzing the text loaders a user's files go through: MoveIt scene and request YAML, our scene
//! YAML, URDF and SRDF. Inputs are valid files mutated at random (bytes flipped, inserted,
//! deleted, spans repeated, cut short) plus deeply nested brackets; every one must load or be
//! refused with an error, never panic. Cases per target: `EMBER_FUZZ_CASES` (default below),
//! seed `EMBER_FUZZ_SEED`; each target prints how many it tried. Found so far: a mesh in
//! millimetres without its scale exhausted memory (now refused, see `robot.rs`).

include!("../../../tests/fixtures/fuzzing.rs");

use crate::robot::testbot;
use ember_engine::robot::spheres::cache::SphereCache;
use ember_engine::robot::{Robot, RobotSpec};
use ember_engine::scene::moveit::{request_from_yaml, scene_from_yaml};
use ember_engine::scene::Scene;
use fuzzing::{cases, fuzz_text};
use std::time::Instant;

/// Brackets nested `depth` deep, as a YAML flow sequence.
fn nested(depth: usize) -> String {
    "[".repeat(depth) + &"]".repeat(depth)
}

fn read(name: &str) -> String {
    std::fs::read_to_string(crate::fixtures().join("moveit").join(name)).unwrap()
}

#[test]
fn fuzz_moveit_and_scene_yaml() {
    let robot = Robot::builtin("fetch").unwrap();
    let scene = read("scene.yaml");
    fuzz_text("moveit scene", &scene, cases(3000), |t| {
        let _ = scene_from_yaml(t, "fuzz");
    });
    for name in ["request_joint.yaml", "request_pose.yaml"] {
        fuzz_text(name, &read(name), cases(3000), |t| {
            let _ = request_from_yaml(t, "fuzz", &robot);
        });
    }
    let ours = scene_from_yaml(&scene, "fixture").unwrap().to_yaml();
    fuzz_text("scene yaml", &ours, cases(3000), |t| {
        let _ = Scene::from_yaml(t, "fuzz");
    });
}

#[test]
fn deeply_nested_yaml_is_refused_quickly() {
    let robot = Robot::builtin("fetch").unwrap();
    // 200 KB of brackets (took 37 s to refuse before the depth check).
    let text = nested(100_000);
    let t = Instant::now();
    assert!(scene_from_yaml(&text, "deep").is_err());
    assert!(request_from_yaml(&text, "deep", &robot).is_err());
    assert!(Scene::from_yaml(&text, "deep").is_err());
    eprintln!("200 KB of nested brackets refused in {:.1?}", t.elapsed());
}

#[test]
fn fuzz_urdf_and_srdf() {
    let bot = testbot::write("fuzz");
    let urdf = std::fs::read_to_string(&bot.urdf).unwrap();
    let srdf = std::fs::read_to_string(&bot.srdf).unwrap();
    let (urdf_path, srdf_path) = (bot.dir.join("fuzz.urdf"), bot.dir.join("fuzz.srdf"));
    let spec = RobotSpec {
        robot: urdf_path.display().to_string(),
        srdf: Some(srdf_path.clone()),
        package_paths: vec![bot.packages.clone()],
        sphere_cache: SphereCache::Dir(bot.packages.join("cache")),
        ..Default::default()
    };
    std::fs::write(&srdf_path, &srdf).unwrap();
    fuzz_text("urdf", &urdf, cases(300), |t| {
        std::fs::write(&urdf_path, t).unwrap();
        let _ = spec.load();
    });
    std::fs::write(&urdf_path, &urdf).unwrap();
    fuzz_text("srdf", &srdf, cases(300), |t| {
        std::fs::write(&srdf_path, t).unwrap();
        let _ = spec.load();
    });
}

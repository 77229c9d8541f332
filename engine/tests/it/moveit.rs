//! MoveIt YAML import and export.

use ember_engine::collision::Shape;
use ember_engine::planning::Goal;
use ember_engine::robot::Robot;
use ember_engine::scene::{moveit, AttachedObject, Scene, SceneError};
use ember_engine::world::Object;
use ember_engine::Pose;

fn read(name: &str) -> String {
    std::fs::read_to_string(crate::fixtures().join("moveit").join(name)).unwrap()
}

#[test]
fn hand_written_planning_scene_imports() {
    let sut = Scene::load(crate::fixtures().join("moveit/scene.yaml")).unwrap();
    assert_eq!(sut.name, "table_scene");
    let names: Vec<&str> = sut.objects.iter().map(|o| o.name.as_str()).collect();
    assert_eq!(names, ["table", "Can1", "crate"]);
    // MoveIt cylinders are [height, radius].
    assert_eq!(
        sut.objects[1].shape,
        Shape::Cylinder {
            radius: 0.035,
            half_length: 0.06
        }
    );
    assert!((sut.objects[1].pose.translation.vector.y - 0.1).abs() < 1e-12);
    // Object pose composed with the primitive pose: 5 cm up along the object's own z.
    let crate_pose = sut.objects[2].pose;
    assert!((crate_pose.translation.vector.z - 0.77).abs() < 1e-9);
    assert!((crate_pose.rotation.angle() - std::f64::consts::FRAC_PI_4).abs() < 1e-6);
}

#[test]
fn planning_scene_round_trips_through_export() {
    let robot = Robot::builtin("fetch").unwrap();
    let sut = Scene::load(crate::fixtures().join("moveit/scene.yaml")).unwrap();
    let text = moveit::scene_to_yaml(&sut, &robot, robot.named_state("tuck").unwrap());
    let again = moveit::scene_from_yaml(&text, "exported").unwrap();
    assert_eq!(sut.objects.len(), again.objects.len());
    for (a, b) in sut.objects.iter().zip(&again.objects) {
        assert_eq!(a.name, b.name);
        assert_eq!(a.shape, b.shape);
        assert!((a.pose.translation.vector - b.pose.translation.vector).norm() < 1e-12);
        assert!(a.pose.rotation.angle_to(&b.pose.rotation) < 1e-9);
    }
}

#[test]
fn attached_objects_round_trip_in_both_scene_formats_and_join_the_robot() {
    let robot = Robot::builtin("fetch").unwrap();
    let mut sut = Scene::load(crate::fixtures().join("moveit/scene.yaml")).unwrap();
    sut.attached.push(AttachedObject {
        link: "gripper_link".into(),
        object: Object {
            name: "held".into(),
            shape: Shape::Cylinder {
                radius: 0.035,
                half_length: 0.06,
            },
            pose: Pose::translation(0.1, 0.0, 0.0),
        },
    });
    let moveit_text = moveit::scene_to_yaml(&sut, &robot, robot.named_state("tuck").unwrap());
    assert!(moveit_text.contains("attached_collision_objects"));
    for again in [
        moveit::scene_from_yaml(&moveit_text, "exported").unwrap(),
        Scene::from_yaml(&sut.to_yaml(), "own").unwrap(),
    ] {
        assert_eq!(again.attached.len(), 1);
        let (a, b) = (&sut.attached[0], &again.attached[0]);
        assert_eq!((&a.link, &a.object.name), (&b.link, &b.object.name));
        assert_eq!(a.object.shape, b.object.shape);
        assert!(
            (a.object.pose.translation.vector - b.object.pose.translation.vector).norm() < 1e-12
        );
        assert_eq!(
            again.objects.len(),
            sut.objects.len(),
            "held objects are not obstacles"
        );
    }
    let holding = sut.robot(&robot).unwrap();
    assert_eq!(holding.links().len(), robot.links().len() + 1);
    sut.attached[0].link = "no_such_link".into();
    let err = sut.robot(&robot).unwrap_err().to_string();
    assert!(
        err.contains("attached[0].link") && err.contains("no_such_link"),
        "{err}"
    );
}

#[test]
fn joint_request_picks_the_group_joints() {
    let robot = Robot::builtin("fetch").unwrap();
    let sut = moveit::request_from_yaml(&read("request_joint.yaml"), "r.yaml", &robot).unwrap();
    assert_eq!(sut.start, robot.named_state("tuck").unwrap());
    assert_eq!(
        sut.goal,
        Goal::Joints(vec![vec![0.3, 0.2, -0.6, 0.0, 0.6, 0.0, 0.0, 0.0]])
    );
    assert_eq!(sut.allowed_planning_time, Some(60.0));
    // Written back out and read again, the request is unchanged.
    let Goal::Joints(goals) = &sut.goal else {
        unreachable!()
    };
    let text = moveit::request_to_yaml(&robot, &sut.start, &goals[0], 60.0);
    let again = moveit::request_from_yaml(&text, "again", &robot).unwrap();
    assert_eq!(again.start, sut.start);
    assert_eq!(again.goal, sut.goal);
    // A planning time no planner can honour is refused with the key named.
    for bad in ["1e308", "-5", "0", ".nan"] {
        let text = read("request_joint.yaml").replace(
            "allowed_planning_time: 60",
            &format!("allowed_planning_time: {bad}"),
        );
        let e = moveit::request_from_yaml(&text, "bad.yaml", &robot).unwrap_err();
        assert!(
            e.to_string().contains("allowed_planning_time"),
            "{bad}: {e}"
        );
    }
}

#[test]
fn pose_request_becomes_a_pose_goal() {
    let robot = Robot::builtin("fetch").unwrap();
    let sut = moveit::request_from_yaml(&read("request_pose.yaml"), "p.yaml", &robot).unwrap();
    let Goal::Pose(goal) = sut.goal else {
        panic!("expected a pose goal")
    };
    assert_eq!(goal.link.as_deref(), Some("wrist_roll_link"));
    assert_eq!(goal.position_tolerance, 0.005);
    assert_eq!(goal.orientation_tolerance, 0.02);
    assert!((goal.pose.translation.vector.x - 0.7).abs() < 1e-12);
}

#[test]
fn missing_group_joint_names_the_field() {
    let robot = Robot::builtin("fetch").unwrap();
    let text = read("request_joint.yaml").replacen("elbow_flex_joint", "elbow_joint", 1);
    let err = moveit::request_from_yaml(&text, "r.yaml", &robot).unwrap_err();
    let msg = err.to_string();
    assert!(
        msg.contains("r.yaml")
            && msg.contains("start_state.joint_state")
            && msg.contains("elbow_flex_joint"),
        "{msg}"
    );
}

#[test]
fn bad_cylinder_dimensions_name_the_field() {
    let text = read("scene.yaml").replace("dimensions: [0.12, 0.035]", "dimensions: [0.12]");
    let err = moveit::scene_from_yaml(&text, "s.yaml").unwrap_err();
    assert!(
        matches!(&err, SceneError::Field { field, .. } if field == "world.collision_objects[1].primitives[0].dimensions"),
        "{err}"
    );
}

#[test]
fn path_round_trips() {
    let robot = Robot::builtin("fetch").unwrap();
    let path = vec![
        robot.named_state("tuck").unwrap().to_vec(),
        vec![0.3, 0.2, -0.6, 0.0, 0.6, 0.0, 0.0, 0.0],
    ];
    let text = moveit::path_to_yaml(&robot, &path);
    assert_eq!(moveit::path_from_yaml(&text, "p", &robot).unwrap(), path);
}

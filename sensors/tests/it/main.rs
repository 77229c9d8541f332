//! Simulated depth camera tests, and the map built from its frames.

use ember_engine::collision::Shape;
use ember_engine::robot::spheres::PlacedSpheres;
use ember_engine::robot::Robot;
use ember_engine::world::map::{MapParams, Occupancy, OccupancyMap};
use ember_engine::world::{Environment, Object};
use ember_engine::Pose;
use ember_sensors::{look_at, CameraModel, DepthCamera, NoiseModel};

fn wall_env(x: f64) -> Environment {
    Environment::from_objects([Object {
        name: "wall".into(),
        shape: Shape::cuboid([0.1, 4.0, 4.0]),
        pose: Pose::translation(x + 0.05, 0.0, 1.0),
    }])
    .unwrap()
}

#[test]
fn camera_sees_a_wall_at_its_distance() {
    let env = wall_env(1.0);
    let mut sut = DepthCamera::new(CameraModel::default(), NoiseModel::none(), 1);
    let frame = sut.render(&env, &look_at([0.0, 0.0, 1.0], [1.0, 0.0, 1.0]));
    assert_eq!(frame.points.len(), 640 * 480, "the wall fills the view");
    // Optical frame: z forward; the wall is 1 m ahead, perpendicular to the view.
    assert!(frame.points.iter().all(|p| (p[2] - 1.0).abs() < 1e-5));
    let corner = frame.points[0];
    assert!(
        corner[0] < 0.0 && corner[1] < 0.0,
        "top-left pixel looks left and up: {corner:?}"
    );
}

#[test]
fn noise_and_dropout_follow_the_model() {
    let env = wall_env(2.0);
    let noise = NoiseModel {
        sigma_const: 0.0,
        sigma_quadratic: 0.005,
        dropout: 0.1,
    };
    let mut sut = DepthCamera::new(CameraModel::default(), noise, 2);
    let frame = sut.render(&env, &look_at([0.0, 0.0, 1.0], [1.0, 0.0, 1.0]));
    let n = frame.points.len() as f64;
    assert!(
        (n / (640.0 * 480.0) - 0.9).abs() < 0.01,
        "dropout share {}",
        1.0 - n / 307200.0
    );
    let mean = frame.points.iter().map(|p| p[2] as f64).sum::<f64>() / n;
    let var = frame
        .points
        .iter()
        .map(|p| (p[2] as f64 - mean).powi(2))
        .sum::<f64>()
        / n;
    assert!((mean - 2.0).abs() < 0.002, "{mean}");
    assert!(
        (var.sqrt() - 0.02).abs() < 0.002,
        "σ at 2 m should be 0.005·4 = 0.02, got {}",
        var.sqrt()
    );
}

#[test]
fn map_from_camera_frames_has_the_wall_and_free_space() {
    let env = wall_env(1.5);
    let mut camera = DepthCamera::new(CameraModel::default(), NoiseModel::none(), 3);
    let frame = camera.render(&env, &look_at([0.0, 0.0, 1.0], [1.0, 0.0, 1.0]));
    let mut sut = OccupancyMap::new(MapParams::default());
    sut.insert_cloud(&frame.points, &frame.sensor_pose, None);
    assert_eq!(sut.occupancy([1.51, 0.0, 1.0]), Occupancy::Occupied);
    assert_eq!(sut.occupancy([1.0, 0.1, 1.1]), Occupancy::Free);
    assert_eq!(sut.occupancy([1.7, 0.0, 1.0]), Occupancy::Unknown);
}

#[test]
fn self_filter_keeps_the_robot_out_of_the_map() {
    let robot = Robot::builtin("fetch").unwrap();
    let q = [0.2, 0.0, 0.3, 0.0, 0.0, 0.0, 0.0, 0.0]; // arm straight out, tilted down
    let mut objects = robot.collision_objects(&q).unwrap();
    objects.push(Object {
        name: "table".into(),
        shape: Shape::cuboid([1.0, 1.5, 0.04]),
        pose: Pose::translation(1.2, 0.0, 0.5),
    });
    let env = Environment::from_objects(objects).unwrap();
    let mut camera = DepthCamera::new(CameraModel::default(), NoiseModel::default(), 4);
    let head = [0.15, 0.0, 1.45];
    let frame = camera.render(&env, &look_at(head, [1.0, 0.0, 0.5]));
    let filter = PlacedSpheres::at(&robot, &q, 0.03);
    let mut unfiltered = OccupancyMap::new(MapParams::default());
    unfiltered.insert_cloud(&frame.points, &frame.sensor_pose, None);
    let mut sut = OccupancyMap::new(MapParams::default());
    let report = sut.insert_cloud(&frame.points, &frame.sensor_pose, Some(&filter));
    assert!(
        report.filtered > 1000,
        "the arm is in view: {} points filtered",
        report.filtered
    );
    let on_robot = |m: &OccupancyMap| m.occupied_voxels().filter(|c| filter.contains(*c)).count();
    assert!(on_robot(&unfiltered) > 50);
    assert_eq!(on_robot(&sut), 0);
    assert!(
        sut.occupied_voxels().any(|c| (c[2] - 0.52).abs() < 0.03),
        "the table stays"
    );
}

//! A sensed map of a scene: the simulated camera's views from a few viewpoints inserted into an
//! occupancy map, as MotionBenchMaker renders its sensed scenes (cameras at several heights above
//! the robot base, looking at the scene).

use crate::{look_at, CameraModel, DepthCamera, NoiseModel};
use ember_engine::world::map::{MapParams, OccupancyMap};
use ember_engine::world::Environment;

/// Camera heights above the robot base (metres), one view each.
pub const VIEW_HEIGHTS: [f64; 3] = [0.6, 1.0, 1.4];

/// Renders `env` from [`VIEW_HEIGHTS`] at the base origin, looking at `target`, with a
/// noise-free camera of `model`, into a new map with `params`.
pub fn sensed_map(
    env: &Environment,
    target: [f64; 3],
    model: &CameraModel,
    params: MapParams,
) -> OccupancyMap {
    let mut camera = DepthCamera::new(model.clone(), NoiseModel::none(), 0);
    let mut map = OccupancyMap::new(params);
    for h in VIEW_HEIGHTS {
        let frame = camera.render(env, &look_at([0.0, 0.0, h], target));
        map.insert_cloud(&frame.points, &frame.sensor_pose, None);
    }
    map
}

/// A 320×240 camera with the default camera's field of view (half the pixels per axis).
pub fn quarter_vga() -> CameraModel {
    CameraModel {
        width: 320,
        height: 240,
        fx: 275.0,
        fy: 275.0,
        cx: 160.0,
        cy: 120.0,
        ..CameraModel::default()
    }
}

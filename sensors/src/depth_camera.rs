//! A simulated depth camera: a pinhole model ray cast against the environment's objects.
//!
//! Frames are in the optical frame (z forward, x right, y down), as ROS depth cameras publish
//! them. Noise: depth gets Gaussian noise with σ = `sigma_const + sigma_quadratic · z²` (the
//! quadratic growth of structured-light and stereo sensors), and each pixel is dropped with
//! probability `dropout`. Pixels that see nothing within `max_range` give no point.

use ember_engine::world::Environment;
use ember_engine::Pose;
use nalgebra::{Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, StandardNormal};

/// Pinhole intrinsics and range limits.
#[derive(Debug, Clone, PartialEq)]
pub struct CameraModel {
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Focal length along x, pixels.
    pub fx: f64,
    /// Focal length along y, pixels.
    pub fy: f64,
    /// Principal point x, pixels.
    pub cx: f64,
    /// Principal point y, pixels.
    pub cy: f64,
    /// Nearest depth returned, metres.
    pub min_range: f64,
    /// Farthest depth returned, metres.
    pub max_range: f64,
}

impl Default for CameraModel {
    /// 640×480, fx = fy = 550, principal point at the centre, 0.01–10 m (MotionBenchMaker's camera).
    fn default() -> Self {
        CameraModel {
            width: 640,
            height: 480,
            fx: 550.0,
            fy: 550.0,
            cx: 320.0,
            cy: 240.0,
            min_range: 0.01,
            max_range: 10.0,
        }
    }
}

/// Depth noise and dropout.
#[derive(Debug, Clone, PartialEq)]
pub struct NoiseModel {
    /// Constant part of the depth standard deviation, metres.
    pub sigma_const: f64,
    /// Quadratic part: σ grows by this times depth², metres⁻¹.
    pub sigma_quadratic: f64,
    /// Probability that a pixel returns nothing.
    pub dropout: f64,
}

impl NoiseModel {
    /// No noise, no dropout.
    pub fn none() -> Self {
        NoiseModel {
            sigma_const: 0.0,
            sigma_quadratic: 0.0,
            dropout: 0.0,
        }
    }
}

impl Default for NoiseModel {
    fn default() -> Self {
        NoiseModel {
            sigma_const: 0.001,
            sigma_quadratic: 0.0015,
            dropout: 0.01,
        }
    }
}

/// One depth frame as a point cloud.
#[derive(Debug, Clone, PartialEq)]
pub struct DepthFrame {
    /// Points in the optical frame, metres.
    pub points: Vec<[f32; 3]>,
    /// Pose of the optical frame in the robot base frame.
    pub sensor_pose: Pose,
}

/// The pose of an optical frame at `eye` looking at `target` (base frame), image "up" towards +z.
pub fn look_at(eye: [f64; 3], target: [f64; 3]) -> Pose {
    let z = (Vector3::from(target) - Vector3::from(eye)).normalize();
    let up = if z.z.abs() > 0.99 {
        Vector3::x()
    } else {
        Vector3::z()
    };
    let x = z.cross(&up).normalize(); // image right
    let y = z.cross(&x); // image down
    let r = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[x, y, z]));
    Pose::from_parts(
        Translation3::from(Vector3::from(eye)),
        UnitQuaternion::from_rotation_matrix(&r),
    )
}

/// A simulated depth camera with its own seeded noise generator.
pub struct DepthCamera {
    /// Intrinsics.
    pub model: CameraModel,
    /// Noise.
    pub noise: NoiseModel,
    rng: rand_xoshiro::Xoshiro256PlusPlus,
    /// Unit ray directions per pixel in the optical frame (row-major).
    rays: Vec<[f64; 3]>,
}

impl DepthCamera {
    /// A camera; `seed` drives its noise.
    pub fn new(model: CameraModel, noise: NoiseModel, seed: u64) -> Self {
        let mut rays = Vec::with_capacity((model.width * model.height) as usize);
        for v in 0..model.height {
            for u in 0..model.width {
                let d = Vector3::new(
                    (u as f64 + 0.5 - model.cx) / model.fx,
                    (v as f64 + 0.5 - model.cy) / model.fy,
                    1.0,
                )
                .normalize();
                rays.push([d.x, d.y, d.z]);
            }
        }
        DepthCamera {
            model,
            noise,
            rng: rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(seed),
            rays,
        }
    }

    /// Renders what the camera at `pose` (optical frame, base frame) sees of `env`'s objects.
    pub fn render(&mut self, env: &Environment, pose: &Pose) -> DepthFrame {
        let r = pose.rotation.to_rotation_matrix();
        let o = pose.translation.vector;
        let origin = [o.x, o.y, o.z];
        let reach = self.model.max_range / self.rays.iter().map(|d| d[2]).fold(1.0, f64::min);
        let mut points = Vec::with_capacity(self.rays.len());
        for d in &self.rays {
            let w = r * Vector3::from(*d);
            let Some(t) = env.ray_cast(origin, [w.x, w.y, w.z], reach) else {
                continue;
            };
            let z = t * d[2];
            if z < self.model.min_range || z > self.model.max_range {
                continue;
            }
            if self.noise.dropout > 0.0 && self.rng.random::<f64>() < self.noise.dropout {
                continue;
            }
            let sigma = self.noise.sigma_const + self.noise.sigma_quadratic * z * z;
            let noisy = if sigma > 0.0 {
                let n: f64 = StandardNormal.sample(&mut self.rng);
                z + sigma * n
            } else {
                z
            };
            let s = noisy / d[2];
            points.push([(d[0] * s) as f32, (d[1] * s) as f32, (d[2] * s) as f32]);
        }
        DepthFrame {
            points,
            sensor_pose: *pose,
        }
    }
}

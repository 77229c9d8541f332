//! The cloud service: depth point clouds in the sensor frame with the sensor's pose, read in
//! place from shared memory.

use super::drops::Gaps;
use super::rejection::Rejection;
use ember_engine::scene::pose_from_xyz_xyzw;
use ember_engine::Pose;
use ember_sdk::services::{self, Limits, Open};
use ember_sdk::wire::{self, CloudHeader, Point};
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;
use iceoryx2::sample::Sample;

/// A received cloud that passed the checks; its points stay in shared memory.
pub struct CloudInput {
    sample: Sample<ipc::Service, [Point], CloudHeader>,
    /// The sensor pose in the robot base frame.
    pub pose: Pose,
}

impl CloudInput {
    /// The header as sent.
    pub fn header(&self) -> &CloudHeader {
        self.sample.user_header()
    }

    /// The points in the sensor frame, metres (no copy).
    pub fn points(&self) -> &[[f32; 3]] {
        Point::as_arrays(self.sample.payload())
    }
}

/// The clouds port.
pub struct CloudPort(Subscriber<ipc::Service, [Point], CloudHeader>);

impl CloudPort {
    /// Subscribes to the instance's clouds.
    pub fn open(node: &Node<ipc::Service>, instance: &str, limits: Limits) -> anyhow::Result<Self> {
        let sub = services::cloud(node, instance, Open::Serve(limits))
            .map_err(anyhow::Error::msg)?
            .subscriber_builder()
            .create()
            .map_err(|e| anyhow::anyhow!("cloud subscriber: {e:?}"))?;
        Ok(CloudPort(sub))
    }

    /// The next waiting cloud, checked (at most `max_points` points); None when none waits.
    /// `gaps` counts the clouds its publisher sent that never arrived.
    pub fn receive(
        &self,
        max_points: usize,
        gaps: &mut Gaps,
    ) -> Option<(u64, Result<CloudInput, Rejection>)> {
        let sample = self.0.receive().ok().flatten()?;
        let h = sample.user_header();
        let dropped = gaps.saw(sample.header().publisher_id().value(), h.seq);
        Some((
            dropped,
            decode(h, sample.payload().len(), max_points).map(|pose| CloudInput { sample, pose }),
        ))
    }
}

/// Checks a cloud's header against its payload of `points` points; gives the sensor pose.
pub fn decode(h: &CloudHeader, points: usize, max_points: usize) -> Result<Pose, Rejection> {
    Rejection::check_version("cloud", h.version)?;
    if points == 0 || h.point_count as usize != points {
        return Err(Rejection::PointCount {
            header: h.point_count,
            payload: points,
        });
    }
    if points > max_points {
        return Err(Rejection::TooManyPoints {
            found: points,
            limit: max_points,
        });
    }
    let p = h.sensor_pose;
    p.iter()
        .all(|v| v.is_finite())
        .then(|| pose_from_xyz_xyzw([p[0], p[1], p[2]], [p[3], p[4], p[5], p[6]]))
        .flatten()
        .ok_or_else(|| Rejection::SensorPose(wire::name_str(&h.frame_id)))
}

/// Signed distance from `p` to a capsule along z (segment `[-half_length, half_length]` on the
/// z axis swept by `radius`).
///
/// ```
/// use ember_engine::collision::distance::distance_point_capsule;
/// assert_eq!(distance_point_capsule([0.0, 0.0, 4.0], 1.0, 2.0), 1.0);
/// assert_eq!(distance_point_capsule([2.0, 0.0, 1.0], 1.0, 2.0), 1.0);
/// ```
#[inline]
pub fn distance_point_capsule(p: [f64; 3], radius: f64, half_length: f64) -> f64 {
    let z = p[2] - p[2].clamp(-half_length, half_length);
    (p[0] * p[0] + p[1] * p[1] + z * z).sqrt() - radius
}

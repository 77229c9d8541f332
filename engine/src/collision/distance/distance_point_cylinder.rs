/// Signed distance from `p` to a cylinder along z with `radius` and `half_length`.
///
/// ```
/// use ember_engine::collision::distance::distance_point_cylinder;
/// assert_eq!(distance_point_cylinder([3.0, 0.0, 0.0], 1.0, 1.0), 2.0);
/// assert_eq!(distance_point_cylinder([0.0, 0.0, 3.0], 1.0, 1.0), 2.0);
/// ```
#[inline]
pub fn distance_point_cylinder(p: [f64; 3], radius: f64, half_length: f64) -> f64 {
    let radial = (p[0] * p[0] + p[1] * p[1]).sqrt() - radius;
    let axial = p[2].abs() - half_length;
    let outside = {
        let a = radial.max(0.0);
        let b = axial.max(0.0);
        (a * a + b * b).sqrt()
    };
    outside + radial.max(axial).min(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rim_distance_is_euclidean() {
        let sut = distance_point_cylinder([2.0, 0.0, 2.0], 1.0, 1.0);
        assert!((sut - 2f64.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn inside_is_negative() {
        assert_eq!(distance_point_cylinder([0.0, 0.0, 0.5], 1.0, 1.0), -0.5);
    }
}

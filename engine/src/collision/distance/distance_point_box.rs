/// Signed distance from `p` to a centred box with half extents `h`.
///
/// ```
/// use ember_engine::collision::distance::distance_point_box;
/// assert_eq!(distance_point_box([2.0, 0.0, 0.0], [1.0, 1.0, 1.0]), 1.0);
/// assert_eq!(distance_point_box([0.5, 0.0, 0.0], [1.0, 1.0, 1.0]), -0.5);
/// ```
#[inline]
pub fn distance_point_box(p: [f64; 3], h: [f64; 3]) -> f64 {
    let q = [p[0].abs() - h[0], p[1].abs() - h[1], p[2].abs() - h[2]];
    let outside = {
        let x = q[0].max(0.0);
        let y = q[1].max(0.0);
        let z = q[2].max(0.0);
        (x * x + y * y + z * z).sqrt()
    };
    let inside = q[0].max(q[1]).max(q[2]).min(0.0);
    outside + inside
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn corner_distance_is_euclidean() {
        let sut = distance_point_box([2.0, 2.0, 1.0], [1.0, 1.0, 1.0]);
        assert!((sut - 2f64.sqrt()).abs() < 1e-12);
    }
}

/// Signed distance from `p` to a ball of `radius` centred at the origin.
#[inline]
pub fn distance_point_sphere(p: [f64; 3], radius: f64) -> f64 {
    (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() - radius
}

//! Order statistics of latency samples, as the daemon's status, the demo and the benchmarks
//! report them (nearest-rank quantiles; the median of an even count is the mean of the middle
//! two).

/// The `q` quantile of `v` by nearest rank (sorts in place); NaN when empty.
///
/// ```
/// let mut v = [5.0, 1.0, 3.0, 2.0, 4.0];
/// assert_eq!(ember_sdk::stats::quantile(&mut v, 0.99), 5.0);
/// assert_eq!(ember_sdk::stats::quantile(&mut v, 0.2), 1.0);
/// ```
pub fn quantile(v: &mut [f64], q: f64) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[((v.len() as f64 * q).ceil() as usize).clamp(1, v.len()) - 1]
}

/// The median of `v` (sorts in place); NaN when empty.
pub fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        (v[n / 2 - 1] + v[n / 2]) / 2.0
    }
}

/// Median, mean and 95th percentile of `v` (sorted in place); NaN when empty.
pub fn summary(v: &mut [f64]) -> (f64, f64, f64) {
    let mean = v.iter().sum::<f64>() / v.len() as f64;
    (median(v), mean, quantile(v, 0.95))
}

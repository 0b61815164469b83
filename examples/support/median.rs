//! The statistic the timing examples report: a median, robust to a shared machine's outliers.

/// The median of `v` (reordered).
pub fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

//! The distance between two sampled curves (thesis II.3.2.1, Definitions 12–14): each polyline
//! is parametrised by its normalised arc length, both are resampled at `M + 1` uniform
//! parameters, and the distance is the sum of the squared Euclidean distances between the
//! resampled points. Unlike the Hausdorff distance it is differentiable in the curve's
//! parameters, and unlike point-to-point interpolation it needs no equal sample counts.

use super::projected::Point;

/// The polyline `points` resampled at the `count + 1` parameters `i / count` of its normalised
/// arc length (Definition 13). A polyline of zero length resamples to its first point.
pub fn resample(points: &[Point], count: usize) -> Vec<Point> {
    let mut lengths = Vec::with_capacity(points.len());
    let mut total = 0.0;
    lengths.push(0.0);
    for w in points.windows(2) {
        total += (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]);
        lengths.push(total);
    }
    let mut out = Vec::with_capacity(count + 1);
    let mut segment = 0;
    for i in 0..=count {
        let target = total * i as f64 / count.max(1) as f64;
        while segment + 2 < points.len() && lengths[segment + 1] < target {
            segment += 1;
        }
        let (a, b) = (points[segment], points[(segment + 1).min(points.len() - 1)]);
        let span = lengths[(segment + 1).min(points.len() - 1)] - lengths[segment];
        let f = if span > 0.0 {
            ((target - lengths[segment]) / span).clamp(0.0, 1.0)
        } else {
            0.0
        };
        out.push([a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1])]);
    }
    out
}

/// The distance `D` of Definition 14 between two polylines, resampled at `count + 1` points.
pub fn distance(a: &[Point], b: &[Point], count: usize) -> f64 {
    resample(a, count)
        .iter()
        .zip(resample(b, count))
        .map(|(p, q)| (p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2))
        .sum()
}

/// Total length of a polyline.
pub fn length(points: &[Point]) -> f64 {
    points
        .windows(2)
        .map(|w| (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]))
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn resampling_follows_the_arc_length() {
        // An L: 3 units right, then 1 up; 4 pieces of 1.
        let l = [[0.0, 0.0], [3.0, 0.0], [3.0, 1.0]];
        let r = resample(&l, 4);
        assert_eq!(
            r,
            vec![[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [3.0, 0.0], [3.0, 1.0]]
        );
        assert_eq!(length(&l), 4.0);
    }

    #[test]
    fn the_distance_ignores_how_a_curve_is_sampled() {
        let coarse = [[0.0, 0.0], [2.0, 0.0]];
        let fine = [[0.0, 0.0], [0.5, 0.0], [1.0, 0.0], [2.0, 0.0]];
        assert!(distance(&coarse, &fine, 100) < 1e-24);
        let shifted = [[0.0, 1.0], [2.0, 1.0]];
        assert!((distance(&coarse, &shifted, 10) - 11.0).abs() < 1e-12);
    }
}

//! The projected-IFS curve (thesis II.1.3): `m + 1` control points `P` and `N` subdivision
//! matrices `T_0 … T_{N-1}` whose columns are barycentric. The curve is `F(s) = P Φ(s)`, the
//! projection of the IFS attractor; with `Φ(0) = e_0`, `Φ(1) = e_m` and the joining condition
//! `T_k e_m = T_{k+1} e_0` it is a continuous curve from the first control point to the last,
//! tabulated exactly at the parameters `i / N^p` (Proposition 5).

/// A point of the plane.
pub type Point = [f64; 2];

/// A projected-IFS curve of the plane.
#[derive(Debug, Clone, PartialEq)]
pub struct ProjectedCurve {
    /// The control points `p_0 … p_m`.
    pub points: Vec<Point>,
    /// The subdivision matrices, by columns: `maps[k][j][i]` is the weight of the parent's
    /// control point `i` in point `j` of the `k`-th piece (each column sums to 1).
    pub maps: Vec<Vec<Vec<f64>>>,
}

impl ProjectedCurve {
    /// The smooth curve of `points` with `maps` pieces: the Bézier curve of those control
    /// points, whose subdivision at `k / N` gives the matrices (de Casteljau). It meets the
    /// joining conditions, so it is the smooth member of the family the fit starts from.
    pub fn bezier(points: Vec<Point>, maps: usize) -> ProjectedCurve {
        let m = points.len() - 1;
        let maps = (0..maps)
            .map(|k| bezier_piece(m, k as f64 / maps as f64, (k + 1) as f64 / maps as f64))
            .collect();
        ProjectedCurve { points, maps }
    }

    /// Number of control points, `m + 1`.
    pub fn point_count(&self) -> usize {
        self.points.len()
    }

    /// The curve at the `N^depth + 1` parameters `i / N^depth` (Proposition 5: the first
    /// control point of each piece's polygon `P T_{ρ1} … T_{ρp}`, then the last control point).
    pub fn tabulate(&self, depth: u32) -> Vec<Point> {
        let mut out = Vec::with_capacity(self.maps.len().pow(depth) + 1);
        self.subdivide(&self.points, depth, &mut out);
        out.push(*self.points.last().expect("a curve has control points"));
        out
    }

    fn subdivide(&self, polygon: &[Point], depth: u32, out: &mut Vec<Point>) {
        if depth == 0 {
            out.push(polygon[0]);
            return;
        }
        let mut child = vec![[0.0; 2]; polygon.len()];
        for map in &self.maps {
            for (c, column) in child.iter_mut().zip(map) {
                *c = column.iter().zip(polygon).fold([0.0; 2], |acc, (w, p)| {
                    [acc[0] + w * p[0], acc[1] + w * p[1]]
                });
            }
            self.subdivide(&child, depth - 1, out);
        }
    }

    /// Whether the matrices meet the conditions that make the attractor a curve from the first
    /// control point to the last (columns barycentric, `T_0 e_0 = e_0`, `T_{N-1} e_m = e_m`,
    /// `T_k e_m = T_{k+1} e_0`), within `tolerance`.
    pub fn is_joined(&self, tolerance: f64) -> bool {
        let n = self.points.len();
        let m = n - 1;
        let unit = |i: usize| {
            (0..n)
                .map(|r| f64::from(u8::from(r == i)))
                .collect::<Vec<_>>()
        };
        let near = |a: &[f64], b: &[f64]| a.iter().zip(b).all(|(x, y)| (x - y).abs() <= tolerance);
        let shapes = self.maps.len() >= 2
            && self
                .maps
                .iter()
                .all(|t| t.len() == n && t.iter().all(|c| c.len() == n));
        shapes
            && self
                .maps
                .iter()
                .flatten()
                .all(|c| (c.iter().sum::<f64>() - 1.0).abs() <= tolerance)
            && near(&self.maps[0][0], &unit(0))
            && near(&self.maps[self.maps.len() - 1][m], &unit(m))
            && self.maps.windows(2).all(|w| near(&w[0][m], &w[1][0]))
    }
}

/// The matrix of the Bézier curve of degree `m` restricted to `[a, b]`: column `j` holds the
/// weights of the parent's control points in the piece's control point `j`.
fn bezier_piece(m: usize, a: f64, b: f64) -> Vec<Vec<f64>> {
    // Control point j of the piece is the blossom at (a^(m-j), b^j); the weight of parent
    // point i is that blossom of the Bernstein basis' i-th unit control values.
    (0..=m)
        .map(|j| {
            (0..=m)
                .map(|i| {
                    let mut values: Vec<f64> =
                        (0..=m).map(|r| f64::from(u8::from(r == i))).collect();
                    for level in 0..m {
                        let t = if level < m - j { a } else { b };
                        for r in 0..m - level {
                            values[r] = (1.0 - t) * values[r] + t * values[r + 1];
                        }
                    }
                    values[0]
                })
                .collect()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cubic(t: f64, p: &[Point]) -> Point {
        let b = [
            (1.0 - t).powi(3),
            3.0 * t * (1.0 - t).powi(2),
            3.0 * t * t * (1.0 - t),
            t.powi(3),
        ];
        let mut out = [0.0; 2];
        for (w, q) in b.iter().zip(p) {
            out[0] += w * q[0];
            out[1] += w * q[1];
        }
        out
    }

    #[test]
    fn the_bezier_rules_tabulate_the_bezier_curve() {
        let points = vec![[0.0, 0.0], [1.0, 3.0], [3.0, -1.0], [4.0, 1.0]];
        for maps in [2, 3] {
            let curve = ProjectedCurve::bezier(points.clone(), maps);
            assert!(curve.is_joined(1e-12));
            let depth = 4;
            let table = curve.tabulate(depth);
            let count = maps.pow(depth);
            assert_eq!(table.len(), count + 1);
            for (i, q) in table.iter().enumerate() {
                let want = cubic(i as f64 / count as f64, &points);
                assert!((q[0] - want[0]).abs() < 1e-12 && (q[1] - want[1]).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn a_matrix_that_breaks_the_joins_is_seen() {
        let mut curve = ProjectedCurve::bezier(vec![[0.0, 0.0], [1.0, 1.0], [2.0, 0.0]], 2);
        curve.maps[1][0][0] += 0.1;
        curve.maps[1][0][1] -= 0.1;
        assert!(!curve.is_joined(1e-9));
    }
}

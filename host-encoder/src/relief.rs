//! Hillshaded relief of a heightmap: a terrain seen under a low light, for a quick look at a
//! decoded elevation model (`pifs decode --hillshade`), where steps and creases between
//! patches show that a plain gray rendering hides.
//!
//! ```
//! use host_encoder::relief::{hillshade, Light};
//! // A ramp rising to the east, lit from the north-west: one shade everywhere.
//! let heights: Vec<f64> = (0..16).map(|i| f64::from(i % 4)).collect();
//! let shade = hillshade(&heights, 4, 4, &Light::default());
//! assert!(shade.iter().all(|&s| s == shade[0]));
//! ```

/// Where the light comes from, and how steep the terrain is drawn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Light {
    /// Direction the light comes from, in degrees clockwise from north (the image's top):
    /// 315 is the north-west of cartography.
    pub azimuth: f64,
    /// Height of the light above the horizon, in degrees.
    pub altitude: f64,
    /// Height units per pixel spacing (the vertical exaggeration); `None` chooses the scale
    /// at which the terrain's median slope is 20 degrees, which shows any heightmap whose
    /// units are unknown (an 8-bit decode, say).
    pub z_factor: Option<f64>,
}

impl Default for Light {
    fn default() -> Self {
        Light {
            azimuth: 315.0,
            altitude: 45.0,
            z_factor: None,
        }
    }
}

/// The slope of `heights` (row-major, `width x height`) at every sample, in order, as `(east,
/// north)` height differences per pixel: central differences inside, one-sided at the
/// borders. Made as they are needed, not stored.
fn slopes(heights: &[f64], width: usize, height: usize) -> impl Iterator<Item = (f64, f64)> + '_ {
    let at = move |x: usize, y: usize| heights[y * width + x];
    let diff = |lo: f64, hi: f64, span: usize| {
        if span == 0 {
            0.0
        } else {
            (hi - lo) / span as f64
        }
    };
    (0..height).flat_map(move |y| {
        let (up, down) = (y.saturating_sub(1), (y + 1).min(height - 1));
        (0..width).map(move |x| {
            let (left, right) = (x.saturating_sub(1), (x + 1).min(width - 1));
            let east = diff(at(left, y), at(right, y), right - left);
            // Rows grow southwards.
            let north = diff(at(x, down), at(x, up), down - up);
            (east, north)
        })
    })
}

/// The z factor at which the median of `slopes` is 20 degrees (1 for a flat map).
fn auto_z_factor(slopes: impl Iterator<Item = (f64, f64)>) -> f64 {
    let mut magnitudes: Vec<f64> = slopes.map(|(e, n)| e.hypot(n)).collect();
    if magnitudes.is_empty() {
        return 1.0;
    }
    let mid = magnitudes.len() / 2;
    let (_, median, _) = magnitudes.select_nth_unstable_by(mid, f64::total_cmp);
    if *median > 0.0 {
        20f64.to_radians().tan() / *median
    } else {
        1.0
    }
}

/// The hillshade of `heights` (row-major, `width x height`): each sample's brightness is the
/// cosine between its surface normal and the direction of `light` (Lambert), 0 for a slope
/// facing away, as 8-bit gray. Panics if `heights` does not hold `width x height` values.
pub fn hillshade(heights: &[f64], width: usize, height: usize, light: &Light) -> Vec<u8> {
    assert_eq!(heights.len(), width * height, "heightmap size mismatch");
    let z = light
        .z_factor
        .unwrap_or_else(|| auto_z_factor(slopes(heights, width, height)));
    let (az, alt) = (light.azimuth.to_radians(), light.altitude.to_radians());
    let towards = [az.sin() * alt.cos(), az.cos() * alt.cos(), alt.sin()];
    slopes(heights, width, height)
        .map(|(east, north)| {
            let normal = [-east * z, -north * z, 1.0];
            let length = normal.iter().map(|v| v * v).sum::<f64>().sqrt();
            let lambert: f64 = normal.iter().zip(towards).map(|(n, l)| n * l).sum::<f64>() / length;
            (255.0 * lambert.max(0.0)).round() as u8
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plane(width: usize, height: usize, f: impl Fn(usize, usize) -> f64) -> Vec<f64> {
        (0..width * height)
            .map(|i| f(i % width, i / width))
            .collect()
    }

    #[test]
    fn flat_ground_takes_the_light_at_its_altitude() {
        let shade = hillshade(&plane(5, 3, |_, _| 7.0), 5, 3, &Light::default());
        // sin 45° of full white.
        assert_eq!(shade, vec![180; 15]);
    }

    #[test]
    fn slopes_facing_the_light_are_brighter() {
        let light = Light {
            z_factor: Some(1.0),
            ..Light::default()
        };
        // Rising to the east faces west, towards a north-west light: brighter than rising
        // to the west. Rising to the south (rows grow south) faces north: brighter too.
        let east = hillshade(&plane(6, 6, |x, _| x as f64), 6, 6, &light);
        let west = hillshade(&plane(6, 6, |x, _| -(x as f64)), 6, 6, &light);
        let south = hillshade(&plane(6, 6, |_, y| y as f64), 6, 6, &light);
        let north = hillshade(&plane(6, 6, |_, y| -(y as f64)), 6, 6, &light);
        assert!(
            east[14] > west[14] && south[14] > north[14],
            "{east:?} {west:?}"
        );
        // A unit slope rising east, normal (-1, 0, 1) / sqrt 2, under the light (-1/2, 1/2,
        // 1/sqrt 2): (1/2 + 1/sqrt 2) / sqrt 2 = 0.854 of white.
        assert_eq!(
            east[14],
            (255.0 * (0.5 + 0.5f64.sqrt()) / 2f64.sqrt()).round() as u8
        );
        // A slope facing away from a light this low is black.
        let steep = Light {
            z_factor: Some(10.0),
            ..light
        };
        assert_eq!(
            hillshade(&plane(6, 6, |x, _| -(x as f64)), 6, 6, &steep)[14],
            0
        );
    }

    #[test]
    fn the_automatic_scale_gives_a_median_slope_of_twenty_degrees() {
        let ramp = plane(8, 8, |x, _| 0.001 * x as f64);
        let z = auto_z_factor(slopes(&ramp, 8, 8));
        assert!((z * 0.001 - 20f64.to_radians().tan()).abs() < 1e-12);
        // Scaling the heights does not change the automatic view.
        let light = Light::default();
        let steep = plane(8, 8, |x, y| 50.0 * (x * y) as f64);
        let shallow: Vec<f64> = steep.iter().map(|h| h / 1000.0).collect();
        assert_eq!(
            hillshade(&steep, 8, 8, &light),
            hillshade(&shallow, 8, 8, &light)
        );
    }
}

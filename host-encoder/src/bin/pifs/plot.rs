//! The rate/distortion curve as an SVG drawing (`plotters`, SVG backend).

use crate::compare::Series;
use plotters::prelude::*;

/// Line colours, one per series in turn (PIFS first).
const COLOURS: [RGBColor; 8] = [
    RGBColor(214, 39, 40),
    RGBColor(31, 119, 180),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
];

/// The SVG document of PSNR against bits per pixel, one line with markers per series, with a
/// legend; `title` is its caption. The error is the backend's message.
pub fn rd_svg(title: &str, series: &[Series]) -> Result<String, String> {
    let mut svg = String::new();
    draw(&mut svg, title, series).map_err(|e| e.to_string())?;
    Ok(svg)
}

fn draw(
    svg: &mut String,
    title: &str,
    series: &[Series],
) -> Result<(), Box<dyn std::error::Error>> {
    let points = series.iter().flat_map(|s| s.points.iter());
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for &(x, y) in points {
        (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
    }
    if x0 > x1 {
        (x0, x1, y0, y1) = (0.0, 1.0, 20.0, 40.0);
    }
    // Some room around the points; the rate axis starts at zero.
    let x1 = x1 + 0.05 * (x1 - x0).max(0.01);
    let (y0, y1) = (
        (y0 - 0.05 * (y1 - y0).max(1.0)).floor(),
        (y1 + 0.05 * (y1 - y0).max(1.0)).ceil(),
    );
    let root = SVGBackend::with_string(svg, (800, 520)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 24))
        .margin(16)
        .x_label_area_size(50)
        .y_label_area_size(64)
        .build_cartesian_2d(0.0..x1, y0..y1)?;
    chart
        .configure_mesh()
        .light_line_style(RGBColor(235, 235, 235))
        .label_style(("sans-serif", 15))
        .axis_desc_style(("sans-serif", 16))
        .x_desc("bits per pixel (whole file)")
        .y_desc("PSNR (dB)")
        .draw()?;
    for (i, s) in series.iter().enumerate() {
        let colour = COLOURS[i % COLOURS.len()];
        chart
            .draw_series(LineSeries::new(
                s.points.iter().copied(),
                colour.stroke_width(2),
            ))?
            .label(s.name.as_str())
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2))
            });
        chart.draw_series(
            s.points
                .iter()
                .map(move |&p| Circle::new(p, 3, colour.filled())),
        )?;
    }
    legend(&mut chart, SeriesLabelPosition::LowerRight)?;
    root.present()?;
    Ok(())
}

/// A chart of the tool's SVG drawings: two real axes.
pub type Chart<'a, 'b> = ChartContext<
    'a,
    SVGBackend<'b>,
    Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
>;

/// The legend of the labelled series, boxed, at `position`.
pub fn legend<'a>(
    chart: &mut Chart<'a, 'a>,
    position: SeriesLabelPosition,
) -> Result<(), Box<dyn std::error::Error>> {
    chart
        .configure_series_labels()
        .position(position)
        .label_font(("sans-serif", 15))
        .background_style(WHITE.mix(0.9))
        .border_style(BLACK)
        .draw()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_series_is_drawn_with_its_name() {
        let series = [
            Series {
                name: "pifs".into(),
                points: vec![(0.05, 25.0), (0.1, 27.5), (0.25, 31.0)],
            },
            Series {
                name: "jpeg (mean of 2 images)".into(),
                points: vec![(0.1, 24.0), (0.25, 28.0)],
            },
        ];
        let svg = rd_svg("kodim23.png", &series).unwrap();
        assert!(svg.starts_with("<svg"), "{}", &svg[..80.min(svg.len())]);
        let texts: Vec<&str> = svg.lines().map(str::trim).collect();
        assert!(texts.contains(&"pifs") && texts.contains(&"jpeg (mean of 2 images)"));
        assert!(svg.contains("PSNR (dB)"));
        // One marker per point.
        assert_eq!(svg.matches("<circle").count(), 5);
    }
}

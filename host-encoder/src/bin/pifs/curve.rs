//! `pifs curve`: projected-IFS curves (thesis part II) fitted to polylines and sampled
//! functions, drawn at any resolution, and described.

use crate::error::{CliError, Result};
use crate::output::{self, Kind};
use crate::say;
use clap::{Args, Subcommand};
use host_encoder::curve::{
    distance, fit_curve, read_csv, read_svg, CurveFile, CurveFitConfig, FitRecord, LmConfig, Point,
    ProjectedCurve, MAX_TABULATION,
};
use host_encoder::io;
use plotters::prelude::*;
use std::path::{Path, PathBuf};

/// Largest curve input read (CSV, SVG or JSON).
const MAX_INPUT_BYTES: u64 = 64 << 20;

/// `pifs curve ...`.
#[derive(Subcommand, Debug)]
pub enum CurveCommand {
    /// Fit a projected-IFS curve to a polyline or a sampled function (CSV or SVG) and write
    /// it as a JSON curve file.
    ///
    /// CSV: one "x,y" per line (or one value per line: a function sampled at 0, 1, 2, ...).
    /// SVG: the first polyline, polygon or path of straight segments. The fit is
    /// Levenberg-Marquardt on the thesis's distance (both curves resampled by arc length),
    /// from control points on the data and the smooth (Bezier) rules.
    Fit(FitArgs),
    /// Draw a fitted curve (.svg, over its data with --data) or tabulate it (.csv).
    Render(RenderArgs),
    /// Describe a fitted curve: its model, parameters and error (against --data if given).
    Info(InfoArgs),
}

/// `pifs curve fit`.
#[derive(Args, Debug)]
pub struct FitArgs {
    /// The data: a CSV file, or an SVG file (by its .svg name); "-" reads CSV from standard
    /// input.
    input: PathBuf,
    /// Control points of the curve (at least 2).
    #[arg(long)]
    points: usize,
    /// Subdivision matrices: pieces per level (at least 2).
    #[arg(long, default_value_t = 2)]
    maps: usize,
    /// Keep the smooth subdivision rules (a Bezier curve): fit the control points only.
    #[arg(long)]
    smooth: bool,
    /// Tabulation depth: the curve is compared through its maps^depth + 1 points [default:
    /// the smallest with at least 1025 points].
    #[arg(long)]
    depth: Option<u32>,
    /// Points both curves are resampled to for the distance.
    #[arg(long, default_value_t = 500)]
    resample: usize,
    /// Levenberg-Marquardt iterations at most, per stage (control points, then weights).
    #[arg(long, default_value_t = 300)]
    iterations: usize,
    /// Output curve file (JSON); "-" writes standard output.
    #[arg(short, long)]
    output: PathBuf,
}

/// `pifs curve render`.
#[derive(Args, Debug)]
pub struct RenderArgs {
    /// A curve file written by `pifs curve fit`.
    input: PathBuf,
    /// Output: an .svg drawing or a .csv table of points ("x,y" per line).
    #[arg(short, long)]
    output: PathBuf,
    /// Tabulation depth: maps^depth + 1 points [default: the depth it was fitted with].
    #[arg(long)]
    depth: Option<u32>,
    /// Draw this data (CSV or SVG) under the curve.
    #[arg(long, value_name = "FILE")]
    data: Option<PathBuf>,
}

/// `pifs curve info`.
#[derive(Args, Debug)]
pub struct InfoArgs {
    /// A curve file written by `pifs curve fit`.
    input: PathBuf,
    /// Measure the curve's distance to this data (CSV or SVG).
    #[arg(long, value_name = "FILE")]
    data: Option<PathBuf>,
}

/// Runs a `pifs curve` command.
pub fn run(command: &CurveCommand) -> Result<()> {
    match command {
        CurveCommand::Fit(args) => fit(args),
        CurveCommand::Render(args) => render(args),
        CurveCommand::Info(args) => info(args),
    }
}

fn fit(args: &FitArgs) -> Result<()> {
    output::check(&args.output, Some(&args.input), Kind::Json)?;
    let data = read_data(&args.input)?;
    let mut config = CurveFitConfig::new(args.points, args.maps);
    config.weights = !args.smooth;
    config.resample = args.resample;
    config.lm = LmConfig {
        max_iterations: args.iterations,
        ..LmConfig::default()
    };
    if let Some(depth) = args.depth {
        check_depth(args.maps, depth)?;
        config.depth = depth;
    }
    let fit = fit_curve(&data, &config)
        .map_err(|e| CliError::Refused(format!("{}: {e}", args.input.display())))?;
    let record = FitRecord {
        data_points: data.len(),
        resample: config.resample,
        weights: config.weights,
        parameters: fit.parameters,
        distance: fit.distance,
        rms: fit.rms,
        iterations: fit.iterations,
    };
    let y_down = is_svg(&args.input);
    let file = CurveFile::new(&fit.curve, config.depth, y_down, Some(record));
    if io::is_std_stream(&args.output) {
        say::stdout_is_data();
    }
    io::write_atomic(&args.output, file.to_json().as_bytes())?;
    say::line(format_args!(
        "{}: {} points fitted by {} control points and {} maps ({} parameters): rms distance {:.6} ({} iterations) -> {}",
        args.input.display(),
        data.len(),
        args.points,
        args.maps,
        fit.parameters,
        fit.rms,
        fit.iterations,
        args.output.display()
    ));
    Ok(())
}

fn render(args: &RenderArgs) -> Result<()> {
    let svg = has_extension(&args.output, "svg");
    if !svg && !has_extension(&args.output, "csv") {
        return Err(CliError::Refused(format!(
            "{}: name the output .svg (a drawing) or .csv (the points)",
            args.output.display()
        )));
    }
    output::check(
        &args.output,
        Some(&args.input),
        if svg { Kind::Svg } else { Kind::Csv },
    )?;
    let file = read_curve(&args.input)?;
    let depth = args.depth.unwrap_or(file.depth);
    check_depth(file.maps.len(), depth)?;
    let data = args.data.as_deref().map(read_data).transpose()?;
    let curve = file.curve();
    let table = curve.tabulate(depth);
    let text = if svg {
        curve_svg(&curve, &table, data.as_deref(), file.y_down).map_err(|cause| CliError::Plot {
            path: args.output.clone(),
            cause,
        })?
    } else {
        table
            .iter()
            .map(|p| format!("{},{}\n", p[0], p[1]))
            .collect()
    };
    if io::is_std_stream(&args.output) {
        say::stdout_is_data();
    }
    io::write_atomic(&args.output, text.as_bytes())?;
    say::line(format_args!(
        "{}: {} points at depth {depth} -> {}",
        args.input.display(),
        table.len(),
        args.output.display()
    ));
    Ok(())
}

fn info(args: &InfoArgs) -> Result<()> {
    let file = read_curve(&args.input)?;
    let n = file.points.len();
    say::text(format_args!(
        "  model            {} control points, {} maps, depth {} ({} points)\n",
        n,
        file.maps.len(),
        file.depth,
        file.maps.len().saturating_pow(file.depth).saturating_add(1)
    ));
    if let Some(fit) = &file.fit {
        let rules = if fit.weights {
            "fitted weights"
        } else {
            "smooth (Bezier) rules"
        };
        say::text(format_args!(
            "  fit              {} data points, {rules}, {} parameters, {} iterations\n  error            rms distance {:.6}, D = {:.6e} over {} resampled points\n",
            fit.data_points, fit.parameters, fit.iterations, fit.rms, fit.distance, fit.resample + 1
        ));
    }
    if let Some(path) = &args.data {
        check_depth(file.maps.len(), file.depth)?;
        let data = read_data(path)?;
        let count = file.fit.as_ref().map_or(500, |f| f.resample);
        let d = distance(&file.curve().tabulate(file.depth), &data, count);
        say::text(format_args!(
            "  against {}  rms distance {:.6}, D = {d:.6e} over {} resampled points\n",
            path.display(),
            (d / (count + 1) as f64).sqrt(),
            count + 1
        ));
    }
    Ok(())
}

/// Refuses a tabulation larger than [`MAX_TABULATION`].
fn check_depth(maps: usize, depth: u32) -> Result<()> {
    match maps.checked_pow(depth) {
        Some(n) if n < MAX_TABULATION => Ok(()),
        _ => Err(CliError::Refused(format!(
            "depth {depth} with {maps} maps tabulates more than {MAX_TABULATION} points: choose a smaller --depth"
        ))),
    }
}

fn has_extension(path: &Path, ext: &str) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case(ext))
}

fn is_svg(path: &Path) -> bool {
    has_extension(path, "svg")
}

fn read_text(path: &Path, expected: &'static str) -> Result<String> {
    let bytes = io::read_input(path, expected, MAX_INPUT_BYTES)?;
    String::from_utf8(bytes)
        .map_err(|_| CliError::Refused(format!("{}: not a text file", path.display())))
}

/// The points of a CSV or SVG data file.
fn read_data(path: &Path) -> Result<Vec<Point>> {
    let text = read_text(path, "a CSV or SVG curve")?;
    let points = if is_svg(path) {
        read_svg(&text)
    } else {
        read_csv(&text)
    }
    .map_err(|e| CliError::Refused(format!("{}: {e}", path.display())))?;
    if points.len() < 2 {
        return Err(CliError::Refused(format!(
            "{}: fewer than 2 points",
            path.display()
        )));
    }
    Ok(points)
}

fn read_curve(path: &Path) -> Result<CurveFile> {
    let text = read_text(path, "a curve file")?;
    CurveFile::parse(&text).map_err(|e| CliError::Refused(format!("{}: {e}", path.display())))
}

/// The SVG drawing of `table` (the curve), its control polygon, and `data` under it.
fn curve_svg(
    curve: &ProjectedCurve,
    table: &[Point],
    data: Option<&[Point]>,
    y_down: bool,
) -> std::result::Result<String, String> {
    let mut svg = String::new();
    draw(&mut svg, curve, table, data, y_down).map_err(|e| e.to_string())?;
    Ok(svg)
}

fn draw(
    svg: &mut String,
    curve: &ProjectedCurve,
    table: &[Point],
    data: Option<&[Point]>,
    y_down: bool,
) -> std::result::Result<(), Box<dyn std::error::Error>> {
    let all = table.iter().chain(data.unwrap_or(&[])).chain(&curve.points);
    let (mut lo, mut hi) = ([f64::MAX; 2], [f64::MIN; 2]);
    for p in all {
        for a in 0..2 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    let span = [(hi[0] - lo[0]).max(1e-9), (hi[1] - lo[1]).max(1e-9)];
    let (lo, hi) = (
        [lo[0] - 0.03 * span[0], lo[1] - 0.03 * span[1]],
        [hi[0] + 0.03 * span[0], hi[1] + 0.03 * span[1]],
    );
    // The canvas follows the data's aspect (within 1:4 and 4:1).
    let height = (900.0 * span[1] / span[0]).clamp(225.0, 900.0) as u32 + 90;
    let root = SVGBackend::with_string(svg, (1000, height)).into_drawing_area();
    root.fill(&WHITE)?;
    let y_range = if y_down { hi[1]..lo[1] } else { lo[1]..hi[1] };
    let mut chart = ChartBuilder::on(&root)
        .margin(16)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(lo[0]..hi[0], y_range)?;
    chart
        .configure_mesh()
        .light_line_style(RGBColor(240, 240, 240))
        .label_style(("sans-serif", 14))
        .draw()?;
    let to = |p: &Point| (p[0], p[1]);
    if let Some(data) = data {
        chart
            .draw_series(LineSeries::new(
                data.iter().map(to),
                RGBColor(160, 160, 160).stroke_width(3),
            ))?
            .label("data")
            .legend(|(x, y)| {
                PathElement::new(
                    vec![(x, y), (x + 20, y)],
                    RGBColor(160, 160, 160).stroke_width(3),
                )
            });
    }
    let blue = RGBColor(31, 119, 180);
    chart
        .draw_series(LineSeries::new(
            curve.points.iter().map(to),
            blue.mix(0.5).stroke_width(1),
        ))?
        .label("control polygon")
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], blue.mix(0.5)));
    chart.draw_series(
        curve
            .points
            .iter()
            .map(|p| Circle::new(to(p), 4, blue.filled())),
    )?;
    let red = RGBColor(214, 39, 40);
    chart
        .draw_series(LineSeries::new(table.iter().map(to), red.stroke_width(1)))?
        .label("projected-IFS curve")
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], red.stroke_width(2)));
    crate::plot::legend(&mut chart, SeriesLabelPosition::UpperRight)?;
    root.present()?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_drawing_has_the_data_the_polygon_and_the_curve() {
        let curve = ProjectedCurve::bezier(vec![[0.0, 0.0], [1.0, 2.0], [3.0, 1.0]], 2);
        let table = curve.tabulate(6);
        let data = host_encoder::curve::resample(&table, 20);
        let svg = curve_svg(&curve, &table, Some(&data), false).unwrap();
        assert!(svg.starts_with("<svg"));
        for label in ["data", "control polygon", "projected-IFS curve"] {
            assert!(svg.contains(label), "{label}");
        }
        assert_eq!(svg.matches("<circle").count(), 3);
    }
}

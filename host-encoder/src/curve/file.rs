//! Curve files: sampled curves read from CSV or SVG, fitted curves stored as JSON.
//!
//! - **CSV**: one point per line, `x,y` (commas, semicolons, tabs or spaces between the two);
//!   a line with one number is a sampled function, `x` its line's index. Blank lines, lines
//!   starting with `#` and a first line that is not numbers (a header) are skipped.
//! - **SVG**: the first `polyline`, `polygon` or `path` element. Paths may use the straight
//!   commands (`M L H V Z`, absolute or relative); curved ones are refused (flatten them
//!   first). SVG's `y` axis points down, and the fitted curve keeps the data's coordinates.
//! - **JSON** (what `pifs curve fit` writes): `{"format": "pifs-curve", "version": 1,
//!   "points": [[x, y], …], "maps": [[[w, …] column, …] matrix, …], "depth": p, "y_down":
//!   bool, "fit": {…}}`, the matrices by columns as [`ProjectedCurve::maps`].

use super::projected::{Point, ProjectedCurve};
use serde::{Deserialize, Serialize};
use std::fmt;

/// Why a curve file cannot be read.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum CurveFileError {
    /// A CSV line that is not one or two numbers (1-based line number).
    Csv {
        /// Line number, from 1.
        line: usize,
    },
    /// An SVG document that does not parse (the parser's message).
    Xml(String),
    /// An SVG without a `polyline`, `polygon` or `path`.
    NoShape,
    /// An SVG path command other than `M L H V Z`.
    PathCommand(char),
    /// SVG coordinates that are not numbers.
    SvgNumbers,
    /// A JSON curve file that does not parse or is not one (the reason).
    Json(String),
}

impl fmt::Display for CurveFileError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CurveFileError::Csv { line } => write!(f, "line {line} is not one or two numbers"),
            CurveFileError::Xml(why) => write!(f, "not an SVG document: {why}"),
            CurveFileError::NoShape => write!(f, "no polyline, polygon or path in the SVG"),
            CurveFileError::PathCommand(c) => write!(
                f,
                "SVG path command '{c}' is not supported (straight segments only: M L H V Z)"
            ),
            CurveFileError::SvgNumbers => write!(f, "SVG coordinates that are not numbers"),
            CurveFileError::Json(why) => write!(f, "not a curve file: {why}"),
        }
    }
}

impl std::error::Error for CurveFileError {}

/// The points of a CSV file (see the module's documentation).
pub fn read_csv(text: &str) -> Result<Vec<Point>, CurveFileError> {
    let mut points = Vec::new();
    let mut numbers_seen = false;
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> = line
            .split(|c: char| c == ',' || c == ';' || c.is_whitespace())
            .filter(|f| !f.is_empty())
            .collect();
        let values: Option<Vec<f64>> = fields.iter().map(|f| f.parse().ok()).collect();
        match values.as_deref() {
            Some([x, y]) if x.is_finite() && y.is_finite() => points.push([*x, *y]),
            Some([y]) if y.is_finite() => points.push([points.len() as f64, *y]),
            _ if !numbers_seen => {}
            _ => return Err(CurveFileError::Csv { line: i + 1 }),
        }
        // Only the first non-blank line may be a header.
        numbers_seen = true;
    }
    Ok(points)
}

/// The points of the first `polyline`, `polygon` or `path` of an SVG document.
pub fn read_svg(text: &str) -> Result<Vec<Point>, CurveFileError> {
    let doc = roxmltree::Document::parse(text).map_err(|e| CurveFileError::Xml(e.to_string()))?;
    for node in doc.descendants().filter(|n| n.is_element()) {
        match node.tag_name().name() {
            name @ ("polyline" | "polygon") => {
                let mut points = pairs(&numbers(node.attribute("points").unwrap_or(""))?)?;
                if name == "polygon" && !points.is_empty() {
                    points.push(points[0]);
                }
                return Ok(points);
            }
            "path" => return path_points(node.attribute("d").unwrap_or("")),
            _ => {}
        }
    }
    Err(CurveFileError::NoShape)
}

fn numbers(text: &str) -> Result<Vec<f64>, CurveFileError> {
    text.split(|c: char| c == ',' || c.is_whitespace())
        .filter(|f| !f.is_empty())
        .map(|f| {
            f.parse()
                .ok()
                .filter(|v: &f64| v.is_finite())
                .ok_or(CurveFileError::SvgNumbers)
        })
        .collect()
}

fn pairs(values: &[f64]) -> Result<Vec<Point>, CurveFileError> {
    if !values.len().is_multiple_of(2) {
        return Err(CurveFileError::SvgNumbers);
    }
    Ok(values.chunks_exact(2).map(|c| [c[0], c[1]]).collect())
}

/// The vertices of an SVG path of straight segments.
fn path_points(d: &str) -> Result<Vec<Point>, CurveFileError> {
    let mut points: Vec<Point> = Vec::new();
    let mut start = [0.0, 0.0];
    let mut at = [0.0, 0.0];
    for (command, args) in path_commands(d)? {
        let relative = command.is_ascii_lowercase();
        let base = if relative { at } else { [0.0, 0.0] };
        match command.to_ascii_uppercase() {
            'M' | 'L' => {
                for (k, p) in pairs(&args)?.into_iter().enumerate() {
                    let origin = if relative { at } else { base };
                    at = [origin[0] + p[0], origin[1] + p[1]];
                    if k == 0 && command.eq_ignore_ascii_case(&'M') {
                        start = at;
                    }
                    points.push(at);
                }
            }
            'H' => {
                for x in args {
                    at = [if relative { at[0] + x } else { x }, at[1]];
                    points.push(at);
                }
            }
            'V' => {
                for y in args {
                    at = [at[0], if relative { at[1] + y } else { y }];
                    points.push(at);
                }
            }
            'Z' => {
                at = start;
                points.push(at);
            }
            other => return Err(CurveFileError::PathCommand(other)),
        }
    }
    Ok(points)
}

/// A path's commands with their numbers.
fn path_commands(d: &str) -> Result<Vec<(char, Vec<f64>)>, CurveFileError> {
    let mut out: Vec<(char, Vec<f64>)> = Vec::new();
    let mut rest = d.trim_start();
    while let Some(c) = rest.chars().next() {
        if c.is_ascii_alphabetic() && c != 'e' && c != 'E' {
            out.push((c, Vec::new()));
            rest = rest[1..].trim_start_matches(|c: char| c == ',' || c.is_whitespace());
            continue;
        }
        let len = number_len(rest).ok_or(CurveFileError::SvgNumbers)?;
        let value: f64 = rest[..len]
            .parse()
            .map_err(|_| CurveFileError::SvgNumbers)?;
        out.last_mut()
            .ok_or(CurveFileError::SvgNumbers)?
            .1
            .push(value);
        rest = rest[len..].trim_start_matches(|c: char| c == ',' || c.is_whitespace());
    }
    Ok(out)
}

/// Length of the number at the start of `s` (SVG's grammar: sign, digits, one point, exponent).
fn number_len(s: &str) -> Option<usize> {
    let b = s.as_bytes();
    let mut i = 0;
    if matches!(b.first(), Some(b'+' | b'-')) {
        i += 1;
    }
    let digits = |i: &mut usize| {
        let from = *i;
        while b.get(*i).is_some_and(u8::is_ascii_digit) {
            *i += 1;
        }
        *i > from
    };
    let mut any = digits(&mut i);
    if b.get(i) == Some(&b'.') {
        i += 1;
        any |= digits(&mut i);
    }
    if !any {
        return None;
    }
    if matches!(b.get(i), Some(b'e' | b'E')) {
        let mut j = i + 1;
        if matches!(b.get(j), Some(b'+' | b'-')) {
            j += 1;
        }
        if digits(&mut j) {
            i = j;
        }
    }
    Some(i)
}

/// How a stored curve was fitted.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FitRecord {
    /// Data points fitted.
    pub data_points: usize,
    /// Resampling count `M` of the distance.
    pub resample: usize,
    /// Whether the subdivision weights were fitted (otherwise the smooth Bézier rules).
    pub weights: bool,
    /// Free parameters.
    pub parameters: usize,
    /// The distance `D` to the data (squared data units).
    pub distance: f64,
    /// Root-mean-square distance between the resampled points (data units).
    pub rms: f64,
    /// Levenberg–Marquardt iterations.
    pub iterations: usize,
}

/// A fitted curve as stored in a JSON curve file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CurveFile {
    /// Always `"pifs-curve"`.
    pub format: String,
    /// Version of this layout: 1.
    pub version: u32,
    /// The control points.
    pub points: Vec<Point>,
    /// The subdivision matrices by columns ([`ProjectedCurve::maps`]).
    pub maps: Vec<Vec<Vec<f64>>>,
    /// Tabulation depth the curve was fitted with.
    pub depth: u32,
    /// Whether the data's `y` axis points down (SVG input).
    pub y_down: bool,
    /// How it was fitted.
    pub fit: Option<FitRecord>,
}

/// The value of [`CurveFile::format`].
pub const CURVE_FORMAT: &str = "pifs-curve";

impl CurveFile {
    /// A file for `curve`.
    pub fn new(curve: &ProjectedCurve, depth: u32, y_down: bool, fit: Option<FitRecord>) -> Self {
        CurveFile {
            format: CURVE_FORMAT.to_string(),
            version: 1,
            points: curve.points.clone(),
            maps: curve.maps.clone(),
            depth,
            y_down,
            fit,
        }
    }

    /// Parses and checks a curve file: its format and version, finite numbers, and matrices
    /// that make a curve ([`ProjectedCurve::is_joined`]).
    pub fn parse(text: &str) -> Result<CurveFile, CurveFileError> {
        let bad = |why: &str| Err(CurveFileError::Json(why.to_string()));
        let value: serde_json::Value =
            serde_json::from_str(text).map_err(|e| CurveFileError::Json(e.to_string()))?;
        if value.get("format").and_then(|f| f.as_str()) != Some(CURVE_FORMAT)
            || value.get("version").and_then(|v| v.as_u64()) != Some(1)
        {
            return bad("not a version 1 pifs-curve file");
        }
        let file: CurveFile = serde_json::from_value(value)
            .map_err(|e| CurveFileError::Json(e.to_string().replace('`', "'")))?;
        if file.points.len() < 2 || file.depth > 24 {
            return bad("fewer than 2 control points, or a depth above 24");
        }
        if file
            .points
            .iter()
            .flatten()
            .chain(file.maps.iter().flatten().flatten())
            .any(|v| !v.is_finite())
        {
            return bad("a number is not finite");
        }
        if !file.curve().is_joined(1e-6) {
            return bad("the matrices do not make a curve (columns summing to 1, joined pieces)");
        }
        Ok(file)
    }

    /// The curve.
    pub fn curve(&self) -> ProjectedCurve {
        ProjectedCurve {
            points: self.points.clone(),
            maps: self.maps.clone(),
        }
    }

    /// The file as pretty-printed JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("a curve file serialises") + "\n"
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_takes_pairs_single_values_and_a_header() {
        assert_eq!(
            read_csv("x,y\n0,1\n# note\n\n2.5; -3\n4\t5e1\n").unwrap(),
            vec![[0.0, 1.0], [2.5, -3.0], [4.0, 50.0]]
        );
        assert_eq!(
            read_csv("elevation\n10\n12\n11\n").unwrap(),
            vec![[0.0, 10.0], [1.0, 12.0], [2.0, 11.0]]
        );
        assert_eq!(read_csv("0,1\n1,x\n"), Err(CurveFileError::Csv { line: 2 }));
        assert_eq!(read_csv("0,1,2\n"), Ok(vec![]));
        assert_eq!(
            read_csv("1,2\n0,1,2\n"),
            Err(CurveFileError::Csv { line: 2 })
        );
    }

    #[test]
    fn svg_polylines_polygons_and_straight_paths() {
        let poly = r#"<svg xmlns="http://www.w3.org/2000/svg"><g><polyline points="0,0 10,5 20,0"/></g></svg>"#;
        assert_eq!(
            read_svg(poly).unwrap(),
            vec![[0.0, 0.0], [10.0, 5.0], [20.0, 0.0]]
        );
        let gon = r#"<svg><polygon points="0 0 1 0 1 1"/></svg>"#;
        assert_eq!(read_svg(gon).unwrap().len(), 4);
        let path = r#"<svg><path d="M1,2 l3-1 2,0 H10 v5 h-1e1 z"/></svg>"#;
        assert_eq!(
            read_svg(path).unwrap(),
            vec![
                [1.0, 2.0],
                [4.0, 1.0],
                [6.0, 1.0],
                [10.0, 1.0],
                [10.0, 6.0],
                [0.0, 6.0],
                [1.0, 2.0]
            ]
        );
        assert_eq!(
            read_svg(r#"<svg><path d="M0 0 C1 1 2 2 3 3"/></svg>"#),
            Err(CurveFileError::PathCommand('C'))
        );
        assert_eq!(read_svg("<svg><rect/></svg>"), Err(CurveFileError::NoShape));
        assert!(matches!(read_svg("<svg"), Err(CurveFileError::Xml(_))));
        assert_eq!(
            read_svg(r#"<svg><polyline points="0,0 1"/></svg>"#),
            Err(CurveFileError::SvgNumbers)
        );
    }

    #[test]
    fn json_round_trips_and_refuses_broken_curves() {
        let curve = ProjectedCurve::bezier(vec![[0.0, 0.0], [1.0, 2.0], [3.0, 1.0]], 2);
        let file = CurveFile::new(&curve, 8, true, None);
        let back = CurveFile::parse(&file.to_json()).unwrap();
        assert_eq!(back, file);
        let mut broken = file.clone();
        broken.maps[0][0][0] = 0.5;
        assert!(CurveFile::parse(&broken.to_json()).is_err());
        assert!(CurveFile::parse("{}").is_err());
        assert!(CurveFile::parse("[1, 2]").is_err());
    }

    #[test]
    fn damaged_files_give_errors_not_panics() {
        // Valid files of each kind with bytes changed, cut or inserted at random.
        let curve = ProjectedCurve::bezier(vec![[0.0, 0.0], [1.0, 2.0], [3.0, 1.0]], 2);
        let seeds = [
            CurveFile::new(&curve, 8, false, None).to_json(),
            "x,y\n0,1\n2.5,-3e2\n4,5\n".to_string(),
            r#"<svg><path d="M1,2 l3-1 2,0 H10 v5 h-1e1 z"/><polyline points="0,0 1,1"/></svg>"#
                .to_string(),
        ];
        let alphabet = b"0123456789.,;-+eE MLHVZmlhvzC<>/\"=[]{}:\n\t#xy";
        let mut rng = crate::ifs::Rng::new(26);
        for seed in &seeds {
            for _ in 0..3000 {
                let mut bytes = seed.as_bytes().to_vec();
                for _ in 0..1 + rng.below(4) {
                    let at = rng.below(bytes.len() + 1);
                    let byte = alphabet[rng.below(alphabet.len())];
                    match rng.below(3) {
                        0 if at < bytes.len() => bytes[at] = byte,
                        1 if at < bytes.len() => {
                            bytes.truncate(at);
                        }
                        _ => bytes.insert(at, byte),
                    }
                }
                let text = String::from_utf8_lossy(&bytes);
                let _ = read_csv(&text);
                let _ = read_svg(&text);
                if let Ok(file) = CurveFile::parse(&text) {
                    // Whatever parses draws.
                    assert!(file.curve().tabulate(file.depth.min(6)).len() >= 2);
                }
            }
        }
    }
}

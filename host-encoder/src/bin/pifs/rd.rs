//! `pifs rd`: the rate/distortion curve of an image from one analysis: a table, and optionally
//! a CSV, an SVG plot beside other codecs' points, and the streams.

use crate::compare::{self, Series};
use crate::encode::{self, AnalysisArgs, Job};
use crate::error::{CliError, Result};
use crate::output::{self, Kind};
use clap::Args;
use host_encoder::{io, EncodeError, Target};
use std::fmt::Write;
use std::path::{Path, PathBuf};

/// Arguments of `pifs rd`.
#[derive(Args, Debug)]
pub struct RdArgs {
    /// Input image. A colour image is coded in colour (PSNR on RGB) unless --gray.
    pub input: PathBuf,
    /// Code the image's luma only (BT.601), even from a colour image.
    #[arg(long)]
    pub gray: bool,
    /// Rates to encode, bits per pixel (whole file), comma-separated.
    #[arg(long, value_delimiter = ',', default_values_t = [0.05, 0.1, 0.25, 0.5])]
    pub rates: Vec<f64>,
    /// Write the points as CSV: codec,bpp,psnr,bytes (codec is "pifs").
    #[arg(long, value_name = "FILE")]
    pub csv: Option<PathBuf>,
    /// Draw PSNR against bpp as an SVG.
    #[arg(long, value_name = "FILE")]
    pub plot: Option<PathBuf>,
    /// Other codecs' points to draw beside ours: a CSV as anchors.py writes.
    ///
    /// A header row and the columns codec, bpp, psnr (optional: status, image, target_bpp). Rows of
    /// this image are drawn when the image column names it, else each codec's mean per target.
    #[arg(long, value_name = "CSV", requires = "plot")]
    pub compare: Option<PathBuf>,
    /// Also write each stream into this directory (created if missing) as
    /// STEM-RATEbpp.pifs.
    #[arg(long, value_name = "DIR")]
    pub out_dir: Option<PathBuf>,
    #[command(flatten)]
    pub analysis: AnalysisArgs,
    #[command(flatten)]
    pub limits: encode::InputLimits,
}

/// One rate's outcome.
#[derive(Debug, Clone, PartialEq)]
pub enum Point {
    /// Encoded: bytes, bpp, PSNR dB.
    Reached {
        /// Stream size.
        bytes: usize,
        /// Its bits per pixel.
        bpp: f64,
        /// Its PSNR, dB.
        psnr: f64,
    },
    /// The rate's budget is below the smallest stream.
    BelowSmallest {
        /// The smallest stream, bytes.
        smallest: usize,
    },
}

/// Refuses an empty list or a rate that is not a positive number.
fn check_rates(rates: &[f64]) -> Result<()> {
    if rates.is_empty() {
        return Err(CliError::Refused("--rates needs at least one rate".into()));
    }
    if let Some(bad) = rates.iter().find(|r| !(r.is_finite() && **r > 0.0)) {
        return Err(CliError::Refused(format!(
            "--rates must be positive numbers, got {bad}"
        )));
    }
    Ok(())
}

/// Refuses an output directory that is a file or whose parent does not exist.
fn check_out_dir(dir: &Path) -> Result<()> {
    if dir.exists() && !dir.is_dir() {
        return Err(CliError::Refused(format!(
            "--out-dir {} is not a directory",
            dir.display()
        )));
    }
    Ok(())
}

/// The table printed on stdout.
pub fn table(rates: &[f64], points: &[Point]) -> String {
    let mut out = String::from("  rate asked      bytes       bpp   PSNR dB\n");
    for (rate, point) in rates.iter().zip(points) {
        let _ = match point {
            Point::Reached { bytes, bpp, psnr } => {
                writeln!(out, "  {rate:>10} {bytes:>10} {bpp:>9.4} {psnr:>9.2}")
            }
            Point::BelowSmallest { smallest } => writeln!(
                out,
                "  {rate:>10}   below the smallest stream ({smallest} bytes)"
            ),
        };
    }
    out
}

/// The CSV written by `--csv`.
pub fn csv(points: &[Point]) -> String {
    let mut out = String::from("codec,bpp,psnr,bytes\n");
    for p in points {
        if let Point::Reached { bytes, bpp, psnr } = p {
            let _ = writeln!(out, "pifs,{bpp:.5},{psnr:.4},{bytes}");
        }
    }
    out
}

/// `pifs rd`.
pub fn run(args: &RdArgs) -> Result<()> {
    check_rates(&args.rates)?;
    if let Some(csv) = &args.csv {
        output::check(csv, Some(&args.input), Kind::Csv)?;
    }
    if let Some(plot) = &args.plot {
        output::check(plot, Some(&args.input), Kind::Svg)?;
    }
    if let Some(dir) = &args.out_dir {
        check_out_dir(dir)?;
    }
    let name = args
        .input
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    // Read before the long analysis: a bad file fails at once.
    let others = match &args.compare {
        Some(path) => {
            let text = std::fs::read_to_string(path).map_err(|source| {
                CliError::File(io::FileError::Read {
                    path: path.clone(),
                    source,
                })
            })?;
            compare::parse(&text, &name)
                .map_err(|why| CliError::Refused(format!("{}: {why}", path.display())))?
        }
        None => Vec::new(),
    };
    let checked = encode::check_image(&args.input, &args.limits, &args.analysis, args.gray)?;
    checked.whole("rate/distortion curves are measured")?;
    let image = checked.decode(args.gray, args.analysis.depth)?;
    let targets: Vec<Target> = args.rates.iter().map(|&r| Target::Bpp(r)).collect();
    let analysed = encode::analyse_loaded(&image, &args.analysis, &targets)?;
    drop(image);
    let psnr = if analysed.analysis.channels() == 3 {
        "PSNR-RGB"
    } else {
        "PSNR"
    };
    if let Some(dir) = &args.out_dir {
        std::fs::create_dir_all(dir).map_err(|source| io::FileError::Write {
            path: dir.clone(),
            source,
        })?;
    }
    let stem = args
        .input
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "image".into());
    let mut points = Vec::new();
    for &rate in &args.rates {
        let job = Job {
            target: Target::Bpp(rate),
            is_default: false,
        };
        let point = match encode::encode_stream(&analysed.analysis, job) {
            Ok((encoded, _)) => {
                if let Some(dir) = &args.out_dir {
                    io::write_atomic(&dir.join(format!("{stem}-{rate}bpp.pifs")), &encoded.bytes)?;
                }
                Point::Reached {
                    bytes: encoded.bytes.len(),
                    bpp: analysed.bpp(encoded.bytes.len()),
                    psnr: encoded.psnr,
                }
            }
            Err(CliError::Encode(EncodeError::BudgetTooSmall { smallest, .. })) => {
                Point::BelowSmallest { smallest }
            }
            Err(e) => return Err(e),
        };
        points.push(point);
    }
    let (w, h) = analysed.size();
    say!(
        "{}: {w}x{h}, {}, one analysis in {:.2} s",
        args.input.display(),
        if psnr == "PSNR" {
            "gray"
        } else {
            "colour (PSNR on RGB)"
        },
        analysed.seconds
    );
    crate::say::text(table(&args.rates, &points));
    let ours: Vec<(f64, f64)> = points
        .iter()
        .filter_map(|p| match p {
            Point::Reached { bpp, psnr, .. } if psnr.is_finite() => Some((*bpp, *psnr)),
            _ => None,
        })
        .collect();
    if ours.is_empty() {
        return Err(CliError::Refused(
            "no rate reached: every one is below the smallest stream".into(),
        ));
    }
    if let Some(path) = &args.csv {
        io::write_atomic(path, csv(&points).as_bytes())?;
        say!("points written to {}", path.display());
    }
    if let Some(path) = &args.plot {
        let mut series = vec![Series {
            name: "pifs".into(),
            points: ours,
        }];
        series.extend(others.into_iter().map(|mut s| {
            if s.name == "pifs" {
                s.name = "pifs (compared)".into();
            }
            s
        }));
        let svg = crate::plot::rd_svg(&format!("{name}: {psnr} against rate"), &series).map_err(
            |cause| CliError::Plot {
                path: path.clone(),
                cause,
            },
        )?;
        io::write_atomic(path, svg.as_bytes())?;
        say!("curve drawn in {}", path.display());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_and_csv_show_every_reached_rate() {
        let points = [
            Point::BelowSmallest { smallest: 40 },
            Point::Reached {
                bytes: 120,
                bpp: 0.24,
                psnr: 31.234,
            },
        ];
        let t = table(&[0.05, 0.25], &points);
        assert!(t.contains("below the smallest stream (40 bytes)"), "{t}");
        assert!(
            t.contains("120") && t.contains("0.2400") && t.contains("31.23"),
            "{t}"
        );
        assert_eq!(
            csv(&points),
            "codec,bpp,psnr,bytes\npifs,0.24000,31.2340,120\n"
        );
        assert!(check_rates(&[]).is_err());
        assert!(check_rates(&[0.1, -1.0]).is_err());
        assert!(check_rates(&[0.1, 0.5]).is_ok());
    }
}

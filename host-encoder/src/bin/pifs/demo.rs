//! The demo: the bundled sample (embedded in the binary, so that an installed `pifs` has it
//! too) encoded at three rates from one analysis, and decoded, into `./pifs-demo/` under the
//! current directory.

use crate::encode::{self, AnalysisArgs, Job};
use crate::error::Result;
use host_encoder::{io, Target};
use std::path::{Path, PathBuf};

/// Kodak's kodim23 (see samples/SOURCES.md).
const SAMPLE: &[u8] = include_bytes!("../../../../samples/kodim23.png");

/// The sample's name, for messages and file names.
const SAMPLE_NAME: &str = "kodim23.png";

/// Where the demo writes, relative to the current directory.
pub const DEMO_DIR: &str = "pifs-demo";

/// The rates of the demo, bits per pixel.
const RATES: [f64; 3] = [0.05, 0.1, 0.25];

/// Runs the demo, writing into [`DEMO_DIR`] under the current directory.
pub fn run() -> Result<()> {
    let out = PathBuf::from(DEMO_DIR);
    std::fs::create_dir_all(&out).map_err(|source| io::FileError::Write {
        path: out.clone(),
        source,
    })?;
    say!(
        "pifs demo: encoding the bundled sample {SAMPLE_NAME} (Kodak kodim23, in colour) at {RATES:?} bpp into {}",
        shown(&out)
    );
    let image =
        io::DecodedImage::decode(SAMPLE, Path::new(SAMPLE_NAME), &io::ImageLimits::DEFAULT)?
            .into_loaded(false, io::Depth::Auto);
    let targets: Vec<Target> = RATES.iter().map(|&b| Target::Bpp(b)).collect();
    let analysed = encode::analyse_loaded(&image, &AnalysisArgs::default(), &targets)?;
    for &target in &targets {
        let Target::Bpp(bpp) = target else { continue };
        let stream = out.join(format!("kodim23-{bpp}bpp.pifs"));
        let job = Job {
            target,
            is_default: false,
        };
        encode::write_stream(&analysed, job, &stream)?;
        crate::decode::run(
            std::slice::from_ref(&stream),
            &stream.with_extension("png"),
            None,
            &decoder_core::Limits::NONE,
            crate::decode::Drawing {
                scale: decoder_core::Scale::One,
                packets: false,
                follow: false,
                hillshade: None,
                display: None,
            },
        )?;
    }
    say!(
        "streams and decoded images are in {} (see 'pifs --help' for encode, decode, info and rd)",
        shown(&out)
    );
    Ok(())
}

/// `path` in full when the current directory is known.
fn shown(path: &Path) -> String {
    std::env::current_dir()
        .map(|d| d.join(path))
        .unwrap_or_else(|_| path.to_path_buf())
        .display()
        .to_string()
}

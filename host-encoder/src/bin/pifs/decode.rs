//! `pifs decode`: a stream to an image file whose format the name's extension chooses.

use crate::error::{CliError, Result};
use crate::output::{self, Kind};
use decoder_core::{Decoder, Header, LeafInfo, Limits, Scale};
use host_encoder::io;
use std::path::Path;
use std::time::Instant;

/// The widest stripe the tool decodes: any the format allows (one byte per column, on the
/// stack while decoding).
pub const HOST_STRIPE: usize = 1 << 16;

/// Decodes the stream `data` read from `path` within `limits`: its header and pixels, and
/// every leaf when `leaves` is given.
pub fn decode_stream(
    path: &Path,
    data: &[u8],
    limits: &Limits,
    leaves: Option<&mut Vec<LeafInfo>>,
) -> Result<(Header, Vec<u8>)> {
    decode_scaled(path, data, limits, leaves, Scale::One).map(|(h, _, _, p)| (h, p))
}

/// A `--scale` value: `1/8`, `1/4`, `1/2`, `1`, `2` or `4` (or the same as a decimal, `0.25`).
pub fn parse_scale(text: &str) -> std::result::Result<Scale, String> {
    let value = match text.split_once('/') {
        Some((num, den)) => {
            let num: f64 = num
                .trim()
                .parse()
                .map_err(|_| format!("not a scale: {text}"))?;
            let den: f64 = den
                .trim()
                .parse()
                .map_err(|_| format!("not a scale: {text}"))?;
            num / den
        }
        None => text
            .trim()
            .parse()
            .map_err(|_| format!("not a scale: {text}"))?,
    };
    Scale::ALL
        .into_iter()
        .find(|s| (2f64.powi(s.log2()) - value).abs() < 1e-9)
        .ok_or_else(|| format!("scale {text}: one of 1/8, 1/4, 1/2, 1, 2, 4"))
}

/// [`decode_stream`] at `scale`: also returns the decoded image's width and height.
pub fn decode_scaled(
    path: &Path,
    data: &[u8],
    limits: &Limits,
    leaves: Option<&mut Vec<LeafInfo>>,
    scale: Scale,
) -> Result<(Header, u32, u32, Vec<u8>)> {
    let decoder = Decoder::new(data)
        .map_err(|e| CliError::stream(path, e))?
        .stripe_capacity::<HOST_STRIPE>();
    let decoder = decoder.limits(limits).map_err(|e| CliError::Stream {
        path: path.to_path_buf(),
        source: e,
        hint: Some("--max-pixels"),
    })?;
    let decoder = decoder.scale(scale);
    let header = *decoder.header();
    let (width, height) = decoder.output_size();
    let mut pixels = vec![0u8; width as usize * height as usize * usize::from(header.channels)];
    let decoded = match leaves {
        Some(list) => decoder
            .observe(|leaf: &LeafInfo| list.push(*leaf))
            .decode_into(&mut pixels),
        None => decoder.decode_into(&mut pixels),
    };
    let header = decoded.map_err(|e| CliError::stream(path, e))?;
    Ok((header, width, height, pixels))
}

/// `pifs decode`: refuses a bad output name before reading anything.
pub fn run(input: &Path, output: &Path, limits: &Limits) -> Result<()> {
    run_scaled(input, output, limits, Scale::One)
}

/// `pifs decode --scale`: [`run`] at `scale` of the coded size.
pub fn run_scaled(input: &Path, output: &Path, limits: &Limits, scale: Scale) -> Result<()> {
    let start = Instant::now();
    output::check(output, Some(input), Kind::Image)?;
    let data = io::read_stream(input)?;
    let (header, width, height, pixels) = decode_scaled(input, &data, limits, None, scale)?;
    let bytes = if header.channels == 3 {
        io::encode_rgb(output, width, height, &pixels)?
    } else {
        io::encode_gray(output, width, height, &pixels)?
    };
    io::write_atomic(output, &bytes)?;
    println!(
        "{}: {}x{} {} decoded in {:.1} ms",
        output.display(),
        width,
        height,
        if header.channels == 3 {
            "colour"
        } else {
            "gray"
        },
        start.elapsed().as_secs_f64() * 1e3
    );
    Ok(())
}

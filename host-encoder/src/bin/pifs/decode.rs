//! `pifs decode`: a stream to an image file whose format the name's extension chooses.

use crate::error::{CliError, Result};
use crate::output::{self, Kind};
use decoder_core::{Decoder, Header, LeafInfo, Limits};
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
    let decoder = Decoder::new(data)
        .map_err(|e| CliError::stream(path, e))?
        .stripe_capacity::<HOST_STRIPE>();
    let decoder = decoder.limits(limits).map_err(|e| CliError::Stream {
        path: path.to_path_buf(),
        source: e,
        hint: Some("--max-pixels"),
    })?;
    let header = *decoder.header();
    let mut pixels = vec![0u8; header.pixel_count() * usize::from(header.channels)];
    let decoded = match leaves {
        Some(list) => decoder
            .observe(|leaf: &LeafInfo| list.push(*leaf))
            .decode_into(&mut pixels),
        None => decoder.decode_into(&mut pixels),
    };
    let header = decoded.map_err(|e| CliError::stream(path, e))?;
    Ok((header, pixels))
}

/// `pifs decode`: refuses a bad output name before reading anything.
pub fn run(input: &Path, output: &Path, limits: &Limits) -> Result<()> {
    let start = Instant::now();
    output::check(output, Some(input), Kind::Image)?;
    let data = io::read_stream(input)?;
    let (header, pixels) = decode_stream(input, &data, limits, None)?;
    let bytes = io::encode_gray(
        output,
        u32::from(header.width),
        u32::from(header.height),
        &pixels,
    )?;
    io::write_atomic(output, &bytes)?;
    println!(
        "{}: {}x{} decoded in {:.1} ms",
        output.display(),
        header.width,
        header.height,
        start.elapsed().as_secs_f64() * 1e3
    );
    Ok(())
}

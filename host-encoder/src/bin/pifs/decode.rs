//! `pifs decode`: a stream to an image file whose format the name's extension (or `--format`)
//! chooses.
//!
//! The stream's header is read first and checked against `--max-pixels`; the image is written
//! row band by row band ([`io::decode_to_image`]), so memory follows the width, not the image.
//! A 16-bit stream is decoded whole to its values and written as a 16-bit image.

use crate::display::{self, Showing};
use crate::error::{CliError, Result};
use crate::output::{self, Kind};
use crate::say;
use decoder_core::graphics::Dither;
use decoder_core::{Header, LeafInfo, Limits, Scale};
use host_encoder::io::{self, Content, Output, OutputFormat, StreamInput};
use std::io::Write;
use std::path::Path;
use std::time::Instant;

/// Opens the stream at `path` (`-`: standard input) header first, within `limits`.
pub fn open_stream(path: &Path, limits: &Limits) -> Result<StreamInput> {
    StreamInput::open(path, limits).map_err(|e| match e {
        io::FileError::Stream {
            path,
            source: source @ decoder_core::DecodeError::TooLarge { .. },
        } => CliError::Stream {
            path,
            source,
            hint: Some("--max-pixels"),
        },
        // Standard input and devices are read as a stream, header first: framed packets
        // there need saying so.
        io::FileError::Stream {
            path,
            source: source @ decoder_core::DecodeError::BadMagic,
        } if !path.is_file() => CliError::Stream {
            path,
            source,
            hint: Some("--packets, for framed packets"),
        },
        other => other.into(),
    })
}

/// Decodes `input` into memory: its header and pixels, and every leaf when `leaves` is given
/// (for the drawing of `info --svg`).
pub fn decode_pixels(
    input: &StreamInput,
    leaves: Option<&mut Vec<LeafInfo>>,
) -> Result<(Header, Vec<u8>)> {
    let (decoder, failure) = input.decoder()?;
    let header = *decoder.header();
    let (width, height) = decoder.output_size();
    let mut pixels = vec![0u8; width as usize * height as usize * usize::from(header.channels)];
    let decoded = match leaves {
        Some(list) => decoder
            .observe(|leaf: &LeafInfo| list.push(*leaf))
            .decode_into(&mut pixels),
        None => decoder.decode_into(&mut pixels),
    };
    let header = decoded.map_err(|e| input.error(e, &failure))?;
    Ok((header, pixels))
}

/// Decodes the 16-bit stream `input` (at `scale`) into memory: its header and values.
pub fn decode_values(input: &StreamInput, scale: Scale) -> Result<(Header, Vec<u16>)> {
    let (decoder, failure) = input.decoder()?;
    let decoder = decoder.scale(scale);
    let (width, height) = decoder.output_size();
    let mut values = vec![0u16; width as usize * height as usize];
    let header = decoder
        .decode_values_into(&mut values)
        .map_err(|e| input.error(e, &failure))?;
    Ok((header, values))
}

/// A `--scale` value: `1/8`, `1/4`, `1/2`, `1`, `2` or `4` (or the same as a decimal, `0.25`).
pub fn parse_scale(text: &str) -> std::result::Result<Scale, String> {
    let number = |t: &str| -> std::result::Result<f64, String> {
        t.trim().parse().map_err(|_| format!("not a scale: {text}"))
    };
    let value = match text.split_once('/') {
        Some((num, den)) => number(num)? / number(den)?,
        None => number(text)?,
    };
    Scale::ALL
        .into_iter()
        .find(|s| (2f64.powi(s.log2()) - value).abs() < 1e-9)
        .ok_or_else(|| format!("scale {text}: one of 1/8, 1/4, 1/2, 1, 2, 4"))
}

/// The format to write: `--format` if given (a name whose extension names another format is
/// refused), else the name's extension; PNG on standard output.
pub fn output_format(output: &Path, chosen: Option<OutputFormat>) -> Result<OutputFormat> {
    if io::is_std_stream(output) {
        return Ok(chosen.unwrap_or(OutputFormat::Png));
    }
    let named = OutputFormat::from_path(output);
    match (chosen, named) {
        (None, named) => Ok(named?),
        (Some(chosen), Ok(named)) if chosen != named => Err(CliError::Refused(format!(
            "output {} is named as {} but --format asks for {}",
            output.display(),
            named.name(),
            chosen.name()
        ))),
        (Some(chosen), _) => Ok(chosen),
    }
}

/// A `--hillshade` value: the vertical exaggeration, or `auto`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ZFactor(pub Option<f64>);

/// Parses a `--hillshade` value: `auto` or a positive number.
pub fn parse_z_factor(text: &str) -> std::result::Result<ZFactor, String> {
    if text == "auto" {
        return Ok(ZFactor(None));
    }
    match text.parse::<f64>() {
        Ok(z) if z.is_finite() && z > 0.0 => Ok(ZFactor(Some(z))),
        _ => Err(format!(
            "not a vertical exaggeration: {text} (a positive number, or auto)"
        )),
    }
}

/// How `pifs decode` draws: at which scale, from packets or a stream, as the image, as a
/// hillshaded relief or as a panel shows it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Drawing {
    /// The output's scale of the coded size.
    pub scale: Scale,
    /// Read the input as packets.
    pub packets: bool,
    /// Read framed packets as they arrive, writing the picture after each.
    pub follow: bool,
    /// Draw the heights as a hillshaded relief, with this vertical exaggeration.
    pub hillshade: Option<ZFactor>,
    /// Draw the picture as a panel shows it.
    pub display: Option<Showing>,
}

/// `pifs decode`: refuses a bad output name before reading anything, a bad stream on its
/// header, then opens the output and writes the image at `scale` band by band.
pub fn run(
    inputs: &[std::path::PathBuf],
    output: &Path,
    format: Option<OutputFormat>,
    limits: &Limits,
    drawing: Drawing,
) -> Result<()> {
    let Drawing {
        scale,
        packets,
        follow,
        hillshade,
        display,
    } = drawing;
    let input = inputs.first().map_or(Path::new("-"), |p| p.as_path());
    let start = Instant::now();
    let chosen = format.is_some();
    let format = output_format(output, format)?;
    let kind = if chosen {
        Kind::ChosenImage
    } else {
        Kind::Image
    };
    for input in inputs {
        output::check(output, Some(input), kind)?;
    }
    if io::is_std_stream(output) {
        say::stdout_is_data();
    }
    let from_packets =
        packets || follow || inputs.len() > 1 || crate::packets::is_packet_input(input);
    if let Some(showing) = display {
        if hillshade.is_some() {
            return Err(CliError::Refused(
                "--display and --hillshade draw different pictures: one at a time".into(),
            ));
        }
        if !from_packets {
            return on_panel(input, output, format, limits, showing, scale, start);
        }
    }
    if let Some(ZFactor(z_factor)) = hillshade {
        if from_packets || scale != Scale::One {
            return Err(CliError::Refused(
                "--hillshade draws one stream at its coded size (not packets, no --scale)".into(),
            ));
        }
        return relief(input, output, format, limits, z_factor);
    }
    if from_packets {
        let max_pixels = limits.max_pixels;
        if follow {
            return crate::packets::follow(inputs, output, format, max_pixels, scale, display);
        }
        return crate::packets::decode(inputs, output, format, max_pixels, scale, display);
    }
    let stream = open_stream(input, limits)?;
    if stream.header().range.is_some() {
        return surface(&stream, output, format, scale, start);
    }
    let out = Output::create(output, Content::Binary("an image"))?;
    let name = out.name().to_path_buf();
    let (decoded, out) = io::decode_to_image(&stream, format, scale, out, &name, io::BAND_BYTES)?;
    out.commit()?;
    say!(
        "{}: {}x{} {} decoded in {:.1} ms",
        name.display(),
        decoded.width,
        decoded.height,
        if decoded.header.channels == 3 {
            "colour"
        } else {
            "gray"
        },
        start.elapsed().as_secs_f64() * 1e3
    );
    Ok(())
}

/// Writes the encoded image `bytes` to `output` (replaced atomically, never left partial);
/// the name it goes by, for messages.
pub fn write_image(output: &Path, bytes: &[u8]) -> Result<std::path::PathBuf> {
    let mut out = Output::create(output, Content::Binary("an image"))?;
    let name = out.name().to_path_buf();
    out.write_all(bytes).map_err(|e| out.error(e))?;
    out.commit()?;
    Ok(name)
}

/// `pifs decode --display`: the stream `input` as `panel` shows it, dithered by `dither`, at
/// `scale`.
fn on_panel(
    input: &Path,
    output: &Path,
    format: OutputFormat,
    limits: &Limits,
    showing: Showing,
    scale: Scale,
    start: Instant,
) -> Result<()> {
    let stream = open_stream(input, limits)?;
    if stream.header().range.is_some() {
        return Err(CliError::Refused(format!(
            "--display draws pictures; {} is a 16-bit surface",
            stream.name().display()
        )));
    }
    let (decoder, failure) = stream.decoder()?;
    let decoder = decoder.scale(scale);
    let (width, height) = decoder.output_size();
    let channels = decoder.header().channels;
    let mut pixels = vec![0u8; width as usize * height as usize * usize::from(channels)];
    decoder
        .decode_into(&mut pixels)
        .map_err(|e| stream.error(e, &failure))?;
    let decoded = display::Picture {
        width,
        height,
        channels,
        pixels,
    };
    let shown = display::show_picture(&decoded, showing);
    let encoded = format.encode(
        output,
        shown.width,
        shown.height,
        shown.channels,
        &shown.pixels,
    )?;
    let name = write_image(output, &encoded)?;
    say!(
        "{}: {}x{} as a {} panel shows it ({}) in {:.1} ms",
        name.display(),
        shown.width,
        shown.height,
        display::panel_name(showing.panel),
        match showing.dither {
            Dither::Ordered => "ordered dither",
            Dither::Nearest => "nearest levels",
        },
        start.elapsed().as_secs_f64() * 1e3
    );
    Ok(())
}

/// `pifs decode` of a 16-bit stream: its values, as a 16-bit image.
fn surface(
    stream: &StreamInput,
    output: &Path,
    format: OutputFormat,
    scale: Scale,
    start: Instant,
) -> Result<()> {
    let (header, values) = decode_values(stream, scale)?;
    let (width, height) = (
        scale.apply(header.width.into()),
        scale.apply(header.height.into()),
    );
    let bytes = format.encode_values(output, width, height, &values)?;
    let name = write_image(output, &bytes)?;
    let (low, high) = header.range.map_or((0, 0), |r| (r.low, r.high()));
    say!(
        "{}: {width}x{height} 16-bit surface ({low}..{high}) decoded in {:.1} ms",
        name.display(),
        start.elapsed().as_secs_f64() * 1e3
    );
    Ok(())
}

/// `pifs decode --hillshade`: the grayscale stream `input` decoded and drawn as a relief.
fn relief(
    input: &Path,
    output: &Path,
    format: OutputFormat,
    limits: &Limits,
    z_factor: Option<f64>,
) -> Result<()> {
    let start = Instant::now();
    let stream = open_stream(input, limits)?;
    // Refused on its header, before anything is decoded.
    if stream.header().channels != 1 {
        return Err(CliError::Refused(format!(
            "--hillshade needs a grayscale stream (its values are the heights); {} is colour",
            input.display()
        )));
    }
    // A 16-bit stream's heights are its values (finer than its grey).
    let (header, heights): (Header, Vec<f64>) = if stream.header().range.is_some() {
        let (header, values) = decode_values(&stream, Scale::One)?;
        (header, values.iter().map(|&v| f64::from(v)).collect())
    } else {
        let (header, pixels) = decode_pixels(&stream, None)?;
        (header, pixels.iter().map(|&p| f64::from(p)).collect())
    };
    let (width, height) = (usize::from(header.width), usize::from(header.height));
    let light = host_encoder::relief::Light {
        z_factor,
        ..Default::default()
    };
    let shade = host_encoder::relief::hillshade(&heights, width, height, &light);
    let bytes = format.encode(
        output,
        u32::from(header.width),
        u32::from(header.height),
        1,
        &shade,
    )?;
    let name = write_image(output, &bytes)?;
    say!(
        "{}: {}x{} hillshaded relief decoded in {:.1} ms",
        name.display(),
        width,
        height,
        start.elapsed().as_secs_f64() * 1e3
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_format_comes_from_the_option_or_the_name() {
        let f = |out: &str, chosen| output_format(Path::new(out), chosen);
        assert_eq!(f("-", None).unwrap(), OutputFormat::Png);
        assert_eq!(f("-", Some(OutputFormat::Pgm)).unwrap(), OutputFormat::Pgm);
        assert_eq!(f("x.ppm", None).unwrap(), OutputFormat::Ppm);
        assert_eq!(f("x", Some(OutputFormat::Pgm)).unwrap(), OutputFormat::Pgm);
        assert_eq!(
            f("x.PGM", Some(OutputFormat::Pgm)).unwrap(),
            OutputFormat::Pgm
        );
        assert!(f("x", None).is_err());
        let err = f("x.png", Some(OutputFormat::Pgm)).unwrap_err();
        assert_eq!(
            err.to_string(),
            "output x.png is named as png but --format asks for pgm"
        );
    }
}

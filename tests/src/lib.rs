//! Support shared by the integration tests and the fuzz targets (`fuzz/`): a pixel sink that
//! checks the sink contract, and the fuzz checks themselves, so that the corpus replay under
//! `cargo test` and `cargo fuzz` run the very same assertions.

pub mod fuzz;

/// The README's code examples, compiled (and run where they can be) by `cargo test`, so that
/// they cannot drift from the API.
#[cfg(doctest)]
#[doc = include_str!("../../README.md")]
pub struct ReadmeExamples;

use decoder_core::{ByteSource, DecodeError, Decoder, Header, PixelSink, Rect, Tile};
use std::convert::Infallible;

/// A [`decoder_core::PixelSink`] that records how often every pixel of a `width x height` image
/// is written, the last value written, and any tile that breaks the sink contract (out of the
/// image, larger than [`decoder_core::TILE`], `pixels.len() != w * h`, or values that are
/// neither absent nor one per pixel), and the tiles that carried values and their extremes.
pub struct CoverageSink {
    pub width: u32,
    pub height: u32,
    pub counts: Vec<u32>,
    pub pixels: Vec<u8>,
    pub tiles: usize,
    pub violations: Vec<String>,
    /// Values per pixel of the tiles (1 until a colour tile comes: `pixels` then holds RGB).
    pub channels: usize,
    /// Tiles that carried values (a 16-bit stream's, [`Tile::values`]).
    pub tiles_with_values: usize,
    /// The smallest and largest value any tile carried.
    pub value_extremes: Option<(u16, u16)>,
}

impl CoverageSink {
    pub fn new(width: u32, height: u32) -> Self {
        let n = width as usize * height as usize;
        CoverageSink {
            width,
            height,
            counts: vec![0; n],
            pixels: vec![0; n],
            tiles: 0,
            violations: Vec::new(),
            channels: 1,
            tiles_with_values: 0,
            value_extremes: None,
        }
    }

    /// Pixels written a number of times other than once: `(x, y, count)`, at most `limit`.
    pub fn not_once(&self, limit: usize) -> Vec<(u32, u32, u32)> {
        self.counts
            .iter()
            .enumerate()
            .filter(|(_, &c)| c != 1)
            .take(limit)
            .map(|(i, &c)| {
                (
                    (i % self.width as usize) as u32,
                    (i / self.width as usize) as u32,
                    c,
                )
            })
            .collect()
    }
}

impl decoder_core::PixelSink for CoverageSink {
    type Error = Infallible;

    fn tile(&mut self, tile: Tile<'_>) -> Result<(), Infallible> {
        let Rect { x, y, w, h } = tile.area;
        let (pixels, values) = (tile.pixels, tile.values);
        self.tiles += 1;
        let ch = usize::from(tile.channels);
        if self.tiles == 1 && ch == 3 {
            self.channels = 3;
            self.pixels = vec![0; 3 * self.counts.len()];
        }
        if ch != self.channels {
            self.violations.push(format!(
                "tile at ({x}, {y}): {ch} channels, not {}",
                self.channels
            ));
            return Ok(());
        }
        let tile = decoder_core::TILE as u32;
        if w == 0 || h == 0 || w > tile || h > tile {
            self.violations
                .push(format!("tile {w}x{h} at ({x}, {y}): bad tile size"));
        }
        if pixels.len() != w as usize * h as usize * ch {
            self.violations.push(format!(
                "tile {w}x{h} at ({x}, {y}): {} pixels",
                pixels.len()
            ));
            return Ok(());
        }
        if !values.is_empty() {
            self.tiles_with_values += 1;
            if values.len() != pixels.len() {
                self.violations.push(format!(
                    "tile {w}x{h} at ({x}, {y}): {} values",
                    values.len()
                ));
            }
            for &v in values {
                let (lo, hi) = self.value_extremes.unwrap_or((v, v));
                self.value_extremes = Some((lo.min(v), hi.max(v)));
            }
        }
        if u64::from(x) + u64::from(w) > u64::from(self.width)
            || u64::from(y) + u64::from(h) > u64::from(self.height)
        {
            self.violations.push(format!(
                "tile {w}x{h} at ({x}, {y}) outside the {}x{} image",
                self.width, self.height
            ));
            return Ok(());
        }
        let mut k = 0;
        for py in y..y + h {
            for px in x..x + w {
                let i = py as usize * self.width as usize + px as usize;
                self.counts[i] += 1;
                self.pixels[i * ch..(i + 1) * ch].copy_from_slice(&pixels[k * ch..(k + 1) * ch]);
                k += 1;
            }
        }
        Ok(())
    }
}

/// Decodes a whole stream in memory into `sink` ([`Decoder::new`] then [`Decoder::decode`]).
pub fn decode<S: PixelSink<Error = Infallible>>(
    data: &[u8],
    sink: &mut S,
) -> Result<Header, DecodeError> {
    Ok(Decoder::new(data)?.decode(sink)?)
}

/// Decodes a whole stream in memory into a row-major buffer.
pub fn decode_into(data: &[u8], out: &mut [u8]) -> Result<Header, DecodeError> {
    Decoder::new(data)?.decode_into(out)
}

/// Decodes a stream read from `source` in order into `sink`.
pub fn decode_stream<B: ByteSource, S: PixelSink<Error = Infallible>>(
    source: B,
    sink: &mut S,
) -> Result<Header, DecodeError> {
    Ok(Decoder::from_source(source)?.decode(sink)?)
}

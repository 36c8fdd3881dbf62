//! # decoder-core
//!
//! The `no_std`, allocation-free decoder of the PIFS image format: a quadtree of projected-IFS
//! patches (E. Guérin's thesis, 2002) coded with an adaptive binary arithmetic coder.
//!
//! The crate is also the one definition of the bitstream: the host encoder writes streams with
//! the same syntax code ([`bitstream`], [`quadtree`]) and judges its choices with the same
//! reconstruction ([`patch`]), so what the encoder measures is what a device shows.
//!
//! Layout:
//! - [`bitstream`]: the header and every payload syntax element (where a byte is parsed);
//! - [`entropy`]: the range decoder and the binarisations;
//! - [`model`]: model types, subdivision rules, quantisers;
//! - [`patch`]: integer patch synthesis (where a pixel is made);
//! - [`prediction`]: the pixel frontier a leaf's values are predicted from;
//! - [`quadtree`]: the walk over the quadtree cut;
//! - [`stream`]: decoding from a sequential [`entropy::ByteSource`] (no stream in RAM) and
//!   decoding of a clip rectangle only;
//! - `graphics` (cargo feature `embedded-graphics`): a stream as an embedded-graphics image.
//!
//! ```
//! # fn demo(stream: &[u8]) -> Result<(), decoder_core::DecodeError> {
//! let header = decoder_core::read_header(stream)?;
//! let mut pixels = vec![0u8; header.pixel_count()];
//! decoder_core::decode_into(stream, &mut pixels)?;
//! # Ok(()) }
//! ```
#![no_std]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod bitstream;
pub mod checksum;
pub mod entropy;
mod error;
pub mod initial_contexts;
pub mod model;
pub mod patch;
pub mod prediction;
pub mod quadtree;
pub mod stream;

#[cfg(feature = "embedded-graphics")]
pub mod graphics;

pub use bitstream::{Header, LeafSyntax};
pub use error::DecodeError;
pub use patch::{PixelSink, Rect};
pub use stream::{decode_region, decode_stream, decode_stream_region, MAX_HEADER_LEN};

use entropy::{RangeDecoder, SliceSource};
use patch::Patch;
use prediction::Frontier;
pub use quadtree::LeafInfo;
use quadtree::{Node, TreeVisitor};

/// Reads and validates the header of a stream.
pub fn read_header(data: &[u8]) -> Result<Header, DecodeError> {
    Header::parse(data).map(|(h, _)| h)
}

/// Bounds a caller sets on the images it accepts, checked on the header alone, before anything
/// is drawn or allocated (a host decoding into a buffer it allocates should always set them:
/// a 17-byte header can announce a 65535 x 65535 image).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Limits {
    /// Largest accepted width.
    pub max_width: u16,
    /// Largest accepted height.
    pub max_height: u16,
    /// Largest accepted `width * height`.
    pub max_pixels: u64,
}

impl Limits {
    /// No bound beyond the format's own (65535 x 65535).
    pub const NONE: Limits = Limits {
        max_width: u16::MAX,
        max_height: u16::MAX,
        max_pixels: u64::MAX,
    };

    /// At most `max_pixels` pixels, any shape.
    pub const fn pixels(max_pixels: u64) -> Limits {
        Limits {
            max_pixels,
            ..Limits::NONE
        }
    }

    /// `Ok` when `header` describes an image within these bounds, else
    /// [`DecodeError::TooLarge`].
    pub fn check(&self, header: &Header) -> Result<(), DecodeError> {
        let pixels = u64::from(header.width) * u64::from(header.height);
        if header.width > self.max_width
            || header.height > self.max_height
            || pixels > self.max_pixels
        {
            return Err(DecodeError::TooLarge {
                width: header.width,
                height: header.height,
            });
        }
        Ok(())
    }
}

/// A [`PixelSink`] that also hears about every leaf (for inspection tools).
pub trait LeafObserver {
    /// Called for every leaf, in coding order, before its pixels.
    fn leaf(&mut self, info: &LeafInfo);
}

struct Drawer<'s, S: PixelSink, O: LeafObserver> {
    clip: Rect,
    sink: &'s mut S,
    observer: O,
}

impl<S: PixelSink, O: LeafObserver> TreeVisitor for Drawer<'_, S, O> {
    fn split(&mut self, _node: &Node) -> bool {
        false
    }

    fn prepare_leaf(&mut self, _node: &Node, _leaf: &mut LeafSyntax) {}

    fn leaf(&mut self, info: &LeafInfo, patch: &Patch) -> Result<(), DecodeError> {
        self.observer.leaf(info);
        let node = &info.node;
        patch.render(node.x, node.y, node.log2, self.clip, self.sink);
        Ok(())
    }

    // The whole image is drawn: the frontier learns each leaf's edges as they are drawn.
    fn leaf_with_frontier(
        &mut self,
        info: &LeafInfo,
        patch: &Patch,
        frontier: &mut Frontier,
    ) -> Result<(), DecodeError> {
        self.observer.leaf(info);
        let node = &info.node;
        let mut sink = frontier.capture(node, self.sink);
        patch.render(node.x, node.y, node.log2, self.clip, &mut sink);
        Ok(())
    }
}

struct NoObserver;

impl LeafObserver for NoObserver {
    fn leaf(&mut self, _info: &LeafInfo) {}
}

/// Decodes a stream, handing pixels to `sink` tile by tile (no frame buffer needed).
pub fn decode<S: PixelSink>(data: &[u8], sink: &mut S) -> Result<Header, DecodeError> {
    decode_observed(data, sink, NoObserver).map(|(h, _)| h)
}

/// Decodes a stream like [`decode`], also reporting every leaf to `observer`; returns the header
/// and the observer.
pub fn decode_observed<S: PixelSink, O: LeafObserver>(
    data: &[u8],
    sink: &mut S,
    observer: O,
) -> Result<(Header, O), DecodeError> {
    let (header, payload) = stream::open(data)?;
    let mut coder = RangeDecoder::new(SliceSource::new(payload))?;
    let clip = Rect::of_size(u32::from(header.width), u32::from(header.height));
    let mut drawer = Drawer {
        clip,
        sink,
        observer,
    };
    stream::run_walk(&header, &mut coder, &mut drawer)?;
    stream::Payload::finish(coder.into_source(), &header)?;
    Ok((header, drawer.observer))
}

struct BufferSink<'a> {
    out: &'a mut [u8],
    width: usize,
}

impl PixelSink for BufferSink<'_> {
    fn tile(&mut self, x: u32, y: u32, w: u32, h: u32, pixels: &[u8]) {
        let (x, y, w, h) = (x as usize, y as usize, w as usize, h as usize);
        for (row, src) in pixels.chunks_exact(w).take(h).enumerate() {
            let start = (y + row) * self.width + x;
            if let Some(dst) = self.out.get_mut(start..start + w) {
                dst.copy_from_slice(src);
            }
        }
    }
}

/// Decodes a stream into `out` (row-major, `width * height` bytes for grayscale).
pub fn decode_into(data: &[u8], out: &mut [u8]) -> Result<Header, DecodeError> {
    let header = read_header(data)?;
    if out.len() < header.pixel_count() * usize::from(header.channels) {
        return Err(DecodeError::BufferTooSmall);
    }
    let mut sink = BufferSink {
        out,
        width: usize::from(header.width),
    };
    decode(data, &mut sink)
}

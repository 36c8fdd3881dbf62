//! # decoder-core
//!
//! The `no_std`, allocation-free decoder of the PIFS image format: a quadtree of projected-IFS
//! patches (E. Guérin's thesis, 2002) coded with an adaptive binary arithmetic coder. Memory is
//! fixed at compile time (a few KiB of stack, no frame buffer), reconstruction is integer and
//! bit-exact on every platform, and no input makes it panic: every malformed stream is a
//! [`DecodeError`], and a release build has no panic path at all (a Cortex-M firmware links no
//! panic location of this crate, which the QEMU tests check).
//!
//! ```
//! # fn demo(stream: &[u8]) -> Result<(), decoder_core::DecodeError> {
//! use decoder_core::{Decoder, Limits};
//!
//! let decoder = Decoder::new(stream)?.limits(&Limits::pixels(1 << 24))?;
//! let mut pixels = vec![0u8; decoder.header().pixel_count()];
//! decoder.decode_into(&mut pixels)?;
//! # Ok(()) }
//! ```
//!
//! ## The public surface
//!
//! - [`Decoder`]: the one entry point, over a stream in memory ([`Decoder::new`]) or a
//!   sequential [`ByteSource`] ([`Decoder::from_source`]), optionally cut to a [`Rect`]
//!   ([`Decoder::clip`]) or bounded by [`Limits`]; decodes into a [`PixelSink`] (tile by tile,
//!   no frame buffer) or a buffer. It keeps a byte per column of the stream's stripes (two
//!   in colour), for stripes of up to 512 pixels unless [`Decoder::stripe_capacity`] gives
//!   more: a stream coded as one stripe wider than that (the reference encoder's default for
//!   wider images) is refused with [`DecodeError::StripeTooWide`]; a host gives 65536.
//! - [`PixelSink`] receives [`Tile`]s of at most [`TILE`] x [`TILE`] pixels and may fail; its
//!   error ends the decode as [`DrawError::Sink`].
//! - [`Header`]: the image's size and format fields; [`LeafInfo`] (with [`Node`] and
//!   [`ControlCoding`]) describes each leaf to a [`Decoder::observe`] callback.
//! - 16-bit streams (cargo feature `deep`, on by default): surfaces such as elevation models,
//!   whose [`Header::range`] ([`SampleRange`]) gives each pixel a value in the data's units,
//!   finer than its grey: [`Tile::values`], [`Decoder::decode_values_into`].
//! - Errors: [`DecodeError`] (with [`HeaderField`] and [`SyntaxElement`]), [`DrawError`];
//!   with the cargo feature `defmt` they implement `defmt::Format`, so a firmware that logs
//!   with defmt prints them without `core::fmt`.
//! - [`Packet`]: an image sent as self-contained packets for lossy links (`docs/bitstream.md`,
//!   section 9): [`Packet::parse`] checks one (its CRC-16 first), [`Packet::decode`] draws its
//!   region, in image coordinates, into the same [`PixelSink`]s; a preview packet that arrives
//!   after some regions is drawn around them ([`Packet::decode_around`]). A receiver needs one
//!   packet's buffer and the decoder's usual fixed memory. A receiver with room for an image's
//!   packets rebuilds lost ones from parity packets ([`ParityPacket`]) with [`Rebuild`], in a
//!   buffer it lends, the packets added as they arrive.
//! - `graphics` (cargo feature `embedded-graphics`): a stream as an embedded-graphics
//!   `ImageDrawable` in any colour type, ordered-dithered by default where the colour has
//!   fewer than 8 bits a channel (a 1-bit OLED, RGB565); `graphics::DrawSink`, the same
//!   drawing as a [`PixelSink`], draws packets as they arrive.
//!
//! ## Scaled decoding
//!
//! [`Decoder::scale`] decodes at 1/8, 1/4 or 1/2 of the coded size by stopping the subdivision
//! early (pixel `(X, Y)` is pixel `(X 2^k, Y 2^k)` of the full decode), or at 2 or 4 times it by
//! letting the subdivision continue below the pixel ([`Scale`]), each leaf closing the smoothed
//! steps at its top and left edges on its own side (cargo feature `smooth-enlarged`, on by
//! default); the embedded-graphics image has `graphics::PifsImage::with_scale`.
//!
//! ## The patches are IFS attractors
//!
//! A leaf's patch is a projected IFS (Guérin's thesis, II.1): the attractor of the maps
//! `W_k(s, t, x) = ((j + s) / N, (i + t) / N, T_k x)`, one per child `k = (i, j)`, with `T_k` the
//! subdivision matrices acting on barycentric coordinates `x` over the control points, seen
//! through the control values (`F(s, t) = P x`). This crate tabulates it by recursive
//! subdivision in integers. The host encoder's `ifs` module draws the same attractor the
//! classic ways, in floating point from matrices it builds from the specification's rules: by
//! the chaos game (random iteration from a control point, which lies on the attractor) and by
//! the Hutchinson iteration (the union of the images under every map). Its tests
//! (`host-encoder/tests/ifs.rs`) check, for every model with random control points, that every
//! point both draw is within one grey level of this
//! crate's pixel at that parameter (the tabulation rounds each level to 1/16 grey level), and
//! that the chaos game draws the Sierpinski triangle and Barnsley's fern of the seed paper;
//! `cargo run -p host-encoder --example ifs` draws them.
//!
//! ## Inside
//!
//! The modules are layered, each using only those below it: the format's shared vocabulary
//! (constants, geometry, the CRC), errors, entropy coding (the range decoder), the patch models,
//! synthesis (where a pixel is made), prediction (the pixel frontier), syntax (where a byte is
//! parsed), the quadtree walk, the decoder API, the embedded-graphics adapter. The host encoder
//! runs the same syntax and synthesis code (through `decoder_core::internal`, which is not part
//! of the public API), so what it measures is what a device shows. `docs/bitstream.md` is the
//! specification.
#![no_std]
#![forbid(unsafe_code)]
#![deny(missing_docs, missing_debug_implementations)]
#![deny(rustdoc::broken_intra_doc_links)]

mod checksum;
mod colour;
mod decoder;
mod entropy;
mod error;
mod format;
mod geometry;
mod model;
mod packet;
mod parity;
mod prediction;
mod syntax;
mod synthesis;
mod walk;

#[cfg(feature = "embedded-graphics")]
pub mod graphics;

pub use decoder::{Decoder, InMemory, Input, Limits, Streamed};
pub use entropy::{ByteSource, SliceSource};
pub use error::{DecodeError, DrawError, HeaderField, SyntaxElement};
pub use format::{PACKET_TAG, STREAM_TAG, VERSION};
pub use geometry::{Node, Rect};
pub use packet::{Packet, PacketKind, REGION_UNIT};
pub use parity::{ParityPacket, Rebuild, RebuildError};
pub use syntax::{ControlCoding, Header, SampleRange, MAX_HEADER_LEN};
pub use synthesis::{PixelSink, Scale, Tile, TILE};
pub use walk::LeafInfo;

/// The format's machinery that the host encoder and the project's tests share with this
/// decoder: the syntax, the entropy coder, the models, synthesis, prediction and the walk.
///
/// Not part of the public API: no stability promise, and nothing here is needed to decode.
#[doc(hidden)]
pub mod internal {
    /// See the crate's `checksum` module.
    pub mod checksum {
        pub use crate::checksum::*;
    }
    /// See the crate's `colour` module.
    pub mod colour {
        pub use crate::colour::*;
    }
    /// See the crate's `entropy` module.
    pub mod entropy {
        pub use crate::entropy::*;
    }
    /// See the crate's `format` module.
    pub mod format {
        pub use crate::format::*;
    }
    /// See the crate's `geometry` module.
    pub mod geometry {
        pub use crate::geometry::*;
    }
    /// See the crate's `model` module.
    pub mod model {
        pub use crate::model::*;
    }
    /// See the crate's `packet` module.
    pub mod packet {
        pub use crate::packet::*;
    }
    /// See the crate's `parity` module.
    pub mod parity {
        pub use crate::parity::*;
    }
    /// See the crate's `prediction` module.
    pub mod prediction {
        pub use crate::prediction::*;
    }
    /// See the crate's `syntax` module.
    pub mod syntax {
        pub use crate::syntax::*;
    }
    /// See the crate's `synthesis` module.
    pub mod synthesis {
        pub use crate::synthesis::*;
    }
    /// See the crate's `walk` module.
    pub mod walk {
        pub use crate::walk::*;
    }
}

#[cfg(test)]
mod layering {
    extern crate std;

    use std::string::String;
    use std::vec::Vec;

    /// The modules from the bottom up: each may use only those before it (and its own
    /// submodules).
    const LAYERS: &[&[&str]] = &[
        &["format", "geometry", "checksum"],
        &["error"],
        &["entropy"],
        &["model"],
        &["synthesis"],
        &["prediction"],
        &["colour"],
        &["syntax"],
        &["walk"],
        &["decoder"],
        &["packet"],
        &["graphics"],
    ];

    fn layer(module: &str) -> usize {
        LAYERS
            .iter()
            .position(|l| l.contains(&module))
            .unwrap_or_else(|| panic!("module {module} has no layer"))
    }

    /// Every `crate::<module>` a source file names, outside comments.
    fn uses(source: &str) -> Vec<String> {
        let mut out = Vec::new();
        for line in source.lines() {
            let code = line.split("//").next().unwrap_or("");
            let mut rest = code;
            while let Some(at) = rest.find("crate::") {
                let name: String = rest[at + 7..]
                    .chars()
                    .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
                    .collect();
                out.push(name);
                rest = &rest[at + 7..];
            }
        }
        out
    }

    /// No module uses one above it: the layering has no cycle. Read from the sources, so a new
    /// `use` that breaks it fails here.
    #[test]
    fn modules_use_only_the_layers_below() {
        let src = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
        let mut checked = 0;
        for layer_modules in LAYERS {
            for &module in *layer_modules {
                let mut files = Vec::new();
                let file = src.join(std::format!("{module}.rs"));
                files.push(file);
                if let Ok(dir) = std::fs::read_dir(src.join(module)) {
                    files.extend(dir.flatten().map(|e| e.path()));
                }
                for file in files {
                    let text = std::fs::read_to_string(&file)
                        .unwrap_or_else(|e| panic!("{}: {e}", file.display()));
                    for used in uses(&text) {
                        if used == module {
                            continue;
                        }
                        assert!(
                            layer(&used) < layer(module),
                            "{} uses crate::{used}, which is not below {module}",
                            file.display()
                        );
                    }
                    checked += 1;
                }
            }
        }
        assert!(checked >= 13, "only {checked} files checked");
    }
}

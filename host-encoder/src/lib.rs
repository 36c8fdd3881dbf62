//! # host-encoder
//!
//! The encoder of the PIFS format (a quadtree of projected-IFS patches, after E. Guérin's
//! thesis) and the library behind the `pifs` command-line tool.
//!
//! An image is analysed once ([`analyse`]: every model fitted at every quadtree node, every
//! quantiser tried); the [`Analysis`] then encodes any number of targets
//! ([`Analysis::encode`]: a rate, a size or a quality).
//!
//! ```no_run
//! use host_encoder::{analyse, EncoderConfig, Plane, Target};
//! let plane = Plane::new(2, 2, vec![0, 64, 128, 255]);
//! let analysis = analyse(plane, &EncoderConfig::default(), &|_| {}).unwrap();
//! let small = analysis.encode(Target::Bpp(0.25)).unwrap();
//! let good = analysis.encode(Target::Psnr(30.0)).unwrap();
//! # let _ = (small, good);
//! ```
//!
//! [`ifs`] draws iterated function systems the classic ways (the chaos game and the Hutchinson
//! iteration): the Sierpinski triangle and Barnsley's fern, and any decoder patch as the
//! attractor of its projected IFS. Its tests check that decoder-core's integer tabulation of a
//! patch is that attractor, up to the tabulation's roundings (`cargo run --example ifs` draws
//! them).
//!
//! The `pifs` tool is behind the default cargo feature `cli`; a library user writes
//! `host-encoder = { version = "…", default-features = false }` and gets no command-line
//! dependencies (`clap`, `indicatif`, `plotters`).
#![deny(
    missing_docs,
    missing_debug_implementations,
    rustdoc::broken_intra_doc_links
)]

mod encoder;
mod entropy;
pub mod ifs;
#[doc(hidden)]
pub mod internal;
pub mod io;
pub mod packets;

pub use encoder::{
    analyse, analyse_colour, psnr, Analysis, AnalysisTiming, ColourPlanes, EncodeError, Encoded,
    EncoderConfig, Plane, Target, CHROMA_WEIGHTS, MIN_TRIAL_BPP,
};

//! # host-encoder
//!
//! The encoder of the PIFS format (a quadtree of projected-IFS patches, after E. Guérin's
//! thesis) and the library behind the `pifs` command-line tool.
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
//! The `pifs` tool is behind the default cargo feature `cli`; a library user writes
//! `host-encoder = { version = "…", default-features = false }` and gets no command-line
//! dependencies (`clap`, `indicatif`, `plotters`).
#![deny(missing_docs)]
#![deny(rustdoc::broken_intra_doc_links)]
// To be denied as well once the encoder's `ImagePrediction`, `ControlTargets` and `Quantised`
// implement `Debug` (the encoder's restructuring adds them):
// #![deny(missing_debug_implementations)]

pub mod encoder;
pub mod entropy;
pub mod io;

pub use encoder::analysis::Analysis;
pub use encoder::{
    analyse, psnr, EncodeError, Encoded, EncoderConfig, Plane, Target, MIN_TRIAL_BPP,
};

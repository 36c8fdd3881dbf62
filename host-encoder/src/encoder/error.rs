//! Why an analysis or an encode fails.
//!
//! Above [`super::config`] (an error names the target it refused); below every stage.

use super::config::Target;
use decoder_core::DecodeError;
use std::fmt;

/// Why an encode failed.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum EncodeError {
    /// The image is larger than the format allows (65535 per side) or empty.
    BadDimensions {
        /// Width of the image, pixels.
        width: u32,
        /// Height of the image, pixels.
        height: u32,
    },
    /// The target is not a positive finite number.
    BadTarget(Target),
    /// Even the smallest stream is larger than the budget.
    BudgetTooSmall {
        /// The budget, bytes.
        budget: usize,
        /// The smallest stream the encoder can write for this image, bytes.
        smallest: usize,
    },
    /// The PSNR cannot be reached.
    QualityUnreachable {
        /// Requested PSNR, dB.
        requested: f64,
        /// Best reachable, dB: the PSNR of the analysis's highest-quality stream (the one a
        /// budget of unlimited bytes writes from it), so that any target up to it is met.
        best: f64,
    },
    /// The shared syntax code refused what the encoder asked it to write (a bug).
    Syntax(DecodeError),
    /// The encoder's own bookkeeping is inconsistent (a bug); the text says what was found.
    Internal(&'static str),
    /// What was asked is not supported; the text says what.
    Unsupported(&'static str),
}

impl fmt::Display for EncodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            EncodeError::BadDimensions { width, height } => write!(
                f,
                "image size {width}x{height} is not supported (1 to 65535 per side)"
            ),
            EncodeError::BadTarget(t) => write!(f, "invalid target: {t}"),
            EncodeError::BudgetTooSmall { budget, smallest } => {
                write!(f, "budget of {budget} bytes is too small: the smallest stream for this image is {smallest} bytes")
            }
            EncodeError::QualityUnreachable { requested, best } => {
                // Rounded down: a target of the figure shown is reachable.
                let best = (best * 100.0).floor() / 100.0;
                write!(f, "PSNR {requested:.2} dB is unreachable: the best this encoder reaches is {best:.2} dB")
            }
            EncodeError::Syntax(_) => {
                write!(f, "internal encoder error: the syntax refused a leaf")
            }
            EncodeError::Internal(what) => write!(f, "internal encoder error: {what}"),
            EncodeError::Unsupported(what) => write!(f, "not supported: {what}"),
        }
    }
}

impl std::error::Error for EncodeError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            EncodeError::Syntax(e) => Some(e),
            _ => None,
        }
    }
}

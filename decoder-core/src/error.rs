//! Typed decoding errors.

use core::fmt;

/// Everything that can go wrong while reading a `.pifs` stream.
///
/// The decoder never panics: every malformed, truncated or hostile byte string ends in one of
/// these values.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DecodeError {
    /// The stream ended before the header or the payload was complete.
    Truncated,
    /// The first four bytes are not `PIFS`.
    BadMagic,
    /// The stream was written by a newer (or unknown) version of the format.
    UnsupportedVersion(u8),
    /// The channel count is not one this decoder can reconstruct.
    UnsupportedChannels(u8),
    /// The sample bit depth is not one this decoder can reconstruct.
    UnsupportedBitDepth(u8),
    /// A header field is out of its allowed range; the text names the field.
    InvalidHeader(&'static str),
    /// The payload decoded to a value the syntax forbids (the arithmetic decoder lost
    /// synchronisation, or the stream was damaged); the text names the element.
    InvalidData(&'static str),
    /// The stream's CRC-32 does not match its bytes: it was damaged on the way.
    ChecksumMismatch {
        /// The checksum the header carries.
        stored: u32,
        /// The checksum of the bytes received.
        computed: u32,
    },
    /// The image is larger than the caller's [`crate::Limits`] allow.
    TooLarge {
        /// Width in the header.
        width: u16,
        /// Height in the header.
        height: u16,
    },
    /// The caller's output buffer is smaller than `width * height * channels` bytes.
    BufferTooSmall,
}

impl fmt::Display for DecodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DecodeError::Truncated => write!(f, "the stream is truncated"),
            DecodeError::BadMagic => write!(f, "not a PIFS stream (bad magic bytes)"),
            DecodeError::UnsupportedVersion(v) => {
                write!(
                    f,
                    "unsupported PIFS version {v} (this decoder reads version {})",
                    crate::bitstream::VERSION
                )
            }
            DecodeError::UnsupportedChannels(c) => write!(f, "unsupported channel count {c}"),
            DecodeError::UnsupportedBitDepth(b) => write!(f, "unsupported bit depth {b}"),
            DecodeError::InvalidHeader(what) => write!(f, "invalid header: {what}"),
            DecodeError::InvalidData(what) => write!(f, "corrupt payload: invalid {what}"),
            DecodeError::ChecksumMismatch { stored, computed } => write!(
                f,
                "the stream is damaged: its CRC-32 is {computed:08x}, the header says {stored:08x}"
            ),
            DecodeError::TooLarge { width, height } => {
                write!(
                    f,
                    "the image ({width}x{height}) exceeds the decoder's size limit"
                )
            }
            DecodeError::BufferTooSmall => write!(f, "output buffer too small for the image"),
        }
    }
}

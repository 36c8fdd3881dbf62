//! Typed errors: what is wrong with a stream ([`DecodeError`]), and a decode that may also
//! stop because the pixel sink failed ([`DrawError`]).

use core::fmt;

use crate::format::VERSION;

/// Everything that can be wrong with a `.pifs` stream, or with a caller's request to decode it.
///
/// The decoder never panics: every malformed, truncated or hostile byte string ends in one of
/// these values.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
// A word-sized tag before word-aligned fields: moving an error is three word copies, where the
// default layout's byte offsets pulled a general `memcpy` (0.7 KiB) into the M0's flash.
#[repr(C, u32)]
pub enum DecodeError {
    /// The stream ended before the header or the payload was complete.
    Truncated,
    /// The first byte is not a stream's (or, for a packet, a packet's) of any version.
    BadMagic,
    /// The stream was written by another (or an unknown) version of the format.
    UnsupportedVersion(u8),
    /// The channel count is not one this decoder can reconstruct (3 needs the `colour`
    /// feature, on by default).
    UnsupportedChannels(u8),
    /// The sample bit depth is not one this decoder can reconstruct.
    UnsupportedBitDepth(u8),
    /// A header field is out of its allowed range.
    InvalidHeader(HeaderField),
    /// The payload decoded to a value the syntax forbids (the arithmetic decoder lost
    /// synchronisation, or the stream was damaged).
    InvalidData(SyntaxElement),
    /// The checksum (a stream's CRC-32, a packet's CRC-16) does not match the bytes: they were
    /// damaged on the way.
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
    /// The stream is coded in stripes wider than the decoder holds prediction memory for
    /// (one byte per column of a stripe).
    StripeTooWide {
        /// Width of the stream's stripes, pixels.
        stripe: u32,
        /// Widest stripe the decoder holds, pixels.
        capacity: u32,
    },
}

/// The header field a [`DecodeError::InvalidHeader`] is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum HeaderField {
    /// Width or height is not 1 to 65535.
    Dimensions,
    /// The smallest or largest leaf size is outside the format's range, or they are in the
    /// wrong order.
    LeafSizes,
    /// The payload length is badly encoded or too large.
    PayloadLength,
    /// The coding fields (leaf sizes and stripe) are written though they are the defaults: a
    /// header has one encoding.
    CodingFields,
    /// Bytes follow the payload the header declares.
    TrailingBytes,
    /// The edge-smoothing strength is above the format's largest.
    Deblock,
    /// A packet's region does not lie in its image.
    Region,
    /// A packet's index, count or size field is badly encoded or out of range.
    PacketField,
    /// A 16-bit stream's value range has a step of 0.
    Range,
}

impl HeaderField {
    fn describe(self) -> &'static str {
        match self {
            HeaderField::Dimensions => "width and height must be 1 to 65535",
            HeaderField::LeafSizes => "leaf sizes",
            HeaderField::PayloadLength => "payload length",
            HeaderField::CodingFields => "coding fields (written, though they are the defaults)",
            HeaderField::TrailingBytes => "payload length (bytes follow the payload)",
            HeaderField::Deblock => "edge-smoothing strength",
            HeaderField::Region => "packet region (outside the image)",
            HeaderField::PacketField => "packet index, count or size",
            HeaderField::Range => "value range",
        }
    }
}

/// Why a payload could not be read, as the entropy decoder and the syntax report it: one byte,
/// so that it travels the decoder's hot path in a register (a [`DecodeError`] is twelve bytes,
/// and each `?` copied it). It becomes a [`DecodeError`] where the walk hands it out.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum PayloadError {
    /// The payload ended before the quadtree did ([`DecodeError::Truncated`]).
    Truncated,
    /// The payload decoded to a value the syntax forbids ([`DecodeError::InvalidData`]).
    InvalidData(SyntaxElement),
}

impl From<PayloadError> for DecodeError {
    fn from(e: PayloadError) -> Self {
        match e {
            PayloadError::Truncated => DecodeError::Truncated,
            PayloadError::InvalidData(element) => DecodeError::InvalidData(element),
        }
    }
}

/// The payload syntax element a [`DecodeError::InvalidData`] is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum SyntaxElement {
    /// A quadtree node of a size no node may have.
    NodeSize,
    /// The quadtree is deeper than any image allows.
    QuadtreeDepth,
    /// A leaf of a size no model may code.
    LeafSize,
    /// A model type index.
    ModelType,
    /// A control quantiser index.
    ControlQuantiser,
    /// A control value index out of range.
    ControlValue,
    /// An integer whose magnitude prefix is longer than the format allows.
    IntegerMagnitude,
    /// The payload's length does not match what the quadtree used.
    PayloadLength,
}

impl SyntaxElement {
    fn describe(self) -> &'static str {
        match self {
            SyntaxElement::NodeSize => "node size",
            SyntaxElement::QuadtreeDepth => "quadtree depth",
            SyntaxElement::LeafSize => "leaf size",
            SyntaxElement::ModelType => "model type",
            SyntaxElement::ControlQuantiser => "control quantiser",
            SyntaxElement::ControlValue => "control value",
            SyntaxElement::IntegerMagnitude => "integer magnitude",
            SyntaxElement::PayloadLength => "payload length",
        }
    }
}

impl fmt::Display for HeaderField {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.describe())
    }
}

impl fmt::Display for SyntaxElement {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.describe())
    }
}

impl fmt::Display for DecodeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DecodeError::Truncated => write!(f, "the stream is truncated"),
            DecodeError::BadMagic => write!(f, "not a PIFS stream or packet (unknown first byte)"),
            DecodeError::UnsupportedVersion(v) => write!(
                f,
                "unsupported PIFS version {v} (this decoder reads version {VERSION})"
            ),
            DecodeError::UnsupportedChannels(c) => write!(f, "unsupported channel count {c}"),
            DecodeError::UnsupportedBitDepth(b) => write!(f, "unsupported bit depth {b}"),
            DecodeError::InvalidHeader(field) => write!(f, "invalid header: {field}"),
            DecodeError::InvalidData(element) => write!(f, "corrupt payload: invalid {element}"),
            DecodeError::ChecksumMismatch { stored, computed } => write!(
                f,
                "damaged on the way: its checksum is {computed:08x}, the header says {stored:08x}"
            ),
            DecodeError::TooLarge { width, height } => write!(
                f,
                "the image ({width}x{height}) exceeds the decoder's size limit"
            ),
            DecodeError::BufferTooSmall => write!(f, "output buffer too small for the image"),
            DecodeError::StripeTooWide { stripe, capacity } => write!(
                f,
                "the stream is coded in stripes of {stripe} pixels; this decoder holds {capacity}"
            ),
        }
    }
}

impl core::error::Error for DecodeError {}

/// A decode that hands pixels to a sink can fail two ways: the stream is bad, or the sink
/// (a display, a file) failed. Decoding stops at the first of either.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DrawError<E> {
    /// The stream is bad: decoding stopped here (what came before was drawn).
    Decode(DecodeError),
    /// The sink failed: decoding stopped at its first error.
    Sink(E),
}

impl<E> From<DecodeError> for DrawError<E> {
    fn from(e: DecodeError) -> Self {
        DrawError::Decode(e)
    }
}

/// A sink that cannot fail leaves only the stream's errors.
impl From<DrawError<core::convert::Infallible>> for DecodeError {
    fn from(e: DrawError<core::convert::Infallible>) -> Self {
        match e {
            DrawError::Decode(e) => e,
            DrawError::Sink(never) => match never {},
        }
    }
}

impl<E: fmt::Debug> fmt::Display for DrawError<E> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DrawError::Decode(e) => e.fmt(f),
            DrawError::Sink(e) => write!(f, "the pixel sink failed: {e:?}"),
        }
    }
}

impl<E: fmt::Debug> core::error::Error for DrawError<E> {
    fn source(&self) -> Option<&(dyn core::error::Error + 'static)> {
        match self {
            DrawError::Decode(e) => Some(e),
            DrawError::Sink(_) => None,
        }
    }
}

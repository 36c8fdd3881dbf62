//! The public decoding API: a [`Decoder`] built over a stream in memory or a sequential source,
//! optionally cut to a clip rectangle, that hands pixels to a [`PixelSink`].
//!
//! A stream in memory ([`Decoder::new`]) is checked whole (length and CRC-32) before anything
//! is drawn. A sequential source ([`Decoder::from_source`]: a UART, a radio link, an SPI flash
//! read in order) is never held in memory: the header is collected into a small fixed buffer
//! ([`MAX_HEADER_LEN`] bytes) and the payload is fed straight into the range decoder, each byte
//! pulled exactly once; its checksum can only be checked at the end.
//!
//! A clip rectangle limits the synthesis, not the entropy decoding: the arithmetic decoder and
//! the adaptive contexts must see every bit, but leaves outside the clip produce no pixels
//! (only the edge pixels later leaves are predicted from).

use core::convert::Infallible;

use crate::checksum::Crc32;
use crate::colour::{ChromaFrontier, ChromaPatch, ColourOut};
use crate::entropy::{ByteSource, RangeDecoder, SliceSource};
use crate::error::{DecodeError, DrawError, HeaderField, SyntaxElement};
#[cfg(feature = "smooth-enlarged")]
use crate::format::byte;
use crate::format::{ends, put_ends, DEFAULT_STRIPE};
use crate::geometry::{Node, Rect};
use crate::prediction::{Frontier, RECORD_WHOLE};
use crate::syntax::control_step;
use crate::syntax::{
    stream_checksum, Header, SampleRange, CHECKSUM_BYTES, MAX_HEADER_LEN, MIN_HEADER_LEN,
};
#[cfg(feature = "smooth-enlarged")]
use crate::synthesis::TILE;
use crate::synthesis::{Catch, Discard, Patch, PixelSink, Scale, Stop, Tile, TileMut, TileOut};
use crate::walk::{self, LeafInfo, TreeVisitor, WalkState};

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

mod sealed {
    pub trait Sealed {}
}

/// Where a [`Decoder`] reads a payload from: a stream in memory ([`InMemory`], checked before
/// decoding) or a sequential source ([`Streamed`], checked at the end). Sealed: the two are
/// the only ones.
pub trait Input: sealed::Sealed + ByteSource {
    /// Whether the payload was verified (length and checksum) before decoding; otherwise it
    /// must be read to its end even when no pixel of it is wanted.
    #[doc(hidden)]
    const VERIFIED: bool;

    /// After the walk: `Ok` when the walk used exactly the payload (and the checksum matches).
    #[doc(hidden)]
    fn finish(self, header: &Header) -> Result<(), DecodeError>;

    /// After a walk that failed with `error`: the error to report. A payload not verified
    /// beforehand reads the rest of its declared length, so that damage is reported as such
    /// ([`DecodeError::ChecksumMismatch`]) whichever syntax check it happened to trip first,
    /// exactly as the in-memory decoder reports it.
    #[doc(hidden)]
    fn after_error(self, header: &Header, error: DecodeError) -> DecodeError;
}

/// The payload of a stream in memory, whose length and checksum [`Decoder::new`] checked.
#[derive(Debug, Clone)]
pub struct InMemory<'a>(SliceSource<'a>);

impl sealed::Sealed for InMemory<'_> {}

impl ByteSource for InMemory<'_> {
    #[inline]
    fn next_byte(&mut self) -> Option<u8> {
        self.0.next_byte()
    }
}

impl Input for InMemory<'_> {
    const VERIFIED: bool = true;

    fn finish(mut self, _header: &Header) -> Result<(), DecodeError> {
        match self.next_byte() {
            None => Ok(()),
            Some(_) => Err(DecodeError::InvalidData(SyntaxElement::PayloadLength)),
        }
    }

    fn after_error(self, _header: &Header, error: DecodeError) -> DecodeError {
        error
    }
}

/// The payload of a packet (already checked by its CRC), read as if followed by zero bytes:
/// a packet's range coder ends with as few bytes as decode correctly with that padding
/// (`docs/bitstream.md`, section 9), at most four of which are read past its end.
#[derive(Debug, Clone)]
pub(crate) struct ZeroPadded<'a> {
    source: SliceSource<'a>,
    padding: u8,
}

/// The zero bytes a packet's payload may be read past its end: the range decoder's register.
const PACKET_PADDING: u8 = 4;

impl<'a> ZeroPadded<'a> {
    pub(crate) fn new(payload: &'a [u8]) -> Self {
        ZeroPadded {
            source: SliceSource::new(payload),
            padding: 0,
        }
    }
}

impl sealed::Sealed for ZeroPadded<'_> {}

impl ByteSource for ZeroPadded<'_> {
    #[inline]
    fn next_byte(&mut self) -> Option<u8> {
        match self.source.next_byte() {
            Some(b) => Some(b),
            None if self.padding < PACKET_PADDING => {
                self.padding += 1;
                Some(0)
            }
            None => None,
        }
    }
}

impl Input for ZeroPadded<'_> {
    const VERIFIED: bool = true;

    fn finish(mut self, _header: &Header) -> Result<(), DecodeError> {
        // Every byte of the payload was needed.
        match self.padding > 0 || self.source.next_byte().is_none() {
            true => Ok(()),
            false => Err(DecodeError::InvalidData(SyntaxElement::PayloadLength)),
        }
    }

    fn after_error(self, _header: &Header, error: DecodeError) -> DecodeError {
        error
    }
}

impl<'a> Decoder<ZeroPadded<'a>> {
    /// A decoder of a packet's payload, checked with its header (by its CRC).
    pub(crate) fn packet(header: Header, payload: &'a [u8]) -> Self {
        Decoder::with_input(header, ZeroPadded::new(payload))
    }
}

/// The payload of a sequential source: at most the header's payload length is pulled, and
/// every byte goes through the stream's CRC-32, checked at the end.
#[derive(Debug)]
pub struct Streamed<B> {
    inner: B,
    remaining: u32,
    crc: Crc32,
}

impl<B> sealed::Sealed for Streamed<B> {}

impl<B: ByteSource> ByteSource for Streamed<B> {
    #[inline]
    fn next_byte(&mut self) -> Option<u8> {
        if self.remaining == 0 {
            return None;
        }
        let b = self.inner.next_byte()?;
        self.remaining -= 1;
        self.crc.update_byte(b);
        Some(b)
    }
}

impl<B: ByteSource> Input for Streamed<B> {
    const VERIFIED: bool = false;

    /// The rest of the payload (which a valid stream does not have) goes into the checksum,
    /// which must match (damage is the likeliest cause of a short walk); then the walk must
    /// have used the whole payload.
    fn finish(self, header: &Header) -> Result<(), DecodeError> {
        let unread = self.remaining != 0;
        self.drain_and_check(header)?;
        if unread {
            return Err(DecodeError::InvalidData(SyntaxElement::PayloadLength));
        }
        Ok(())
    }

    fn after_error(self, header: &Header, error: DecodeError) -> DecodeError {
        self.drain_and_check(header).err().unwrap_or(error)
    }
}

impl<B: ByteSource> Streamed<B> {
    /// Reads the rest of the declared payload into the checksum and compares it.
    fn drain_and_check(mut self, header: &Header) -> Result<(), DecodeError> {
        while self.next_byte().is_some() {}
        if self.remaining != 0 {
            return Err(DecodeError::Truncated);
        }
        let computed = self.crc.value();
        if computed != header.checksum {
            return Err(DecodeError::ChecksumMismatch {
                stored: header.checksum,
                computed,
            });
        }
        Ok(())
    }
}

/// Decodes one stream: build it over the stream ([`Decoder::new`] for a slice,
/// [`Decoder::from_source`] for a sequential source), optionally narrow what it draws
/// ([`Decoder::clip`]) or watch its leaves ([`Decoder::observe`]), then decode into a
/// [`PixelSink`] ([`Decoder::decode`]) or a buffer ([`Decoder::decode_into`]).
///
/// ```
/// # use decoder_core::{Decoder, DecodeError, Rect};
/// # fn demo(stream: &[u8]) -> Result<(), DecodeError> {
/// let decoder = Decoder::new(stream)?; // header, length and checksum checked
/// let header = *decoder.header();
/// let mut pixels = vec![0u8; header.pixel_count()];
/// decoder.decode_into(&mut pixels)?;
///
/// // Only the top-left 64 x 64 pixels, into any sink (here a closure-free buffer):
/// let mut corner = vec![0u8; header.pixel_count()];
/// Decoder::new(stream)?
///     .clip(Rect { x: 0, y: 0, w: 64, h: 64 })
///     .decode_into(&mut corner)?;
/// # Ok(()) }
/// ```
///
/// `STRIPE` is the widest stripe the decoder holds prediction memory for (one byte per column,
/// on the stack while decoding; [`Header::stripe_width`]): streams coded in wider stripes are
/// refused with [`DecodeError::StripeTooWide`]. [`Decoder::stripe_capacity`] changes it.
#[derive(Debug, Clone)]
pub struct Decoder<I, O = fn(&LeafInfo), const STRIPE: usize = DEFAULT_STRIPE> {
    header: Header,
    input: I,
    clip: Rect,
    observer: O,
    scale: Scale,
}

/// The default observer: ignores every leaf.
fn ignore_leaf(_: &LeafInfo) {}

impl<'a> Decoder<InMemory<'a>> {
    /// A decoder of the whole stream `data`, after checking its header, that it is exactly as
    /// long as the header says, and its checksum: a damaged stream is refused here, before
    /// anything is drawn.
    pub fn new(data: &'a [u8]) -> Result<Self, DecodeError> {
        let (header, offset) = Header::parse(data)?;
        let end = offset as u64 + u64::from(header.payload_len);
        if (data.len() as u64) < end {
            return Err(DecodeError::Truncated);
        }
        if data.len() as u64 > end {
            return Err(DecodeError::InvalidHeader(HeaderField::TrailingBytes));
        }
        let computed = stream_checksum(data);
        if computed != header.checksum {
            return Err(DecodeError::ChecksumMismatch {
                stored: header.checksum,
                computed,
            });
        }
        Ok(Decoder::verified(header, &data[offset..]))
    }

    /// A decoder of a payload already checked with its header (by [`Decoder::new`]).
    pub(crate) fn verified(header: Header, payload: &'a [u8]) -> Self {
        Decoder::with_input(header, InMemory(SliceSource::new(payload)))
    }
}

impl<B: ByteSource> Decoder<Streamed<B>> {
    /// A decoder that reads its stream from `source` in order, never holding it: reads and
    /// checks the header now (exactly its bytes: the source is left at the payload), the
    /// payload while decoding. Because nothing is held, the checksum is checked at the end: a
    /// damaged stream may draw damaged pixels before [`DecodeError::ChecksumMismatch`] (or the
    /// error the damage caused) is returned. Exactly the header's and the payload's bytes are
    /// pulled from `source`, never one more.
    pub fn from_source(mut source: B) -> Result<Self, DecodeError> {
        let (header, crc) = read_header(&mut source)?;
        let input = Streamed {
            inner: source,
            remaining: header.payload_len,
            crc,
        };
        Ok(Decoder::with_input(header, input))
    }
}

impl<I> Decoder<I> {
    fn with_input(header: Header, input: I) -> Self {
        Decoder {
            header,
            input,
            clip: Rect::EVERYTHING,
            observer: ignore_leaf,
            scale: Scale::One,
        }
    }
}

impl<I: Input, O: FnMut(&LeafInfo), const STRIPE: usize> Decoder<I, O, STRIPE> {
    /// The stream's header.
    pub fn header(&self) -> &Header {
        &self.header
    }

    /// Refuses the stream ([`DecodeError::TooLarge`]) if its image is beyond `limits`.
    pub fn limits(self, limits: &Limits) -> Result<Self, DecodeError> {
        limits.check(&self.header)?;
        Ok(self)
    }

    /// Draws only the pixels inside `area` (image coordinates; the intersection with any
    /// earlier clip). The whole payload is still entropy-decoded, so payload errors are
    /// reported wherever they are.
    pub fn clip(mut self, area: Rect) -> Self {
        self.clip = self.clip.intersect(&area);
        self
    }

    /// Calls `observer` for every leaf, in coding order, before its pixels (for inspection
    /// tools).
    pub fn observe<P: FnMut(&LeafInfo)>(self, observer: P) -> Decoder<I, P, STRIPE> {
        Decoder {
            header: self.header,
            input: self.input,
            clip: self.clip,
            observer,
            scale: self.scale,
        }
    }

    /// Decodes at `scale` of the coded size (see [`Scale`]): an image of
    /// [`Decoder::output_size`] pixels, whose coordinates the clip ([`Decoder::clip`]) and the
    /// sink's tiles then use. Smaller decodes stop the subdivision early (their cost falls with
    /// the output's pixel count, though every leaf's edge pixels are still made at the coded
    /// size for prediction); larger ones continue it below the pixel.
    pub fn scale(mut self, scale: Scale) -> Self {
        self.scale = scale;
        self
    }

    /// Width and height of the decoded image: the header's at the decoder's [`Scale`]
    /// (rounded up).
    pub fn output_size(&self) -> (u32, u32) {
        (
            self.scale.apply(self.header.width.into()),
            self.scale.apply(self.header.height.into()),
        )
    }

    /// Holds prediction memory for stripes of up to `CAPACITY` pixels instead (`CAPACITY` bytes
    /// on the stack while decoding): a host decoding any stream uses 65536.
    pub fn stripe_capacity<const CAPACITY: usize>(self) -> Decoder<I, O, CAPACITY> {
        Decoder {
            header: self.header,
            input: self.input,
            clip: self.clip,
            observer: self.observer,
            scale: self.scale,
        }
    }

    /// Decodes the stream, handing the pixels inside the clip to `sink` tile by tile (no
    /// frame buffer needed); stops at the stream's or the sink's first error. Returns the
    /// header.
    pub fn decode<S: PixelSink + ?Sized>(
        self,
        sink: &mut S,
    ) -> Result<Header, DrawError<S::Error>> {
        // Borrowed, not copied: the header stays in the decoder's place on the stack.
        let header = &self.header;
        let (width, height) = self.output_size();
        let image = Rect::of_size(width, height);
        let mut drawer = Drawer {
            placement: Placement {
                clip: self.clip.intersect(&image),
                image,
                scale: self.scale,
            },
            sink,
            observer: self.observer,
            range: header.range,
        };
        let mut coder = match RangeDecoder::start(self.input) {
            Ok(coder) => coder,
            Err((input, e)) => return Err(input.after_error(header, e.into()).into()),
        };
        match run_walk::<_, _, STRIPE>(header, &mut coder, &mut drawer) {
            Ok(()) => coder.into_source().finish(header)?,
            Err(DrawError::Decode(e)) => {
                return Err(coder.into_source().after_error(header, e).into())
            }
            Err(sink_error) => return Err(sink_error),
        }
        Ok(*header)
    }

    /// Decodes the stream into `out`: row-major, `width` bytes per row, at least
    /// `width * height * channels` bytes ([`DecodeError::BufferTooSmall`] otherwise), with the
    /// width and height of [`Decoder::output_size`]. Pixels outside the clip are left as they
    /// are.
    pub fn decode_into(self, out: &mut [u8]) -> Result<Header, DecodeError> {
        let header = self.header;
        let (width, height) = self.output_size();
        let needed = u64::from(width) * u64::from(height) * u64::from(header.channels);
        if (out.len() as u64) < needed {
            return Err(DecodeError::BufferTooSmall);
        }
        let mut buffer = Buffer {
            out,
            width: width as usize,
        };
        Ok(self.decode(&mut buffer)?)
    }

    /// Decodes the stream's values into `out`, row-major, `width * height * channels` of them
    /// (as [`Decoder::decode_into`]): a 16-bit stream's in its own units
    /// ([`Header::range`]), an 8-bit stream's pixels as they are.
    pub fn decode_values_into(self, out: &mut [u16]) -> Result<Header, DecodeError> {
        let header = self.header;
        let (width, height) = self.output_size();
        let needed = u64::from(width) * u64::from(height) * u64::from(header.channels);
        if (out.len() as u64) < needed {
            return Err(DecodeError::BufferTooSmall);
        }
        let mut buffer = ValueBuffer {
            out,
            width: width as usize,
        };
        Ok(self.decode(&mut buffer)?)
    }

    /// Entropy-decodes the whole payload without drawing a pixel: `Ok` when drawing will not
    /// meet a decoding error.
    pub fn verify(self) -> Result<Header, DecodeError> {
        Ok(self.clip(Rect::of_size(0, 0)).decode(&mut NoPixels)?)
    }
}

/// Reads exactly the header's bytes from `source` and parses them; returns the header and the
/// CRC-32 state after its checksummed bytes.
///
/// The shortest header's bytes are read first; further bytes are pulled one at a time
/// only while [`Header::parse`] reports the header as truncated, so the source is left at the
/// first payload byte. Errors are those of [`Header::parse`] on the same bytes; a source that
/// ends early gives [`DecodeError::Truncated`] (or [`DecodeError::BadMagic`], like a short
/// slice would).
fn read_header<B: ByteSource>(source: &mut B) -> Result<(Header, Crc32), DecodeError> {
    let mut buf = [0u8; MAX_HEADER_LEN];
    let mut len = 0;
    while len < MIN_HEADER_LEN {
        match source.next_byte() {
            Some(b) => {
                buf[len] = b;
                len += 1;
            }
            None => break,
        }
    }
    loop {
        // `len <= MAX_HEADER_LEN`: the slices below are whole.
        let read = buf.get(..len).unwrap_or_default();
        match Header::parse(read) {
            Ok((header, _)) => {
                let mut crc = Crc32::default();
                crc.update(read.get(..CHECKSUM_BYTES.start).unwrap_or_default());
                crc.update(read.get(CHECKSUM_BYTES.end..).unwrap_or_default());
                return Ok((header, crc));
            }
            Err(DecodeError::Truncated) if (MIN_HEADER_LEN..MAX_HEADER_LEN).contains(&len) => {
                buf[len] = source.next_byte().ok_or(DecodeError::Truncated)?;
                len += 1;
            }
            Err(e) => return Err(e),
        }
    }
}

/// The walk, its final state dropped: every decoding path goes through here. Not inlined, so
/// that the walk's state (the adaptive contexts and the prediction memory) stays in this one
/// frame instead of being copied into every caller's.
#[inline(never)]
fn run_walk<B: ByteSource, V: TreeVisitor, const STRIPE: usize>(
    header: &Header,
    coder: &mut RangeDecoder<B>,
    visitor: &mut V,
) -> Result<(), V::Error> {
    let mut state = WalkState::<STRIPE>::FRESH;
    state.contexts.start();
    walk::walk_with(header, coder, visitor, &mut state)
}

/// The one visitor of every decode: draws each leaf's pixels inside the clip into the sink and
/// keeps the prediction frontier.
struct Drawer<'s, S: PixelSink + ?Sized, O> {
    /// Where the leaves go.
    placement: Placement,
    sink: &'s mut S,
    observer: O,
    /// A 16-bit stream's value range, which its samples are mapped onto for the sink.
    range: Option<SampleRange>,
}

impl<S: PixelSink + ?Sized, O: FnMut(&LeafInfo)> TreeVisitor for Drawer<'_, S, O> {
    type Error = DrawError<S::Error>;
    /// Every leaf goes through the prediction frontier, which smooths its edges with the
    /// leaves before it and draws the pixels that were waiting for it (see
    /// [`crate::prediction::Capture`]). At the coded size the whole leaf is drawn through it (or
    /// only its edges, when the clip misses the leaf). A smaller decode takes the edges at the
    /// coded size, keeping those on its pixel grid, and renders the rest of the leaf straight at
    /// its scale; a larger one renders the leaf at its scale, closing the smoothed steps above
    /// and left of it on its own side (`draw_enlarged`). Not inlined: the
    /// synthesis buffers then live only while a leaf is drawn, instead of in every frame of the
    /// quadtree walk.
    #[inline(never)]
    fn leaf<const CAPACITY: usize>(
        &mut self,
        info: &LeafInfo,
        patch: &Patch,
        frontier: &mut Frontier<CAPACITY>,
    ) -> Result<(), Self::Error> {
        (self.observer)(info);
        let mut catch = Catch::with_range(&mut *self.sink, self.range);
        draw_leaf(&self.placement, info, patch, frontier, &mut catch);
        catch.finish().map_err(DrawError::Sink)
    }

    /// A colour leaf: drawn as a grayscale one, through [`ColourOut`], which turns each luma
    /// tile into RGB on its way to the sink.
    #[inline(never)]
    fn leaf_colour<const CAPACITY: usize>(
        &mut self,
        info: &LeafInfo,
        patch: &Patch,
        chroma: &ChromaPatch,
        frontier: &mut Frontier<CAPACITY>,
        chroma_frontier: &ChromaFrontier<CAPACITY>,
    ) -> Result<(), Self::Error> {
        (self.observer)(info);
        let mut catch = Catch::new(&mut *self.sink);
        let mut colour = ColourOut {
            patch: chroma,
            frontier: chroma_frontier,
            scale: self.placement.scale,
            out: &mut catch,
        };
        draw_leaf(&self.placement, info, patch, frontier, &mut colour);
        catch.finish().map_err(DrawError::Sink)
    }
}

/// Draws a leaf's luma into `out` (see [`Drawer`]'s `leaf`), with the decode's clip, output
/// image and scale. A stop comes only from the sink, whose error its [`Catch`] keeps. In line:
/// one of three paths, each out of line.
#[inline(always)]
fn draw_leaf<const CAPACITY: usize>(
    at: &Placement,
    info: &LeafInfo,
    patch: &Patch,
    frontier: &mut Frontier<CAPACITY>,
    out: &mut dyn TileOut,
) {
    let node = &info.node;
    let step = control_step(info.cquant);
    let k = at.scale.log2();
    // A stop comes only from the sink, whose error `finish` returns.
    let _ = if k == 0 {
        draw_coded(node, step, patch, frontier, at, out)
    } else if k < 0 {
        draw_reduced(node, step, patch, frontier, at, out)
    } else {
        draw_enlarged(node, step, patch, frontier, at, out)
    };
}

/// Where a decode's leaves go: the output image (at the decode's scale), the part of it drawn
/// (already cut to the image) and the scale.
#[derive(Debug, Clone, Copy)]
struct Placement {
    clip: Rect,
    image: Rect,
    scale: Scale,
}

/// A leaf of a decode at the coded size: drawn through the frontier's capture, cut to the clip
/// where it reaches past it; recorded only when none of it is inside the clip. Out of line, as
/// [`draw_reduced`] and [`draw_enlarged`] are: only the path taken is on the stack.
#[inline(never)]
fn draw_coded<const CAPACITY: usize>(
    node: &Node,
    step: i32,
    patch: &Patch,
    frontier: &mut Frontier<CAPACITY>,
    &Placement { clip, image, .. }: &Placement,
    out: &mut dyn TileOut,
) -> Result<(), Stop> {
    // Cut to the clip on the way out: the leaf's pixels, and the pixels beside it it draws.
    let mut clipped = ClipOut { clip, out };
    let area = node.rect().intersect(&image);
    if area.intersect(&clip).is_empty() {
        frontier.record(node, step, patch, &mut clipped);
        Ok(())
    } else {
        // Nothing to cut when all it draws is inside the clip: the tiles go straight on.
        let out: &mut dyn TileOut = if draws_inside(node, 0, image, clip) {
            clipped.out
        } else {
            &mut clipped
        };
        patch.render_to(node, area, &mut frontier.capture(node, step, out))
    }
}

/// A leaf of a decode smaller than the coded size: recorded at the coded size, the pixels on
/// the output's grid picked from what the recording draws (all of them for a leaf recorded
/// whole), then the rest of the leaf drawn at its scale. Out of line: the recording is on the
/// stack only here.
#[inline(never)]
fn draw_reduced<const CAPACITY: usize>(
    node: &Node,
    step: i32,
    patch: &Patch,
    frontier: &mut Frontier<CAPACITY>,
    &Placement { clip, image, scale }: &Placement,
    out: &mut dyn TileOut,
) -> Result<(), Stop> {
    let shift = scale.log2().unsigned_abs();
    // As at the coded size: nothing to cut when all it picks is inside the clip.
    let mut clipped = ClipOut { clip, out };
    let picked: &mut dyn TileOut = if draws_inside(node, shift, image, clip) {
        clipped.out
    } else {
        &mut clipped
    };
    frontier.record(node, step, patch, &mut Subsample { shift, out: picked });
    if node.size() <= RECORD_WHOLE {
        // Recorded whole: every pixel of the leaf went to the subsampling.
        return Ok(());
    }
    // The leaf's first row and column are the edges' (its last ones are off the grid).
    let (x, y, n) = (node.x >> shift, node.y >> shift, node.size() >> shift);
    let interior = Rect {
        x: x + 1,
        y: y + 1,
        w: n.saturating_sub(1),
        h: n.saturating_sub(1),
    };
    patch.render_scaled(node, scale, clip.intersect(&interior), clipped.out)
}

/// Whether all a leaf draws at the coded size (its own pixels, and the row above and the
/// column left of it that wait for it: see [`crate::prediction::Capture`]) lies inside `clip`
/// where it lies inside `image` (whose top-left pixel is `(0, 0)`), on the grid of a decode at
/// `1 / 2^shift` of the coded size (`image` and `clip` are that decode's). Then it needs no cut.
#[inline(never)]
fn draws_inside(node: &Node, shift: u32, image: Rect, clip: Rect) -> bool {
    // No overflow: a node lies within a coding tile of an image of at most 65535 pixels a side.
    let last = node.size() - 1;
    // Along one axis: the leaf's reach inside the image is empty or inside the clip.
    let axis = |start: u32, image_end: u32, clip_start: u32, clip_end: u32| {
        let first = start.saturating_sub(1) >> shift;
        let end = ((start + last) >> shift).min(image_end.saturating_sub(1));
        first > end || (clip_start <= first && end < clip_end)
    };
    axis(node.x, image.w, clip.x, clip.x + clip.w) && axis(node.y, image.h, clip.y, clip.y + clip.h)
}

/// A leaf of a decode larger than the coded size, drawn at its scale: with (feature
/// `smooth-enlarged`) its pixels on the coded grid taken through the frontier's capture as it
/// goes and what smoothing moved across the edges above and left of it ramped into its side
/// ([`Enlarged`]); else recorded at the coded size, then drawn as tabulated. A leaf outside the
/// clip is only recorded. Out of line: only the path taken is on the stack.
#[inline(never)]
fn draw_enlarged<const CAPACITY: usize>(
    node: &Node,
    step: i32,
    patch: &Patch,
    frontier: &mut Frontier<CAPACITY>,
    &Placement { clip, image, scale }: &Placement,
    out: &mut dyn TileOut,
) -> Result<(), Stop> {
    #[cfg(feature = "smooth-enlarged")]
    {
        let k = scale.log2().unsigned_abs();
        // The leaf's square at the scale, inside the image: its tiles start on the coded grid.
        let square = Rect {
            x: node.x << k,
            y: node.y << k,
            w: node.size() << k,
            h: node.size() << k,
        }
        .intersect(&image);
        if square.intersect(&clip).is_empty() {
            frontier.record(node, step, patch, &mut Discard);
            return Ok(());
        }
        // Cut to the clip on the way out, where the leaf reaches past it.
        let mut clipped = ClipOut { clip, out };
        let out: &mut dyn TileOut = if inside(square, clip) {
            clipped.out
        } else {
            &mut clipped
        };
        let beside = Beside::default();
        let mut moves: &Beside = &beside;
        let mut enlarged = Enlarged {
            capture: frontier.capture(node, step, &mut moves),
            beside: &beside,
            node: *node,
            k,
            out,
        };
        patch.render_scaled(node, scale, square, &mut enlarged)
    }
    #[cfg(not(feature = "smooth-enlarged"))]
    {
        let _ = image;
        frontier.record(node, step, patch, &mut Discard);
        patch.render_scaled(node, scale, clip, out)
    }
}

/// Whether `area` lies inside `clip`.
#[cfg(feature = "smooth-enlarged")]
fn inside(area: Rect, clip: Rect) -> bool {
    area.intersect(&clip) == area
}

/// Side of the coded tile under an output tile of an enlarged decode, at most.
#[cfg(feature = "smooth-enlarged")]
const UNDER: usize = TILE / 2;

/// The tiles of a leaf of an enlarged decode (`2^k` times the coded size, drawn whole, each
/// tile starting on the coded grid). The pixels of each tile on the coded grid (the coded
/// pixels, exactly) go through the frontier's [`Capture`](crate::prediction::Capture), as a
/// coded tile of at most [`UNDER`] pixels a side, which smooths the leaf's steps with the pixels
/// waiting beside it and keeps its edges. What it moved each waiting pixel by, twice (the
/// step's whole correction: smoothing moves the two pixels of a step towards each other alike)
/// and clamped to `i8`, is closed on the leaf's side: the leaf's first output row (column) moves
/// by it, the rows (columns) after it by less, down to nothing one coded pixel in. The leaves
/// before it were drawn as tabulated, so the leaf alone closes the step.
#[cfg(feature = "smooth-enlarged")]
struct Enlarged<'c, 'o> {
    capture: crate::prediction::Capture<'c>,
    /// The waiting pixels the capture draws, smoothed.
    beside: &'c Beside,
    node: Node,
    /// The scale's power of two.
    k: u32,
    out: &'o mut dyn TileOut,
}

#[cfg(feature = "smooth-enlarged")]
impl Enlarged<'_, '_> {
    /// The coded tile under the output tile `area` (which starts on the coded grid), if it
    /// holds a pixel of the leaf's first or last row or column: the capture passes the others
    /// on untouched.
    fn under(&self, area: Rect) -> Option<Rect> {
        let k = self.k;
        let unit = 1u32 << k;
        let side = |length: u32| ((length + unit - 1) >> k).min(UNDER as u32);
        let coded = Rect {
            x: area.x >> k,
            y: area.y >> k,
            w: side(area.w),
            h: side(area.h),
        };
        let last = self.node.size() - 1;
        let on_edge = |start: u32, length: u32, first: u32| {
            start == first || start + length.saturating_sub(1) == first + last
        };
        (on_edge(coded.x, coded.w, self.node.x) || on_edge(coded.y, coded.h, self.node.y))
            .then_some(coded)
    }

    /// The pixels of the output tile `pixels` (`w` a row) on the coded grid, into `coded` (the
    /// coded tile `area`'s, row-major).
    fn pick(&self, pixels: &[u8], w: u32, area: Rect, coded: &mut [u8]) {
        let k = self.k;
        for r in 0..area.h {
            for c in 0..area.w {
                let from = ((r << k) * w + (c << k)) as usize;
                if let (Some(&v), Some(to)) =
                    (pixels.get(from), coded.get_mut((r * area.w + c) as usize))
                {
                    *to = v;
                }
            }
        }
    }
}

#[cfg(feature = "smooth-enlarged")]
impl TileOut for Enlarged<'_, '_> {
    #[cfg(feature = "deep")]
    fn depth(&self) -> crate::synthesis::Depth {
        self.out.depth()
    }

    /// A 16-bit stream is not smoothed: the coded tile goes through the capture as a 16-bit
    /// stream's (which keeps the leaf's edge pixels, and needs no samples for it), and the tile
    /// on as it is.
    #[cfg(feature = "deep")]
    fn put_samples(&mut self, tile: TileMut<'_>, samples: &mut [i16]) -> Result<(), Stop> {
        if let Some(area) = self.under(tile.area) {
            let mut coded = [0u8; UNDER * UNDER];
            let coded = coded
                .get_mut(..(area.w * area.h) as usize)
                .unwrap_or_default();
            self.pick(tile.pixels, tile.area.w, area, coded);
            let pixels = TileMut {
                area,
                pixels: coded,
                channels: 1,
            };
            self.capture.put_samples(pixels, &mut [])?;
        }
        self.out.put_samples(tile, samples)
    }

    fn put(&mut self, tile: TileMut<'_>) -> Result<(), Stop> {
        let Some(area) = self.under(tile.area) else {
            return self.out.put(tile);
        };
        let (first_row, first_column) = (area.y == self.node.y, area.x == self.node.x);
        // The waiting pixels beside the coded tile (above it, then left of it), before it
        // smooths them.
        let mut before = [0u8; 2 * UNDER];
        let (above, left) = before.split_at_mut(UNDER);
        if first_row {
            let run = above.get_mut(..area.w as usize).unwrap_or_default();
            self.capture.waiting(true, area.x, run);
        }
        if first_column {
            let run = left.get_mut(..area.h as usize).unwrap_or_default();
            self.capture.waiting(false, area.y, run);
        }
        self.beside.start(area);
        let mut coded = [0u8; UNDER * UNDER];
        let coded = coded
            .get_mut(..(area.w * area.h) as usize)
            .unwrap_or_default();
        self.pick(tile.pixels, tile.area.w, area, coded);
        self.capture.put(TileMut {
            area,
            pixels: coded,
            channels: 1,
        })?;
        if first_row || first_column {
            self.beside
                .shifts(&before)
                .ramp(tile.area, tile.pixels, self.k);
        }
        self.out.put(tile)
    }
}

/// What smoothing moved across a leaf's edges under one output tile of an enlarged decode, as
/// the step's whole correction: by coded column of the tile (the edge above), then by coded
/// row (the edge left).
#[cfg(feature = "smooth-enlarged")]
struct Shifts([i8; 2 * UNDER]);

#[cfg(feature = "smooth-enlarged")]
impl Shifts {
    /// Closes the shifts in the output tile `area` (`pixels`, row-major), which starts on the
    /// coded grid of a decode at `2^k`: its first output row (column) moves by the shift above
    /// (left of) its coded column (row) in full, the `t`-th after it by `1 - t / 2^k` of it; a
    /// pixel in both moves by the sum, rounded once.
    fn ramp(&self, area: Rect, pixels: &mut [u8], k: u32) {
        let unit = 1u32 << k;
        let w = area.w;
        for j in 0..area.h {
            // Past the first coded row only the first coded column moves.
            let columns = if j < unit { w } else { w.min(unit) };
            for i in 0..columns {
                let mut moved = 0i32;
                if j < unit {
                    let t = self.0.get((i >> k) as usize).copied().unwrap_or(0);
                    moved += i32::from(t) * (unit - j) as i32;
                }
                if i < unit {
                    let l = self.0.get(UNDER + (j >> k) as usize).copied().unwrap_or(0);
                    moved += i32::from(l) * (unit - i) as i32;
                }
                if moved != 0 {
                    if let Some(v) = pixels.get_mut((j * w + i) as usize) {
                        *v = byte(i32::from(*v) + ((moved + (unit >> 1) as i32) >> k));
                    }
                }
            }
        }
    }
}

/// The waiting pixels beside a coded tile of an enlarged leaf that the frontier's capture
/// draws (smoothed) while it takes the tile: above its columns and left of its rows, by offset
/// from its first column and row. Shared (cells): the capture draws into it while the leaf's
/// [`Enlarged`] reads it.
#[cfg(feature = "smooth-enlarged")]
#[derive(Default)]
struct Beside {
    /// The coded tile.
    tile: core::cell::Cell<(u32, u32)>,
    /// Above its columns, then left of its rows.
    drawn: [core::cell::Cell<Option<u8>>; 2 * UNDER],
}

#[cfg(feature = "smooth-enlarged")]
impl Beside {
    /// Before the capture takes the coded tile `area`: nothing drawn yet.
    fn start(&self, area: Rect) {
        self.tile.set((area.x, area.y));
        for cell in &self.drawn {
            cell.set(None);
        }
    }

    /// The shifts: twice what smoothing moved each pixel drawn from `before` (the step's whole
    /// correction), clamped to `i8`; 0 where none was drawn.
    fn shifts(&self, before: &[u8; 2 * UNDER]) -> Shifts {
        let mut shifts = [0; 2 * UNDER];
        for ((shift, now), &was) in shifts.iter_mut().zip(&self.drawn).zip(before) {
            if let Some(now) = now.get() {
                *shift = (-2 * (i32::from(now) - i32::from(was))).clamp(-127, 127) as i8;
            }
        }
        Shifts(shifts)
    }
}

#[cfg(feature = "smooth-enlarged")]
impl TileOut for &Beside {
    fn put(&mut self, tile: TileMut<'_>) -> Result<(), Stop> {
        let Rect { x, y, w, h } = tile.area;
        let (left, top) = self.tile.get();
        // The row above the tile, or a run of the column left of it; the tile's own pixels
        // (and nothing else the capture draws) lie right of and below both.
        let from = if h == 1 && y + 1 == top && x >= left {
            x - left
        } else if w == 1 && x + 1 == left && y >= top {
            UNDER as u32 + y - top
        } else {
            return Ok(());
        };
        let cells = self.drawn.get(from as usize..).unwrap_or_default();
        for (cell, &p) in cells.iter().zip(tile.pixels.iter()) {
            cell.set(Some(p));
        }
        Ok(())
    }
}

/// Hands on the pixels of full-size tiles that lie on the grid of a decode at `1 / 2^shift`
/// of the coded size, at their place in it.
struct Subsample<'a> {
    shift: u32,
    out: &'a mut dyn TileOut,
}

impl Subsample<'_> {
    /// Hands on the tile's pixels on the grid as one tile, with their samples when `samples`
    /// holds the tile's: moved to the front in place (the `n`-th pixel on the grid comes from
    /// the `n`-th position or a later one).
    fn pick(&mut self, mut tile: TileMut<'_>, mut samples: Option<&mut [i16]>) -> Result<(), Stop> {
        let (shift, unit) = (self.shift, 1u32 << self.shift);
        let Rect { x, y, w, h } = tile.area;
        // Coordinates are below 2^16: no overflow; shifts, no division on a Cortex-M0.
        let on_grid = |v: u32| (v + unit - 1) >> shift << shift;
        let (first_x, first_y) = (on_grid(x), on_grid(y));
        if first_x >= x + w || first_y >= y + h {
            return Ok(());
        }
        // Grid points in the tile's columns and rows.
        let cols = (x + w - first_x + unit - 1) >> shift;
        let rows = (y + h - first_y + unit - 1) >> shift;
        let (dx, dy) = (first_x - x, first_y - y);
        let mut n = 0;
        for r in 0..rows {
            for c in 0..cols {
                let at = ((dy + (r << shift)) * w + dx + (c << shift)) as usize;
                move_back(tile.pixels, at, n);
                if let Some(s) = samples.as_deref_mut() {
                    move_back(s, at, n);
                }
                n += 1;
            }
        }
        let count = (cols * rows) as usize;
        // The tile made the picked one in place.
        let Some(pixels) = core::mem::take(&mut tile.pixels).get_mut(..count) else {
            return Ok(());
        };
        tile.pixels = pixels;
        tile.area = Rect {
            x: first_x >> shift,
            y: first_y >> shift,
            w: cols,
            h: rows,
        };
        match samples.and_then(|s| s.get_mut(..count)) {
            Some(picked) => self.out.put_samples(tile, picked),
            None => self.out.put(tile),
        }
    }
}

/// `values[to] = values[from]`, where both are in `values`.
#[inline(always)]
fn move_back<T: Copy>(values: &mut [T], from: usize, to: usize) {
    if let Some(&v) = values.get(from) {
        if let Some(slot) = values.get_mut(to) {
            *slot = v;
        }
    }
}

impl TileOut for Subsample<'_> {
    fn put(&mut self, tile: TileMut<'_>) -> Result<(), Stop> {
        self.pick(tile, None)
    }

    #[cfg(feature = "deep")]
    fn put_samples(&mut self, tile: TileMut<'_>, samples: &mut [i16]) -> Result<(), Stop> {
        self.pick(tile, Some(samples))
    }

    #[cfg(feature = "deep")]
    fn depth(&self) -> crate::synthesis::Depth {
        self.out.depth()
    }
}

/// Hands on the part of every tile inside `clip`.
struct ClipOut<'a> {
    clip: Rect,
    out: &'a mut dyn TileOut,
}

/// Where the part of a tile inside a clip lies in the tile's values.
struct Inside {
    /// Values before it in each row, and rows above it.
    skip: (usize, usize),
    /// Values per row of it, and of the tile; its rows.
    size: (usize, usize, usize),
}

impl Inside {
    /// The part `area` (not empty) of `tile` (`channels` values a pixel).
    fn of(tile: Rect, area: Rect, channels: u8) -> Inside {
        let c = usize::from(channels);
        Inside {
            skip: ((area.x - tile.x) as usize * c, (area.y - tile.y) as usize),
            size: (area.w as usize * c, tile.w as usize * c, area.h as usize),
        }
    }

    /// Moves the part inside to the front of `values` (the tile's, row-major), row by row:
    /// never onto a value not yet moved. `None` if `values` is too short.
    fn cut<'v, T: Copy>(&self, values: &'v mut [T]) -> Option<&'v mut [T]> {
        let ((dx, dy), (w, tw, h)) = (self.skip, self.size);
        if (dy + h) * tw > values.len() {
            return None;
        }
        for j in 0..h {
            let from = (dy + j) * tw + dx;
            for k in 0..w {
                if let Some(&v) = values.get(from + k) {
                    if let Some(to) = values.get_mut(j * w + k) {
                        *to = v;
                    }
                }
            }
        }
        values.get_mut(..w * h)
    }
}

impl ClipOut<'_> {
    /// Hands on the part of `tile` (and of its `samples`, a 16-bit stream's) inside the clip.
    fn cut(&mut self, tile: TileMut<'_>, samples: Option<&mut [i16]>) -> Result<(), Stop> {
        let t = tile.area;
        let c = &self.clip;
        // Most tiles lie inside the clip: no intersection to make.
        let inside = t.x >= c.x && t.y >= c.y && {
            // In 32 bits: no sum that could overflow.
            let (dx, dy) = (t.x - c.x, t.y - c.y);
            dx <= c.w && t.w <= c.w - dx && dy <= c.h && t.h <= c.h - dy
        };
        let area = if inside { t } else { t.intersect(c) };
        if area.is_empty() {
            return Ok(());
        }
        let (tile, samples) = if area == tile.area {
            (tile, samples)
        } else {
            let inside = Inside::of(tile.area, area, tile.channels);
            let Some(pixels) = inside.cut(tile.pixels) else {
                return Ok(());
            };
            let tile = TileMut {
                area,
                pixels,
                channels: tile.channels,
            };
            match samples {
                Some(s) => match inside.cut(s) {
                    Some(s) => (tile, Some(s)),
                    None => return Ok(()),
                },
                None => (tile, None),
            }
        };
        match samples {
            Some(s) => self.out.put_samples(tile, s),
            None => self.out.put(tile),
        }
    }
}

impl TileOut for ClipOut<'_> {
    #[cfg(feature = "deep")]
    fn depth(&self) -> crate::synthesis::Depth {
        self.out.depth()
    }

    fn put(&mut self, tile: TileMut<'_>) -> Result<(), Stop> {
        self.cut(tile, None)
    }

    #[cfg(feature = "deep")]
    fn put_samples(&mut self, tile: TileMut<'_>, samples: &mut [i16]) -> Result<(), Stop> {
        self.cut(tile, Some(samples))
    }
}

/// A row-major frame buffer.
struct Buffer<'a> {
    out: &'a mut [u8],
    width: usize,
}

impl PixelSink for Buffer<'_> {
    type Error = Infallible;

    fn tile(&mut self, tile: Tile<'_>) -> Result<(), Infallible> {
        place_rows(self.out, self.width, &tile, |dst, at| {
            if let Some(src) = tile.pixels.get(at) {
                copy_row(dst, src);
            }
        });
        Ok(())
    }
}

/// `dst.copy_from_slice(src)` for a tile's row (at most 8 gray or 24 RGB bytes): two
/// overlapping moves of a fixed size, where `copy_from_slice` calls `memcpy` for a length it
/// does not know (6% of a host decode's time).
#[inline(always)]
fn copy_row(dst: &mut [u8], src: &[u8]) {
    if dst.len() != src.len() {
        return;
    }
    match src.len() {
        1 => copy_ends::<1>(dst, src),
        2..4 => copy_ends::<2>(dst, src),
        4..8 => copy_ends::<4>(dst, src),
        8..16 => copy_ends::<8>(dst, src),
        16..=32 => copy_ends::<16>(dst, src),
        _ => dst.copy_from_slice(src),
    }
}

/// Copies `src` (as long as `dst`, `N` to `2 N` bytes) into `dst` by its two ends.
#[inline(always)]
fn copy_ends<const N: usize>(dst: &mut [u8], src: &[u8]) {
    if let Some(both) = ends::<N>(src) {
        put_ends(dst, both);
    }
}

/// A row-major buffer of values: a tile's [`Tile::values`], or its pixels when it has none.
struct ValueBuffer<'a> {
    out: &'a mut [u16],
    width: usize,
}

impl PixelSink for ValueBuffer<'_> {
    type Error = Infallible;

    fn tile(&mut self, tile: Tile<'_>) -> Result<(), Infallible> {
        place_rows(self.out, self.width, &tile, |dst, at| {
            if let Some(values) = tile.values.get(at.clone()) {
                dst.copy_from_slice(values);
            } else if let Some(pixels) = tile.pixels.get(at) {
                for (d, &p) in dst.iter_mut().zip(pixels) {
                    *d = u16::from(p);
                }
            }
        });
        Ok(())
    }
}

/// Where each row of `tile` goes in a row-major image `width` pixels wide held in `out`:
/// `fill(destination, range of the row in the tile's values)` for every row that lies in
/// `out`.
fn place_rows<T>(
    out: &mut [T],
    width: usize,
    tile: &Tile<'_>,
    mut fill: impl FnMut(&mut [T], core::ops::Range<usize>),
) {
    let Rect { x, y, w, h } = tile.area;
    let ch = usize::from(tile.channels.max(1));
    let (stride, w) = (width * ch, w as usize * ch);
    let mut start = y as usize * stride + x as usize * ch;
    let mut from = 0;
    for _ in 0..h {
        if let Some(dst) = out.get_mut(start..start + w) {
            fill(dst, from..from + w);
        }
        start += stride;
        from += w;
    }
}

/// Takes no pixel (none is drawn).
struct NoPixels;

impl PixelSink for NoPixels {
    type Error = Infallible;

    fn tile(&mut self, _tile: Tile<'_>) -> Result<(), Infallible> {
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    extern crate std;

    use super::*;
    use std::path::PathBuf;
    use std::string::String;
    use std::vec::Vec;

    #[test]
    fn rows_are_copied_whole() {
        let src: Vec<u8> = (1..=40).collect();
        for n in 0..=40 {
            let mut dst = [0u8; 40];
            copy_row(&mut dst[..n], &src[..n]);
            assert_eq!(dst[..n], src[..n], "length {n}");
            assert!(dst[n..].iter().all(|&b| b == 0), "length {n}: past the row");
        }
    }

    /// Records every tile.
    #[derive(Default, PartialEq, Debug)]
    struct Recorder {
        tiles: Vec<(Rect, Vec<u8>)>,
    }

    impl PixelSink for Recorder {
        type Error = Infallible;

        fn tile(&mut self, tile: Tile<'_>) -> Result<(), Infallible> {
            self.tiles.push((tile.area, tile.pixels.to_vec()));
            Ok(())
        }
    }

    #[cfg(feature = "smooth-enlarged")]
    use crate::model::SAMPLE_ONE;

    /// A flat patch of grey `value`.
    #[cfg(feature = "smooth-enlarged")]
    fn flat(value: i16) -> Patch {
        let mut control = [0; crate::model::MAX_CONTROL];
        control[..4].fill(value * SAMPLE_ONE as i16);
        Patch {
            model: crate::model::MODELS[0],
            control,
        }
    }

    /// A coded tile taken through the capture of an enlarged decode gives, for each pixel of
    /// the leaf's first row and column in it, the whole correction smoothing made to its step:
    /// twice its neighbour's move.
    #[test]
    #[cfg(feature = "smooth-enlarged")]
    fn shifts_are_the_whole_smoothing_of_each_step() {
        let node = |x, y| Node { x, y, log2: 2 };
        let mut frontier = Frontier::<128>::EMPTY;
        assert!(frontier.start(16, 16, 128, 4));
        frontier.record(&node(0, 0), 64, &flat(100), &mut Discard);
        frontier.record(&node(4, 0), 64, &flat(100), &mut Discard);
        frontier.record(&node(0, 4), 64, &flat(106), &mut Discard);
        // Below 100 and right of 106: 120 (steps of 20 and 14, each side moved by 1 and 2).
        let shifts = |frontier: &mut Frontier<128>, leaf: Node, value: u8| {
            let beside = Beside::default();
            let mut moves: &Beside = &beside;
            let mut capture = frontier.capture(&leaf, 64, &mut moves);
            let mut before = [0u8; 2 * UNDER];
            let (above, left) = before.split_at_mut(UNDER);
            capture.waiting(true, leaf.x, above);
            capture.waiting(false, leaf.y, left);
            let area = Rect {
                x: leaf.x,
                y: leaf.y,
                w: 4,
                h: 4,
            };
            beside.start(area);
            let mut pixels = [value; 16];
            capture
                .put(TileMut {
                    area,
                    pixels: &mut pixels,
                    channels: 1,
                })
                .unwrap();
            beside.shifts(&before).0
        };
        // Above the leaf, then left of it.
        assert_eq!(
            shifts(&mut frontier, node(4, 4), 120),
            [-2, -2, -2, -2, -4, -4, -4, 0]
        );
        // (The left neighbour's bottom-right pixel waits with its row: the leaf below it
        // smooths it, so the last row has no step yet.) A step past four limits is an edge:
        // nothing smoothed, nothing shifted.
        assert_eq!(shifts(&mut frontier, node(8, 0), 200), [0; 2 * UNDER]);
    }

    /// An enlarged leaf's first output rows and columns take the whole shift at the coded
    /// grid's first pixel, less and less after it, and nothing one coded pixel in.
    #[test]
    #[cfg(feature = "smooth-enlarged")]
    fn a_ramp_closes_the_step_on_the_leafs_side() {
        // Above: -4 and +6 under coded columns 0 and 1; left: -4 beside coded row 0.
        let shifts = Shifts([-4, 6, 0, 0, -4, 0, 0, 0]);
        // A leaf's first tile drawn at 4x: one 8 x 8 tile of 100.
        let mut pixels = [100u8; 64];
        let area = Rect {
            x: 16,
            y: 16,
            w: 8,
            h: 8,
        };
        shifts.ramp(area, &mut pixels, 2);
        let row = |j: usize| pixels[j * 8..j * 8 + 8].to_vec();
        // Row 0: the top shift in full (-4 under coded column 0, +6 under column 1), and the
        // left shift (coded row 0) in full at column 0 and by 3/4, 1/2, 1/4 after it.
        assert_eq!(row(0), [92, 93, 94, 95, 106, 106, 106, 106]);
        assert_eq!(row(1)[4..], [105, 105, 105, 105]);
        assert_eq!(row(3)[4..], [102, 102, 102, 102]);
        // Row 2, columns 0 to 3: half the top shift and the left one by 4/4 to 1/4.
        assert_eq!(row(2)[..4], [94, 95, 96, 97]);
        // One coded pixel in, nothing moves.
        assert!((4..8).all(|j| row(j) == [100; 8]));
    }

    /// Fails at its `n`-th tile.
    struct FailsAt(usize);

    impl PixelSink for FailsAt {
        type Error = usize;

        fn tile(&mut self, _tile: Tile<'_>) -> Result<(), usize> {
            if self.0 == 0 {
                return Err(42);
            }
            self.0 -= 1;
            Ok(())
        }
    }

    /// Yields one byte per call and counts the calls made after the end.
    struct ByteByByte<'a> {
        data: &'a [u8],
        pos: usize,
        past_end: usize,
    }

    impl<'a> ByteByByte<'a> {
        fn new(data: &'a [u8]) -> Self {
            ByteByByte {
                data,
                pos: 0,
                past_end: 0,
            }
        }
    }

    impl ByteSource for ByteByByte<'_> {
        fn next_byte(&mut self) -> Option<u8> {
            let b = self.data.get(self.pos).copied();
            match b {
                Some(_) => self.pos += 1,
                None => self.past_end += 1,
            }
            b
        }
    }

    fn golden() -> Vec<(String, Vec<u8>)> {
        let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../tests/golden");
        let mut out = Vec::new();
        if let Ok(entries) = std::fs::read_dir(&dir) {
            for e in entries.flatten() {
                let name = e.file_name().to_string_lossy().into_owned();
                if name.ends_with(".pifs") {
                    out.push((name, std::fs::read(e.path()).unwrap()));
                }
            }
        }
        out.sort();
        out
    }

    /// The longest header this decoder reads: sides of 65535 and a payload length of `2^32 -
    /// 1` (three and five LEB128 bytes), the coding fields, and a 16-bit stream's value range
    /// (an 8-bit stream's header without the `deep` feature).
    fn longest_header() -> Vec<u8> {
        let deep = cfg!(feature = "deep");
        // Tag; flags: smoothing 0, coding fields follow, 16-bit when built in.
        let flags = 4 | if deep { 2 } else { 0 };
        let mut h = Vec::from([crate::format::STREAM_TAG, flags]);
        // Checksum (not checked by the header parser), width and height less one, leaf sizes,
        // stripe, the payload length, a 16-bit stream's range.
        h.extend_from_slice(&[1, 2, 3, 4, 0xFE, 0xFF, 0x03, 0xFE, 0xFF, 0x03, 0x42, 0]);
        h.extend_from_slice(&[0xFF, 0xFF, 0xFF, 0xFF, 0x0F]);
        if deep {
            h.extend_from_slice(&[0x10, 0, 0x20, 0]);
        }
        h
    }

    fn decode_slice(data: &[u8], sink: &mut Recorder) -> Result<Header, DecodeError> {
        Ok(Decoder::new(data)?.decode(sink)?)
    }

    fn decode_streamed<B: ByteSource>(
        source: B,
        sink: &mut Recorder,
    ) -> Result<Header, DecodeError> {
        Ok(Decoder::from_source(source)?.decode(sink)?)
    }

    #[test]
    fn header_is_read_exactly() {
        let mut bytes = longest_header();
        let len = bytes.len();
        bytes.extend_from_slice(&[0xAB, 0xCD]);
        let mut src = ByteByByte::new(&bytes);
        let (header, _) = read_header(&mut src).unwrap();
        assert_eq!(src.pos, len, "read past the header");
        assert_eq!(header.encoded_len(), len);
        assert_eq!(Header::parse(&bytes).unwrap(), (header, len));
        assert_eq!(
            len + usize::from(!cfg!(feature = "deep")) * 4,
            MAX_HEADER_LEN
        );
    }

    #[test]
    fn every_truncated_header_matches_the_slice_parser() {
        let bytes = longest_header();
        for cut in 0..bytes.len() {
            let mut src = ByteByByte::new(&bytes[..cut]);
            let streamed = read_header(&mut src).map(|(h, _)| h);
            let sliced = Header::parse(&bytes[..cut]).map(|(h, _)| h);
            assert_eq!(streamed, sliced, "cut at {cut}");
        }
    }

    #[test]
    fn streamed_equals_sliced_for_every_golden_vector_and_prefix() {
        let vectors = golden();
        assert!(!vectors.is_empty(), "no golden vectors in tests/golden/");
        for (name, data) in &vectors {
            let mut sliced = Recorder::default();
            let r_slice = decode_slice(data, &mut sliced);
            let mut streamed = Recorder::default();
            let mut src = ByteByByte::new(data);
            let r_stream = decode_streamed(&mut src, &mut streamed);
            assert_eq!(r_stream, r_slice, "{name}");
            // The header's flags (byte 1): colour, 16-bit samples.
            let flags = data.get(1).copied().unwrap_or_default();
            if flags & crate::syntax::FLAG_COLOUR != 0 && !cfg!(feature = "colour") {
                // Without the `colour` feature: refused on the header, by both.
                assert_eq!(r_slice, Err(DecodeError::UnsupportedChannels(3)), "{name}");
                continue;
            }
            if flags & crate::syntax::FLAG_DEEP != 0 && !cfg!(feature = "deep") {
                // Without the `deep` feature: refused on the header, by both.
                assert_eq!(r_slice, Err(DecodeError::UnsupportedBitDepth(16)), "{name}");
                continue;
            }
            assert_eq!(streamed, sliced, "{name}: tiles differ");
            assert_eq!((src.pos, src.past_end), (data.len(), 0), "{name}");
            // Truncated streams fail identically; the slice decoder refuses them before
            // drawing, the streaming one after drawing a prefix of the image's tiles.
            for cut in (0..data.len()).step_by(1 + data.len() / 64) {
                let mut a = Recorder::default();
                let mut b = Recorder::default();
                let ra = decode_slice(&data[..cut], &mut a);
                let rb = decode_streamed(SliceSource::new(&data[..cut]), &mut b);
                assert_eq!(ra, Err(DecodeError::Truncated), "{name} cut at {cut}");
                assert_eq!(ra, rb, "{name} cut at {cut}");
                assert!(
                    a.tiles.is_empty(),
                    "{name} cut at {cut}: drew a truncated stream"
                );
                assert_eq!(
                    b.tiles[..],
                    sliced.tiles[..b.tiles.len()],
                    "{name} cut at {cut}"
                );
            }
        }
    }

    #[test]
    fn clipped_decoding_is_the_full_decode_cut_to_the_clip() {
        for (name, data) in &golden() {
            let Ok(decoder) = Decoder::new(data) else {
                continue;
            };
            let header = *decoder.header();
            let (w, h) = (u32::from(header.width), u32::from(header.height));
            let mut full = std::vec![0u8; (w * h) as usize];
            if decoder.decode_into(&mut full).is_err() {
                continue;
            }
            let clips = [
                Rect { x: 0, y: 0, w, h },
                Rect {
                    x: w / 3,
                    y: h / 4,
                    w: w / 2 + 1,
                    h: h / 3 + 1,
                },
                Rect {
                    x: w - 1,
                    y: 0,
                    w: 100,
                    h: 1,
                },
                Rect {
                    x: w,
                    y: h,
                    w: 5,
                    h: 5,
                },
            ];
            for clip in clips {
                let mut rec = Recorder::default();
                Decoder::new(data)
                    .unwrap()
                    .clip(clip)
                    .decode(&mut rec)
                    .unwrap();
                let mut streamed = Recorder::default();
                Decoder::from_source(SliceSource::new(data))
                    .unwrap()
                    .clip(clip)
                    .decode(&mut streamed)
                    .unwrap();
                assert_eq!(rec, streamed, "{name}: clip {clip:?}");
                let inside = clip.intersect(&Rect::of_size(w, h));
                let mut seen = std::vec![0u32; (w * h) as usize];
                for (area, px) in &rec.tiles {
                    assert!(area.w as usize <= crate::synthesis::TILE);
                    assert!(area.h as usize <= crate::synthesis::TILE);
                    for j in 0..area.h {
                        for i in 0..area.w {
                            let (px_x, px_y) = (area.x + i, area.y + j);
                            let pixel = Rect {
                                x: px_x,
                                y: px_y,
                                w: 1,
                                h: 1,
                            };
                            assert!(
                                inside.contains(&pixel),
                                "{name}: pixel ({px_x}, {px_y}) outside clip {clip:?}"
                            );
                            let k = (px_y * w + px_x) as usize;
                            seen[k] += 1;
                            assert_eq!(px[(j * area.w + i) as usize], full[k], "{name}");
                        }
                    }
                }
                let covered = seen.iter().filter(|&&c| c == 1).count() as u32;
                assert_eq!(covered, inside.w * inside.h, "{name}: clip {clip:?}");
                assert!(seen.iter().all(|&c| c <= 1), "{name}: overdraw");
            }
        }
    }

    /// A sink's error ends the decode at once and comes back as itself; a streamed decode does
    /// not read on (past the first leaf of a stream of many).
    #[test]
    fn a_failing_sink_stops_the_decode() {
        for (name, data) in &golden() {
            let Ok(decoder) = Decoder::new(data) else {
                continue;
            };
            let mut leaves = 0;
            Decoder::new(data)
                .unwrap()
                .observe(|_: &LeafInfo| leaves += 1)
                .verify()
                .unwrap();
            assert_eq!(
                decoder.decode(&mut FailsAt(1)),
                Err(DrawError::Sink(42)),
                "{name}"
            );
            let mut src = ByteByByte::new(data);
            let r = Decoder::from_source(&mut src)
                .unwrap()
                .decode(&mut FailsAt(0));
            assert_eq!(r, Err(DrawError::Sink(42)), "{name}");
            assert_eq!(src.past_end, 0, "{name}");
            if leaves > 4 {
                assert!(
                    src.pos < data.len(),
                    "{name}: read on after the sink failed"
                );
            }
        }
    }

    /// The observer sees every leaf once, in coding order, and a verify draws nothing.
    #[test]
    fn observers_see_every_leaf_and_verify_draws_nothing() {
        for (name, data) in &golden() {
            let Ok(decoder) = Decoder::new(data) else {
                continue;
            };
            let header = *decoder.header();
            let mut area = 0u64;
            decoder
                .observe(|leaf: &LeafInfo| {
                    let r = leaf
                        .node
                        .rect()
                        .intersect(&Rect::of_size(header.width.into(), header.height.into()));
                    area += u64::from(r.w) * u64::from(r.h);
                })
                .verify()
                .unwrap();
            assert_eq!(area, header.pixel_count() as u64, "{name}");
        }
    }
}

//! The bitstream syntax ([`VERSION`]): the header, and every syntax element of the payload in the
//! order it is coded (where a byte is parsed). `docs/bitstream.md` is the prose form of this
//! module.
//!
//! Payload elements are coded through the [`Coder`] trait, so the decoder, the host encoder's
//! writer and its rate estimator all run this same code.

pub mod control;
pub mod initial_contexts;

use crate::checksum::Crc32;
use crate::colour::{chroma_models, ChromaPlane, CHROMA_GRIDS};
use crate::entropy::{code_tree, code_unary, Coder, IntContexts, Prob};
use crate::error::{DecodeError, HeaderField, PayloadError, SyntaxElement};
use crate::format::{
    check_tag, div_round, load, med, read_leb128, store, write_leb128, Leb128Error, TagCheck,
    CODING_TILE,
};
pub use crate::format::{
    SampleRange, MAX_LEAF_LOG2, MIN_LEAF_LOG2, PACKET_TAG, PARITY_TAG, STREAM_TAG, VERSION,
};
use crate::geometry::Node;
use crate::model::{ModelType, MAX_CONTROL, MAX_GRID, MODELS, MODEL_COUNT, SAMPLE_MAX, SAMPLE_MIN};
use crate::prediction::{edge_context, edge_offset, edge_pixel, SamplePrediction};
use crate::synthesis::Patch;
use control::{
    band_level, coefficient_step, expand_pixel_grid, fine_starts, grid_position,
    inverse_grid_transform, transform_order, CONTROL_QUANTISERS, CONTROL_STEPS,
};
use initial_contexts::{CHROMA_INITIAL_PROBABILITIES, INITIAL_PROBABILITIES};

/// Size of the fixed part of the header, in bytes: the tag, the flags and the checksum.
pub const FIXED_HEADER_LEN: usize = 6;
/// Where the stream's CRC-32 sits: the only bytes of a stream that its checksum does not cover.
pub const CHECKSUM_BYTES: core::ops::Range<usize> = 2..6;
/// Shortest possible header: the fixed part and one byte each for the width, the height and
/// the payload length. A decoder reading a sequential source reads this much at once.
pub const MIN_HEADER_LEN: usize = FIXED_HEADER_LEN + 3;
/// Largest edge-smoothing strength ([`Header::deblock`]).
pub const MAX_DEBLOCK: u8 = 16;
/// Longest encoding of the payload length (LEB128 of a `u32`).
pub const MAX_LENGTH_BYTES: usize = 5;
/// Longest encoding of a width or height less one (LEB128 of at most 16 bits).
pub const MAX_SIZE_BYTES: usize = 3;
/// Bytes of the optional coding fields: the leaf sizes and the stripe.
pub const CODING_BYTES: usize = 2;
/// Bytes of the value range a 16-bit stream's header ends with ([`SampleRange`]).
pub const RANGE_BYTES: usize = 4;
/// Longest possible header: the fixed part, the longest width, height and payload length, the
/// coding fields and a 16-bit stream's value range (23 bytes). A decoder reading a sequential
/// source never buffers more.
pub const MAX_HEADER_LEN: usize =
    FIXED_HEADER_LEN + 2 * MAX_SIZE_BYTES + CODING_BYTES + MAX_LENGTH_BYTES + RANGE_BYTES;
/// The leaf sizes (`max << 4 | min`) and the stripe of a stream whose flags do not say they
/// follow: leaves of 4 to 128 pixels, one stripe as wide as the image.
pub const DEFAULT_STREAM_CODING: [u8; 2] = [0x72, 0];

/// Flag bit of a stream's or a packet's flags byte: colour (3 channels; else grayscale).
pub const FLAG_COLOUR: u8 = 1;
/// Flag bit of a stream's flags byte: 16-bit samples (else 8-bit). A packet's bit 1 says
/// "preview" instead.
pub const FLAG_DEEP: u8 = 2;
/// Flag bit of a stream's or a packet's flags byte: the coding fields (leaf sizes, stripe)
/// follow; else they are the defaults of the kind.
pub const FLAG_CODING: u8 = 4;
/// The flags byte's bits 3 to 7 hold the edge-smoothing strength.
pub const DEBLOCK_SHIFT: u32 = 3;

/// Reads a width or height at `*pos` (advanced past it): the side less one, unsigned LEB128 in
/// at most three bytes; the side must be 1..=65535 (else [`Leb128Error::Malformed`]). The
/// error is a byte wide: the caller names the field ([`side_error`]).
pub fn read_side(data: &[u8], pos: &mut usize) -> Result<u16, Leb128Error> {
    match read_leb128(data, pos, MAX_SIZE_BYTES)? {
        v if v < 0xFFFF => Ok(v as u16 + 1),
        _ => Err(Leb128Error::Malformed),
    }
}

/// The error of a width or height that [`read_side`] refused.
pub fn side_error(e: Leb128Error) -> DecodeError {
    match e {
        Leb128Error::Truncated => DecodeError::Truncated,
        Leb128Error::Malformed => DecodeError::InvalidHeader(HeaderField::Dimensions),
    }
}

/// Writes a width or height (1..=65535) as [`read_side`] reads it; returns the position after.
pub fn write_side(out: &mut [u8], pos: usize, side: u16) -> usize {
    write_leb128(out, pos, u32::from(side.max(1)) - 1)
}

/// Checks the first byte of `data` against `tag` ([`STREAM_TAG`] or a packet's): the same
/// kind of another tagged version is [`DecodeError::UnsupportedVersion`], anything else
/// [`DecodeError::BadMagic`] (a random first byte is a stream's of some other version about
/// one time in six); no byte at all, [`DecodeError::Truncated`].
pub fn check_first_byte(data: &[u8], tag: u8) -> Result<(), DecodeError> {
    let Some(&first) = data.first() else {
        return Err(DecodeError::Truncated);
    };
    match check_tag(first, tag) {
        TagCheck::Expected => Ok(()),
        TagCheck::OtherVersion(v) => Err(DecodeError::UnsupportedVersion(v)),
        TagCheck::Unknown => Err(DecodeError::BadMagic),
    }
}

/// The stream header.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Header {
    /// Image width in pixels (1..=65535).
    pub width: u16,
    /// Image height in pixels (1..=65535).
    pub height: u16,
    /// Channels per pixel (1: grayscale).
    pub channels: u8,
    /// Bits per sample of the data: 8, or 16 for a grayscale stream whose samples stand for
    /// values in [`Header::range`].
    pub bit_depth: u8,
    /// Smallest leaf side, as a power of two.
    pub min_leaf_log2: u8,
    /// Largest leaf side, as a power of two.
    pub max_leaf_log2: u8,
    /// Width of the stripes the image is coded in, in coding tiles of [`CODING_TILE`] pixels;
    /// 0 for one stripe as wide as the image ([`Header::stripe_width`]).
    pub stripe: u8,
    /// Strength of the smoothing of leaf edges, 0 (none) to [`MAX_DEBLOCK`]: a step across a
    /// leaf's top or left edge is smoothed by a third when it is at most `deblock / 2` of the
    /// leaf's control steps, by less up to four times that (see the prediction frontier's
    /// `Capture`).
    pub deblock: u8,
    /// Length of the payload in bytes: the stream ends right after it.
    pub payload_len: u32,
    /// CRC-32 of every byte of the stream except the four that hold it
    /// ([`CHECKSUM_BYTES`]): see [`stream_checksum`].
    pub checksum: u32,
    /// The values a 16-bit stream's samples stand for; `None` for an 8-bit stream.
    pub range: Option<SampleRange>,
}

/// The CRC-32 a stream must carry: over all its bytes (header and payload) except
/// [`CHECKSUM_BYTES`], in order. `data` is the whole stream.
pub fn stream_checksum(data: &[u8]) -> u32 {
    let mut crc = Crc32::default();
    crc.update(data.get(..CHECKSUM_BYTES.start).unwrap_or(data));
    crc.update(data.get(CHECKSUM_BYTES.end..).unwrap_or(&[]));
    crc.value()
}

/// Writes the checksum of the complete stream `data` (header and payload) into its header
/// field; streams shorter than the fixed header are left alone.
pub fn seal(data: &mut [u8]) {
    let checksum = stream_checksum(data);
    if let Some(field) = data.get_mut(CHECKSUM_BYTES) {
        field.copy_from_slice(&checksum.to_le_bytes());
    }
}

/// Bytes of the LEB128 encoding of `v`.
fn leb128_len(v: u32) -> usize {
    let mut n = 1;
    let mut v = v >> 7;
    while v != 0 {
        n += 1;
        v >>= 7;
    }
    n
}

/// Checks the leaf-sizes byte (`max << 4 | min`) and the edge-smoothing strength of a header
/// (a stream's or a packet's); returns the smallest and largest leaf sizes (log2).
pub fn check_coding_fields(leaf_sizes: u8, deblock: u8) -> Result<(u8, u8), DecodeError> {
    let min_leaf_log2 = leaf_sizes & 0x0F;
    let max_leaf_log2 = leaf_sizes >> 4;
    if !(MIN_LEAF_LOG2..=MAX_LEAF_LOG2).contains(&min_leaf_log2)
        || !(min_leaf_log2..=MAX_LEAF_LOG2).contains(&max_leaf_log2)
    {
        return Err(DecodeError::InvalidHeader(HeaderField::LeafSizes));
    }
    if deblock > MAX_DEBLOCK {
        return Err(DecodeError::InvalidHeader(HeaderField::Deblock));
    }
    Ok((min_leaf_log2, max_leaf_log2))
}

impl Header {
    /// Side of the quadtree's root, as a power of two: the smallest square that covers the
    /// image and is at least one smallest leaf.
    pub fn root_log2(&self) -> u8 {
        let side = u32::from(self.width.max(self.height));
        let mut log2 = 0u8;
        while (1u32 << log2) < side {
            log2 += 1;
        }
        log2.max(self.min_leaf_log2)
    }

    /// Width of the stripes the image is coded in, pixels: a multiple of [`CODING_TILE`], at
    /// most the image's width rounded up to one. A decoder holds one byte per column of a
    /// stripe.
    pub fn stripe_width(&self) -> u32 {
        let whole = u32::from(self.width).div_ceil(CODING_TILE) * CODING_TILE;
        match self.stripe {
            0 => whole,
            k => (u32::from(k) * CODING_TILE).min(whole),
        }
    }

    /// Number of pixels.
    pub fn pixel_count(&self) -> usize {
        usize::from(self.width) * usize::from(self.height)
    }

    /// Whether the leaf sizes and the stripe differ from [`DEFAULT_STREAM_CODING`], and so are
    /// written.
    fn custom_coding(&self) -> bool {
        self.coding_fields() != DEFAULT_STREAM_CODING
    }

    /// The leaf sizes (`max << 4 | min`) and the stripe, as written.
    fn coding_fields(&self) -> [u8; 2] {
        [(self.max_leaf_log2 << 4) | self.min_leaf_log2, self.stripe]
    }

    /// Length of the serialised header in bytes.
    pub fn encoded_len(&self) -> usize {
        let side = |v: u16| leb128_len(u32::from(v.max(1)) - 1);
        let coding = if self.custom_coding() {
            CODING_BYTES
        } else {
            0
        };
        let range = if self.range.is_some() { RANGE_BYTES } else { 0 };
        FIXED_HEADER_LEN
            + side(self.width)
            + side(self.height)
            + coding
            + leb128_len(self.payload_len)
            + range
    }

    /// Length of the whole stream: header and payload.
    pub fn stream_len(&self) -> u64 {
        self.encoded_len() as u64 + u64::from(self.payload_len)
    }

    /// Reads and validates the header at the start of `data` (the payload need not follow: this
    /// is how a caller learns an image's size before deciding to decode it).
    pub fn read(data: &[u8]) -> Result<Header, DecodeError> {
        Header::parse(data).map(|(header, _)| header)
    }

    /// Parses the header at the start of `data`; returns it and the offset of the payload.
    pub fn parse(data: &[u8]) -> Result<(Header, usize), DecodeError> {
        check_first_byte(data, STREAM_TAG)?;
        let fixed = data.get(..FIXED_HEADER_LEN).ok_or(DecodeError::Truncated)?;
        let flags = fixed[1];
        let channels = if flags & FLAG_COLOUR != 0 { 3 } else { 1 };
        if channels == 3 && !cfg!(feature = "colour") {
            return Err(DecodeError::UnsupportedChannels(channels));
        }
        let bit_depth = if flags & FLAG_DEEP != 0 { 16 } else { 8 };
        if bit_depth == 16 && (channels != 1 || !cfg!(feature = "deep")) {
            return Err(DecodeError::UnsupportedBitDepth(bit_depth));
        }
        let deblock = flags >> DEBLOCK_SHIFT;
        let mut pos = FIXED_HEADER_LEN;
        let width = read_side(data, &mut pos).map_err(side_error)?;
        let height = read_side(data, &mut pos).map_err(side_error)?;
        let [leaf_sizes, stripe] = match flags & FLAG_CODING != 0 {
            true => {
                let fields = data
                    .get(pos..pos + CODING_BYTES)
                    .ok_or(DecodeError::Truncated)?;
                pos += CODING_BYTES;
                // Written only when not the defaults: one header, one encoding.
                match [fields[0], fields[1]] {
                    DEFAULT_STREAM_CODING => {
                        return Err(DecodeError::InvalidHeader(HeaderField::CodingFields))
                    }
                    fields => fields,
                }
            }
            false => DEFAULT_STREAM_CODING,
        };
        let (min_leaf_log2, max_leaf_log2) = check_coding_fields(leaf_sizes, deblock)?;
        let mut header = Header {
            width,
            height,
            channels,
            bit_depth,
            min_leaf_log2,
            max_leaf_log2,
            stripe,
            deblock,
            payload_len: 0,
            checksum: u32::from_le_bytes([fixed[2], fixed[3], fixed[4], fixed[5]]),
            range: None,
        };
        // Payload length: LEB128, at most five bytes and 32 bits, no redundant trailing zero
        // group.
        header.payload_len =
            read_leb128(data, &mut pos, MAX_LENGTH_BYTES).map_err(|e| match e {
                Leb128Error::Truncated => DecodeError::Truncated,
                Leb128Error::Malformed => DecodeError::InvalidHeader(HeaderField::PayloadLength),
            })?;
        if bit_depth == 16 {
            // A deep stream's samples are delivered as the leaves make them: nothing is
            // smoothed (see the prediction frontier's `Capture`).
            if header.deblock != 0 {
                return Err(DecodeError::InvalidHeader(HeaderField::Deblock));
            }
            let range = data
                .get(pos..pos + RANGE_BYTES)
                .ok_or(DecodeError::Truncated)?;
            let low = u16::from_le_bytes([range[0], range[1]]);
            let step = u16::from_le_bytes([range[2], range[3]]);
            if step == 0 {
                return Err(DecodeError::InvalidHeader(HeaderField::Range));
            }
            header.range = Some(SampleRange { low, step });
            pos += RANGE_BYTES;
        }
        Ok((header, pos))
    }

    /// Serialises the header into `out` (which must hold [`Header::encoded_len`] bytes);
    /// returns the number of bytes written.
    pub fn write(&self, out: &mut [u8]) -> usize {
        let mut flags = self.deblock << DEBLOCK_SHIFT;
        if self.channels == 3 {
            flags |= FLAG_COLOUR;
        }
        if self.bit_depth == 16 {
            flags |= FLAG_DEEP;
        }
        let custom = self.custom_coding();
        if custom {
            flags |= FLAG_CODING;
        }
        out[0] = STREAM_TAG;
        out[1] = flags;
        out[CHECKSUM_BYTES].copy_from_slice(&self.checksum.to_le_bytes());
        let mut len = write_side(out, FIXED_HEADER_LEN, self.width);
        len = write_side(out, len, self.height);
        if custom {
            out[len..len + CODING_BYTES].copy_from_slice(&self.coding_fields());
            len += CODING_BYTES;
        }
        len = write_leb128(out, len, self.payload_len);
        if let Some(SampleRange { low, step }) = self.range {
            out[len..len + 2].copy_from_slice(&low.to_le_bytes());
            out[len + 2..len + RANGE_BYTES].copy_from_slice(&step.to_le_bytes());
            len += RANGE_BYTES;
        }
        len
    }
}

/// How a leaf's control values are coded (the 'transform' flag).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ControlCoding {
    /// DPCM within the leaf: suits edges.
    Dpcm,
    /// The DCT of the control grid: suits texture and smooth shading.
    Transform,
}

/// The syntax elements of one leaf, as coded: of its luma, or of one of its chroma planes (a
/// colour stream's `Cb` or `Cr`, [`code_chroma`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LeafSyntax {
    /// Model type: index into [`MODELS`] (luma) or [`CHROMA_GRIDS`] (chroma).
    pub model: u8,
    /// Control quantiser index into [`CONTROL_STEPS`].
    pub cquant: u8,
    /// How the control values are coded.
    pub coding: ControlCoding,
    /// Control values as quantiser indices, row-major over the coded grid
    /// ([`ModelType::coded_side`]): DPCM indices (see [`control_value`]) or grid-transform
    /// coefficient indices (see [`transform_control_values`]), by `coding`.
    pub control: [i16; MAX_CONTROL],
}

impl Default for LeafSyntax {
    fn default() -> Self {
        LeafSyntax {
            model: 0,
            cquant: 0,
            coding: ControlCoding::Dpcm,
            control: [0; MAX_CONTROL],
        }
    }
}

/// Control class: a leaf's first value (DPCM) or low band (transform), predicted from one
/// neighbour's pixel or none.
const CLASS_FIRST: usize = 0;
/// Control class: a leaf's first value or low band, predicted from the pixels left of and
/// above its corner.
const CLASS_SHARED: usize = 1;
/// Control class (DPCM): the rest of the first row and column.
const CLASS_EDGE: usize = 2;
/// Control class (DPCM): the interior of the grid.
const CLASS_INTERIOR: usize = 3;
/// Control classes from here (transform): detail bands by level, finest first.
const CLASS_DETAIL: usize = 4;
/// Detail levels with contexts of their own (coarser levels share the last).
const DETAIL_CLASSES: usize = 3;
/// Number of residual classes of control coefficients.
pub const CONTROL_CLASSES: usize = CLASS_DETAIL + DETAIL_CLASSES;
/// Control residuals have separate contexts for fine, medium and coarse steps.
pub const STEP_GROUPS: usize = 3;

/// The residual class of every control index but a leaf's first (grid position `(r, c)`, not
/// `(0, 0)`): by transform level under the grid transform, first row and column or interior
/// under DPCM.
#[inline]
pub fn control_class(transform: bool, side: usize, r: usize, c: usize) -> usize {
    if transform {
        detail_class(band_level(side, r, c))
    } else if r == 0 || c == 0 {
        CLASS_EDGE
    } else {
        CLASS_INTERIOR
    }
}

/// The class of a grid-transform coefficient of band level `level` (0: the finest detail).
#[inline(always)]
fn detail_class(level: usize) -> usize {
    CLASS_DETAIL + level.min(DETAIL_CLASSES - 1)
}

/// The control step of control quantiser `cq`, in sample units (0 for a value no leaf has).
pub fn control_step(cq: u8) -> i32 {
    CONTROL_STEPS.get(usize::from(cq)).copied().unwrap_or(0)
}

// The 'cquant' element is a tree of four bits: each of its 16 values names a quantiser.
const _: () = assert!(CONTROL_QUANTISERS == 1 << 4);

/// The context group of control quantiser `cq`: steps up to 64, 96 to 256, 384 and up.
pub fn step_group(cq: u8) -> usize {
    match control_step(cq) {
        ..=64 => 0,
        65..=256 => 1,
        _ => 2,
    }
}

/// All adaptive contexts of the payload. Starts at [`Contexts::default`] for every stream.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Contexts {
    split: [Prob; MAX_LEAF_LOG2 as usize + 1],
    model: [[Prob; MODEL_COUNT]; MAX_LEAF_LOG2 as usize + 1],
    cquant: [[Prob; 16]; MODEL_COUNT],
    coding: [Prob; MODEL_COUNT],
    control: [[IntContexts; CONTROL_CLASSES]; STEP_GROUPS],
}

impl Default for Contexts {
    /// The contexts at the start of every stream ([`Contexts::start`]).
    fn default() -> Self {
        let mut contexts = Contexts::UNSTARTED;
        contexts.start();
        contexts
    }
}

/// Number of adaptive contexts of a stream ([`Contexts::for_each_prob`]).
pub const CONTEXT_COUNT: usize = (MAX_LEAF_LOG2 as usize + 1) * (1 + MODEL_COUNT)
    + MODEL_COUNT * (16 + 1)
    + STEP_GROUPS * CONTROL_CLASSES * IntContexts::COUNT;

impl Contexts {
    /// Every context not yet started ([`Prob::UNSTARTED`]): all zero bits, so that a decoder
    /// clears its contexts in place (rather than copying a constant onto its stack) before
    /// [`Contexts::start`] sets them.
    pub const UNSTARTED: Contexts = Contexts {
        split: [Prob::UNSTARTED; MAX_LEAF_LOG2 as usize + 1],
        model: [[Prob::UNSTARTED; MODEL_COUNT]; MAX_LEAF_LOG2 as usize + 1],
        cquant: [[Prob::UNSTARTED; 16]; MODEL_COUNT],
        coding: [Prob::UNSTARTED; MODEL_COUNT],
        control: [[IntContexts::UNSTARTED; CONTROL_CLASSES]; STEP_GROUPS],
    };

    /// The contexts of control residuals of class `class` (below [`CONTROL_CLASSES`]) in step
    /// group `group` (below [`STEP_GROUPS`], [`step_group`]), for an encoder that prices
    /// residuals before coding them.
    pub fn control_residuals(&self, group: usize, class: usize) -> Option<&IntContexts> {
        self.control.get(group)?.get(class)
    }

    /// Sets every context to its state at the start of a stream: the trained probability of
    /// [`INITIAL_PROBABILITIES`], in [`Contexts::for_each_prob`] order, as if
    /// [`crate::entropy::INITIAL_COUNT`] bits had been coded with it. Fresh contexts would
    /// spend the first bits of every stream learning what every stream looks like.
    pub fn start(&mut self) {
        let mut table = INITIAL_PROBABILITIES.iter();
        self.for_each_prob(|p| *p = Prob::initial(table.next().copied().unwrap_or(128)));
    }

    /// Calls `f` on every context, in the order of the specification's table of initial
    /// probabilities: split flags by level, model by level (row-major), cquant by model, coding
    /// by model, the control integer classes by step group then class (each integer class as
    /// [`IntContexts::for_each_prob`]).
    pub fn for_each_prob(&mut self, mut f: impl FnMut(&mut Prob)) {
        self.split.iter_mut().for_each(&mut f);
        self.model.iter_mut().flatten().for_each(&mut f);
        self.cquant.iter_mut().flatten().for_each(&mut f);
        self.coding.iter_mut().for_each(&mut f);
        for class in self.control.iter_mut().flatten() {
            class.for_each_prob(&mut f);
        }
    }
}

/// Codes the split flag of a node of side `2^log2` (only coded where the node could be either a
/// leaf or split: see the quadtree walk).
pub fn code_split<C: Coder>(
    c: &mut C,
    ctx: &mut Contexts,
    log2: u8,
    split: &mut bool,
) -> Result<(), PayloadError> {
    let p = ctx
        .split
        .get_mut(usize::from(log2))
        .ok_or(PayloadError::InvalidData(SyntaxElement::NodeSize))?;
    c.bit(p, split)
}

/// The models usable at a block of side `2^log2` ([`ModelType::fits_block`]), in index order,
/// and how many there are (none for a size no leaf may have).
pub fn models_for_block(log2: u8) -> ([u8; MODEL_COUNT], usize) {
    BLOCK_MODELS
        .get(usize::from(log2))
        .map_or(([0; MODEL_COUNT], 0), |&(list, n)| (list, usize::from(n)))
}

/// [`models_for_block`] for every leaf size, built at compile time (in bytes: flash is tight).
const BLOCK_MODELS: [([u8; MODEL_COUNT], u8); MAX_LEAF_LOG2 as usize + 1] = block_models();

const fn block_models() -> [([u8; MODEL_COUNT], u8); MAX_LEAF_LOG2 as usize + 1] {
    let mut out = [([0u8; MODEL_COUNT], 0u8); MAX_LEAF_LOG2 as usize + 1];
    let mut log2 = 0;
    while log2 <= MAX_LEAF_LOG2 as usize {
        let mut i = 0;
        while i < MODEL_COUNT {
            if MODELS[i].fits_block(log2 as u8) {
                out[log2].0[out[log2].1 as usize] = i as u8;
                out[log2].1 += 1;
            }
            i += 1;
        }
        log2 += 1;
    }
    out
}

/// Codes a leaf: model type, control quantiser, coding, control values (syntax only:
/// [`reconstruct_into`] makes the patch). `prediction` supplies the values of earlier leaves.
pub fn code_leaf<C: Coder, P: SamplePrediction>(
    c: &mut C,
    ctx: &mut Contexts,
    node: &Node,
    prediction: &P,
    leaf: &mut LeafSyntax,
) -> Result<(), PayloadError> {
    let log2 = node.log2;
    let (models, count) = models_for_block(log2);
    if count == 0 {
        return Err(PayloadError::InvalidData(SyntaxElement::LeafSize));
    }
    // Model type: truncated unary over the models this block size allows.
    let mut pos = models
        .iter()
        .take(count)
        .position(|&m| m == leaf.model)
        .unwrap_or(0) as u32;
    let model_ctx = ctx
        .model
        .get_mut(usize::from(log2))
        .ok_or(PayloadError::InvalidData(SyntaxElement::LeafSize))?;
    code_unary(c, model_ctx, count as u32, &mut pos)?;
    leaf.model = models.get(pos as usize).copied().unwrap_or(0);
    let model = leaf_model(leaf)?;
    let mi = usize::from(leaf.model);

    let mut cq = u32::from(leaf.cquant);
    // Four bits: every value names one of the 16 quantisers.
    code_tree(c, &mut ctx.cquant[mi], 4, &mut cq)?;
    leaf.cquant = cq as u8;

    let mut transform = leaf.coding == ControlCoding::Transform;
    if model.has_coding_choice() {
        c.bit(&mut ctx.coding[mi], &mut transform)?;
    } else {
        transform = false;
    }
    leaf.coding = if transform {
        ControlCoding::Transform
    } else {
        ControlCoding::Dpcm
    };
    let step = *CONTROL_STEPS
        .get(usize::from(leaf.cquant))
        .ok_or(PayloadError::InvalidData(SyntaxElement::ControlQuantiser))?;
    let grid = ControlGrid {
        step,
        side: model.coded_side(log2),
        spacing: model.spacing(log2),
        transform,
    };
    code_control(
        c,
        &mut ctx.control[step_group(leaf.cquant)],
        &grid,
        node,
        prediction,
        &mut leaf.control,
    )
}

/// Intra-leaf prediction of control value `(r, c)` (not the first) from the leaf's values
/// reconstructed so far (row-major, side `side`): left on the first row, above on the first
/// column, the LOCO-I median elsewhere.
#[inline]
pub fn intra_prediction(values: &[i16], side: usize, r: usize, c: usize) -> i32 {
    let i = r * side + c;
    let at = |k: usize| i32::from(load(values, k));
    match (r, c) {
        (0, 0) => 0,
        (0, _) => at(i - 1),
        (_, 0) => at(i - side),
        _ => med(at(i - 1), at(i - side), at(i - side - 1)),
    }
}

/// Reconstructs control value `i` of a leaf from its index: the first value is `index * step`,
/// every other one `intra prediction + index * step`, clamped to the sample range.
#[inline]
pub fn control_value(values: &[i16], side: usize, i: usize, step: i32, index: i32) -> i16 {
    let base = if i == 0 {
        0
    } else {
        let (r, c) = grid_position(i, side);
        intra_prediction(values, side, r, c)
    };
    dequantise_control(base, step, index)
}

/// A control value from its prediction `base` (see [`control_value`]), step and index.
#[inline]
pub fn dequantise_control(base: i32, step: i32, index: i32) -> i16 {
    // The sample range fits in an i16.
    // An index beyond 2^16 steps saturates either way; within, the product fits 32 bits.
    base.saturating_add(index.clamp(-(1 << 16), 1 << 16) * step)
        .clamp(SAMPLE_MIN, SAMPLE_MAX) as i16
}

/// The control values of a leaf from its coefficient indices (row-major, side `side`) and its
/// control step, into `out`: every index times its coefficient's step ([`coefficient_step`],
/// saturated to 16 bits), through the inverse grid transform ([`inverse_grid_transform`]),
/// clamped to the sample range. Only the first `side * side` values are written.
#[inline(never)]
pub fn transform_control_values(
    side: usize,
    step: i32,
    indices: &[i16],
    out: &mut [i16; MAX_CONTROL],
) {
    let q = coefficient_step(side, step);
    for (v, &k) in out.iter_mut().zip(indices).take(side * side) {
        // A 16-bit index times a step below 2^14: no overflow.
        let c = i32::from(k) * q;
        *v = c.clamp(i32::from(i16::MIN), i32::from(i16::MAX)) as i16;
    }
    inverse_grid_transform(out, side);
    for v in out.iter_mut().take(side * side) {
        *v = (*v).clamp(SAMPLE_MIN as i16, SAMPLE_MAX as i16);
    }
}

/// The shape of a leaf's control coding: its step, the coded grid's side, the spacing of its
/// points in pixels, and whether it is the grid transform (else DPCM).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ControlGrid {
    /// Control step, sample units.
    pub step: i32,
    /// Side of the coded grid.
    pub side: usize,
    /// Pixels between grid points.
    pub spacing: u32,
    /// The grid transform (else DPCM).
    pub transform: bool,
}

/// Chroma quantiser indices with contexts of their own: a tree of 4 bits, as luma's.
const CHROMA_CQUANT_NODES: usize = 16;

/// The adaptive contexts of the chroma planes of a colour stream (shared by `Cb` and `Cr`),
/// separate from luma's: the chroma model by chroma leaf size, the quantiser and the coding
/// flag by chroma model, and one set of control residual classes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ChromaContexts {
    model: [[Prob; CHROMA_GRIDS.len()]; MAX_LEAF_LOG2 as usize],
    cquant: [[Prob; CHROMA_CQUANT_NODES]; CHROMA_GRIDS.len()],
    coding: [Prob; CHROMA_GRIDS.len()],
    control: [IntContexts; CONTROL_CLASSES],
    /// Whether a split node codes the chroma of its whole subtree, by the node's luma level.
    subtree: [Prob; MAX_LEAF_LOG2 as usize + 1],
}

impl Default for ChromaContexts {
    fn default() -> Self {
        let mut contexts = ChromaContexts::UNSTARTED;
        contexts.start();
        contexts
    }
}

impl ChromaContexts {
    /// Every context not yet started ([`Prob::UNSTARTED`]; all zero bits), before
    /// [`ChromaContexts::start`].
    pub const UNSTARTED: ChromaContexts = ChromaContexts {
        model: [[Prob::UNSTARTED; CHROMA_GRIDS.len()]; MAX_LEAF_LOG2 as usize],
        cquant: [[Prob::UNSTARTED; CHROMA_CQUANT_NODES]; CHROMA_GRIDS.len()],
        coding: [Prob::UNSTARTED; CHROMA_GRIDS.len()],
        control: [IntContexts::UNSTARTED; CONTROL_CLASSES],
        subtree: [Prob::UNSTARTED; MAX_LEAF_LOG2 as usize + 1],
    };

    /// The state at the start of a stream: the trained probability of
    /// [`CHROMA_INITIAL_PROBABILITIES`], in [`ChromaContexts::for_each_prob`] order, as if
    /// [`crate::entropy::INITIAL_COUNT`] bits had been coded with it (as luma's
    /// [`Contexts::start`]).
    pub fn start(&mut self) {
        let mut table = CHROMA_INITIAL_PROBABILITIES.iter();
        self.for_each_prob(|p| *p = Prob::initial(table.next().copied().unwrap_or(128)));
    }

    /// Calls `f` on every context, in the order of the specification's table of chroma initial
    /// probabilities: model by chroma level (row-major), cquant by model, coding by model, the
    /// control integer classes (each as [`IntContexts::for_each_prob`]), the subtree flag by
    /// luma level.
    pub fn for_each_prob(&mut self, mut f: impl FnMut(&mut Prob)) {
        self.model.iter_mut().flatten().for_each(&mut f);
        self.cquant.iter_mut().flatten().for_each(&mut f);
        self.coding.iter_mut().for_each(&mut f);
        for class in self.control.iter_mut() {
            class.for_each_prob(&mut f);
        }
        self.subtree.iter_mut().for_each(&mut f);
    }
}

/// Number of adaptive contexts of a colour stream's chroma ([`ChromaContexts::for_each_prob`]).
pub const CHROMA_CONTEXT_COUNT: usize = MAX_LEAF_LOG2 as usize * CHROMA_GRIDS.len()
    + CHROMA_GRIDS.len() * (CHROMA_CQUANT_NODES + 1)
    + CONTROL_CLASSES * IntContexts::COUNT
    + MAX_LEAF_LOG2 as usize
    + 1;

/// Codes whether the split node `node` of a colour stream (not inside a subtree whose chroma
/// is coded already) codes the chroma of its whole subtree (`subtree`), with a context by the
/// node's luma level.
pub fn code_chroma_subtree<C: Coder>(
    c: &mut C,
    ctx: &mut ChromaContexts,
    node: &Node,
    subtree: &mut bool,
) -> Result<(), PayloadError> {
    let p = ctx
        .subtree
        .get_mut(usize::from(node.log2))
        .ok_or(PayloadError::InvalidData(SyntaxElement::NodeSize))?;
    c.bit(p, subtree)
}

/// Codes one chroma plane of a leaf whose chroma node is `node` (side `2^log2`, chroma
/// coordinates): the chroma model (unary over the [`chroma_models`] allowed), the control
/// quantiser (tree of 4 bits), the transform flag (models with a grid of 2 or more intervals)
/// and the control values, exactly as a luma leaf codes them, predicted from the chroma
/// frontier (`prediction`). A chroma model of `g` intervals codes `(g + 1)^2` values, or `g^2`
/// when `g` is the leaf's side (a pixel grid).
pub fn code_chroma<C: Coder, P: SamplePrediction>(
    c: &mut C,
    ctx: &mut ChromaContexts,
    node: &Node,
    prediction: &P,
    leaf: &mut LeafSyntax,
) -> Result<(), PayloadError> {
    let count = chroma_models(node.log2);
    let model_ctx = ctx
        .model
        .get_mut(usize::from(node.log2))
        .ok_or(PayloadError::InvalidData(SyntaxElement::LeafSize))?;
    let mut pos = u32::from(leaf.model).min(count as u32 - 1);
    code_unary(c, model_ctx, count as u32, &mut pos)?;
    leaf.model = pos as u8;
    // `pos < count`, at most the number of chroma grids.
    let mi = (pos as usize).min(CHROMA_GRIDS.len() - 1);
    let mut cq = u32::from(leaf.cquant);
    // Four bits: every value names one of the 16 quantisers.
    code_tree(c, &mut ctx.cquant[mi], 4, &mut cq)?;
    leaf.cquant = cq as u8;
    let g = usize::from(CHROMA_GRIDS[mi].0);
    let mut transform = leaf.coding == ControlCoding::Transform;
    if g >= 2 {
        c.bit(&mut ctx.coding[mi], &mut transform)?;
    } else {
        transform = false;
    }
    leaf.coding = if transform {
        ControlCoding::Transform
    } else {
        ControlCoding::Dpcm
    };
    let grid = chroma_grid(leaf, node.log2);
    code_control(
        c,
        &mut ctx.control,
        &grid,
        node,
        prediction,
        &mut leaf.control,
    )
}

/// The control coding of a chroma plane's syntax at a chroma leaf of side `2^log2`.
pub fn chroma_grid(leaf: &LeafSyntax, log2: u8) -> ControlGrid {
    let g = CHROMA_GRIDS[usize::from(leaf.model) % CHROMA_GRIDS.len()].0;
    let size = 1u32 << log2.min(15);
    let pixel_grid = u32::from(g) >= size;
    ControlGrid {
        step: control_step(leaf.cquant).max(1),
        side: usize::from(g) + usize::from(!pixel_grid),
        // `g` is a power of two: a shift, no division.
        spacing: (size >> g.trailing_zeros()).max(1),
        transform: leaf.coding == ControlCoding::Transform,
    }
}

/// Reconstructs a chroma plane from its syntax at a chroma leaf of side `2^log2`.
pub fn reconstruct_chroma(
    leaf: &LeafSyntax,
    log2: u8,
    plane: &mut ChromaPlane,
) -> Result<(), PayloadError> {
    if usize::from(leaf.cquant) >= CONTROL_QUANTISERS {
        return Err(PayloadError::InvalidData(SyntaxElement::ControlQuantiser));
    }
    let (g, _) = *CHROMA_GRIDS
        .get(usize::from(leaf.model))
        .ok_or(PayloadError::InvalidData(SyntaxElement::ModelType))?;
    let grid = chroma_grid(leaf, log2);
    plane.grid = g;
    fill_control(
        &leaf.control,
        grid.side,
        grid.step,
        grid.transform,
        &mut plane.control,
    );
    if grid.side == usize::from(g) {
        expand_pixel_grid(&mut plane.control, grid.side);
    }
    // Within the sample range, so that the upsampled surface's sums fit 32 bits.
    for v in plane.control.iter_mut() {
        *v = i32::from(*v).clamp(SAMPLE_MIN, SAMPLE_MAX) as i16;
    }
    Ok(())
}

/// The control values of a coded grid of side `side` from its indices (by DPCM or the grid
/// transform).
fn fill_control(
    indices: &[i16; MAX_CONTROL],
    side: usize,
    step: i32,
    transform: bool,
    out: &mut [i16; MAX_CONTROL],
) {
    if transform {
        transform_control_values(side, step, indices, out)
    } else {
        for i in 0..(side * side).min(MAX_CONTROL) {
            let index = i32::from(indices[i]);
            out[i] = control_value(out, side, i, step, index);
        }
    }
}

/// Control values: the coded side's indices in the coding order of the leaf's control coding
/// (raster for DPCM, [`transform_order`] for the grid transform). The first coded index is
/// coded as its difference from a prediction by earlier leaves ([`SamplePrediction::predict`]:
/// of the corner under DPCM, of the block's mean for the transform's low band; with their own
/// contexts when both edges are known), in units of its own step. Under DPCM, every other
/// index of the first row and column is coded as its difference from [`edge_offset`] where the
/// pixels beside it are known ([`crate::prediction::edge_pixels`]); the rest as they are.
/// Contexts are by position (DPCM: first row and column or interior) or transform level.
fn code_control<C: Coder>(
    c: &mut C,
    contexts: &mut [IntContexts; CONTROL_CLASSES],
    grid: &ControlGrid,
    node: &Node,
    prediction: &dyn SamplePrediction,
    control: &mut [i16; MAX_CONTROL],
) -> Result<(), PayloadError> {
    let ControlGrid {
        step,
        side,
        spacing,
        transform,
    } = *grid;
    if side == 0 || side > MAX_GRID {
        return Ok(());
    }
    // The first coded value is grid position 0 in both orders. A grid transform's low band is
    // the block's mean, DPCM's first value its corner.
    let (width, q) = if transform {
        (node.size(), coefficient_step(side, step))
    } else {
        (1, step)
    };
    let (p, exact) = prediction.predict(node.x, node.y, width);
    let class = if exact { CLASS_SHARED } else { CLASS_FIRST };
    let predicted = div_round(p, q);
    let mut residual = i32::from(control[0]) - predicted;
    contexts[class].code(c, 0, &mut residual)?;
    control[0] = control_index(predicted + residual)?;
    // Its residual's magnitude stands for it in its neighbours' contexts.
    let first_magnitude = residual.unsigned_abs().min(2) as usize;
    if transform {
        code_details(c, contexts, side, first_magnitude, control)
    } else {
        let mut edges = DpcmEdges {
            node,
            prediction,
            spacing,
            step,
            before: None,
        };
        code_dpcm(c, contexts, side, first_magnitude, &mut edges, control)
    }
}

/// The context magnitude of a coded index: `min(|k|, 2)`.
#[inline(always)]
fn magnitude(index: i16) -> usize {
    usize::from(index.unsigned_abs().min(2))
}

/// A control index, which a stream must keep within 16 bits.
#[inline]
fn control_index(index: i32) -> Result<i16, PayloadError> {
    i16::try_from(index).map_err(|_| PayloadError::InvalidData(SyntaxElement::ControlValue))
}

/// The grid transform's detail coefficients, after the low band: coded as they are, in the
/// transform's coding order, in runs of one class each (coarse levels, level 1, level 0).
fn code_details<C: Coder>(
    c: &mut C,
    contexts: &mut [IntContexts; CONTROL_CLASSES],
    side: usize,
    first_magnitude: usize,
    control: &mut [i16; MAX_CONTROL],
) -> Result<(), PayloadError> {
    // Position 0 holds its residual's magnitude while the details are coded, so that every
    // neighbour is read alike; its index is put back after.
    let first = control[0];
    control[0] = first_magnitude as i16;
    let coded = code_detail_runs(c, contexts, side, control);
    control[0] = first;
    coded
}

// `code_detail_runs` has a run for each detail class, and they are the last classes.
const _: () = assert!(DETAIL_CLASSES == 3 && CLASS_DETAIL + DETAIL_CLASSES == CONTROL_CLASSES);

/// [`code_details`] with position 0 standing for its residual's magnitude.
fn code_detail_runs<C: Coder>(
    c: &mut C,
    contexts: &mut [IntContexts; CONTROL_CLASSES],
    side: usize,
    control: &mut [i16; MAX_CONTROL],
) -> Result<(), PayloadError> {
    let order = transform_order(side);
    let [medium, fine] = fine_starts(side);
    // The detail classes are the last three, finest first.
    let [.., level_0, level_1, coarse] = contexts;
    let runs = [
        (1..medium, coarse),
        (medium..fine, level_1),
        (fine..order.len(), level_0),
    ];
    for (run, ints) in runs {
        for &i in order.get(run).unwrap_or_default() {
            let i = usize::from(i);
            let (r, col) = grid_position(i, side);
            // The zero context (see `zero_context`): the neighbours left and above, or twice
            // the one there is (position 0, which has neither, is the low band).
            let above = if r > 0 { i - side } else { i.wrapping_sub(1) };
            let left = if col > 0 { i.wrapping_sub(1) } else { above };
            let ctx = magnitude(load(control, left)) + magnitude(load(control, above));
            let mut index = i32::from(load(control, i));
            c.int_mostly_zero(ints, ctx, &mut index)?;
            // A coded integer has fewer than 16 bits.
            store(control, i, index as i16);
        }
    }
    Ok(())
}

/// What a DPCM leaf's first row and column are predicted from: the pixels beside the leaf.
struct DpcmEdges<'a> {
    node: &'a Node,
    prediction: &'a dyn SamplePrediction,
    spacing: u32,
    step: i32,
    /// The pixel beside the point before the one being coded (read with it).
    before: Option<i32>,
}

impl DpcmEdges<'_> {
    /// Codes the index at position `k` of the first row (`row`) or column, whose value before it
    /// in the leaf is `base` and whose zero-flag context is `ctx` before the pixels beside it
    /// are seen; returns its reconstructed value.
    #[inline]
    fn code<C: Coder>(
        &mut self,
        c: &mut C,
        ints: &mut IntContexts,
        (row, k): (bool, usize),
        (base, ctx): (i32, usize),
        index: &mut i16,
    ) -> Result<i32, PayloadError> {
        let step = self.step;
        // `edge_pixels`, each pixel read once: point `k`'s pixel is point `k + 1`'s earlier one.
        let along = k as u32 * self.spacing;
        if k == 1 {
            self.before = edge_pixel(self.prediction, self.node, row, 0);
        }
        let outside = if along < self.node.size() {
            edge_pixel(self.prediction, self.node, row, along)
        } else {
            None
        };
        let pixels = outside.zip(self.before);
        self.before = outside;
        let (predicted, ctx) = match pixels {
            Some((a, b)) => (edge_offset(base, a, b, step), edge_context(ctx, a, b, step)),
            None => (0, ctx),
        };
        let mut residual = i32::from(*index) - predicted;
        ints.code(c, ctx, &mut residual)?;
        let k = predicted + residual;
        *index = control_index(k)?;
        Ok(i32::from(dequantise_control(base, step, k)))
    }
}

/// DPCM after the first value, in raster order: the first row and column (class *edge*,
/// predicted from the pixels beside them where known), the interior (class *interior*, coded
/// as it is).
fn code_dpcm<C: Coder>(
    c: &mut C,
    contexts: &mut [IntContexts; CONTROL_CLASSES],
    side: usize,
    first_magnitude: usize,
    edges: &mut DpcmEdges<'_>,
    control: &mut [i16; MAX_CONTROL],
) -> Result<(), PayloadError> {
    let first_value = i32::from(dequantise_control(0, edges.step, i32::from(control[0])));
    let mut value = first_value;
    let mut before = first_magnitude;
    for (k, at) in (1..).zip(&mut control[1..side]) {
        let ctx = 2 * before;
        value = edges.code(c, &mut contexts[CLASS_EDGE], (true, k), (value, ctx), at)?;
        before = magnitude(*at);
    }
    let mut value = first_value;
    let mut above = first_magnitude;
    for r in 1..side {
        let row = r * side;
        let at = &mut control[row];
        value = edges.code(
            c,
            &mut contexts[CLASS_EDGE],
            (false, r),
            (value, 2 * above),
            at,
        )?;
        above = magnitude(*at);
        let interior = &mut contexts[CLASS_INTERIOR];
        for i in row + 1..row + side {
            let ctx = magnitude(load(control, i - 1)) + magnitude(load(control, i - side));
            let mut index = i32::from(load(control, i));
            c.int_mostly_zero(interior, ctx, &mut index)?;
            // A coded integer has fewer than 16 bits.
            store(control, i, index as i16);
        }
    }
    Ok(())
}

/// The zero-flag context of the control residual at grid position `(r, c)` (below
/// [`crate::entropy::ZERO_CONTEXTS`]): the sum of the magnitudes (each at most 2) of the
/// residuals to its left and above, both coded before it in either coding order; on the first
/// row or column, twice the one neighbour there is. Every index but the first (position 0,
/// whose residual magnitude is `first_magnitude`) is its own residual.
#[inline]
pub fn zero_context(
    indices: &[i16; MAX_CONTROL],
    first_magnitude: usize,
    side: usize,
    r: usize,
    c: usize,
) -> usize {
    let magnitude = |p: usize| {
        if p == 0 {
            first_magnitude
        } else {
            usize::from(load(indices, p).unsigned_abs().min(2))
        }
    };
    let i = r * side + c;
    match (c > 0, r > 0) {
        (true, true) => magnitude(i - 1) + magnitude(i - side),
        (true, false) => 2 * magnitude(i - 1),
        (false, true) => 2 * magnitude(i - side),
        (false, false) => 0,
    }
}

/// Reconstructs the patch a leaf of side `2^log2` describes. Fails on a model or control
/// quantiser out of range.
pub fn reconstruct(leaf: &LeafSyntax, log2: u8) -> Result<Patch, PayloadError> {
    let mut patch = Patch::CLEARED;
    reconstruct_into(leaf, log2, &mut patch)?;
    Ok(patch)
}

/// The model type a leaf names.
fn leaf_model(leaf: &LeafSyntax) -> Result<ModelType, PayloadError> {
    MODELS
        .get(usize::from(leaf.model))
        .copied()
        .ok_or(PayloadError::InvalidData(SyntaxElement::ModelType))
}

/// [`reconstruct`] into a caller's patch (no patch-sized temporary on the stack). The control
/// values past the model's grid keep what they held: nothing reads them.
pub fn reconstruct_into(
    leaf: &LeafSyntax,
    log2: u8,
    patch: &mut Patch,
) -> Result<(), PayloadError> {
    let model = leaf_model(leaf)?;
    let step = *CONTROL_STEPS
        .get(usize::from(leaf.cquant))
        .ok_or(PayloadError::InvalidData(SyntaxElement::ControlQuantiser))?;
    let side = model.coded_side(log2);
    fill_control(
        &leaf.control,
        side,
        step,
        leaf.coding == ControlCoding::Transform,
        &mut patch.control,
    );
    if side == usize::from(model.intervals) {
        expand_pixel_grid(&mut patch.control, side);
    }
    patch.model = model;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::SAMPLE_ONE;

    /// The detail runs of every coded side give each coefficient the class of its band level.
    #[test]
    fn detail_runs_are_the_band_levels_classes() {
        for side in [2, 3, 4, 5, 8, 9] {
            let order = transform_order(side);
            let [medium, fine] = fine_starts(side);
            assert!(
                1 <= medium && medium <= fine && fine <= order.len(),
                "side {side}"
            );
            for (j, &i) in order.iter().enumerate().skip(1) {
                let i = usize::from(i);
                let class = match j {
                    j if j < medium => CLASS_DETAIL + 2,
                    j if j < fine => CLASS_DETAIL + 1,
                    _ => CLASS_DETAIL,
                };
                assert_eq!(
                    class,
                    control_class(true, side, i / side, i % side),
                    "{side} {i}"
                );
            }
        }
    }

    /// Coding the details with position 0 standing for its residual's magnitude gives every
    /// coefficient the zero context [`zero_context`] defines, and puts the first index back.
    #[test]
    fn details_are_coded_with_their_zero_contexts() {
        /// A coder that records the zero context of every integer, coding nothing.
        struct Contexts([usize; MAX_CONTROL], usize);
        impl Coder for Contexts {
            fn bit(&mut self, _: &mut Prob, _: &mut bool) -> Result<(), PayloadError> {
                Ok(())
            }
            fn bypass(&mut self, _: &mut bool) -> Result<(), PayloadError> {
                Ok(())
            }
            fn int(
                &mut self,
                _: &mut IntContexts,
                ctx: usize,
                _: &mut i32,
            ) -> Result<(), PayloadError> {
                self.0[self.1] = ctx;
                self.1 += 1;
                Ok(())
            }
        }
        let mut seed = 7u32;
        for side in [2, 3, 4, 5, 8, 9] {
            for first_magnitude in 0..3 {
                let mut control = [0i16; MAX_CONTROL];
                for v in control.iter_mut().take(side * side) {
                    seed = seed.wrapping_mul(1_103_515_245).wrapping_add(12_345);
                    *v = ((seed >> 16) % 7) as i16 - 3;
                }
                let before = control;
                let mut coder = Contexts([0; MAX_CONTROL], 0);
                let mut contexts = [IntContexts::FRESH; CONTROL_CLASSES];
                code_details(
                    &mut coder,
                    &mut contexts,
                    side,
                    first_magnitude,
                    &mut control,
                )
                .unwrap();
                assert_eq!(control, before);
                let order = transform_order(side);
                assert_eq!(coder.1, order.len() - 1);
                for (&i, &ctx) in order.iter().skip(1).zip(&coder.0) {
                    let i = usize::from(i);
                    let (r, c) = (i / side, i % side);
                    let expected = zero_context(&control, first_magnitude, side, r, c);
                    assert_eq!(ctx, expected, "side {side}, position {i}");
                }
            }
        }
    }

    /// A colour header parses with the `colour` feature (on by default) and is refused on its
    /// channel count without it, a 16-bit one likewise with `deep` and its depth; a grayscale
    /// 8-bit one parses either way.
    #[test]
    fn colour_headers_need_the_colour_feature() {
        let gray = Header {
            width: 33,
            height: 20,
            channels: 1,
            bit_depth: 8,
            min_leaf_log2: 2,
            max_leaf_log2: 7,
            stripe: 4,
            deblock: 2,
            payload_len: 10,
            checksum: 0,
            range: None,
        };
        let colour = Header {
            channels: 3,
            ..gray
        };
        let deep = Header {
            bit_depth: 16,
            deblock: 0,
            range: Some(SampleRange::covering(236, 1076)),
            ..gray
        };
        for header in [gray, colour, deep] {
            let mut out = [0u8; MAX_HEADER_LEN];
            let n = header.write(&mut out);
            let parsed = Header::parse(&out[..n]).map(|(h, _)| h);
            if header.bit_depth == 16 && !cfg!(feature = "deep") {
                assert_eq!(parsed, Err(DecodeError::UnsupportedBitDepth(16)));
            } else if header.channels == 1 || cfg!(feature = "colour") {
                assert_eq!(parsed, Ok(header));
            } else {
                assert_eq!(parsed, Err(DecodeError::UnsupportedChannels(3)));
            }
        }
    }

    /// Every side from 1 to 65535 survives the header in one to three bytes; the default coding
    /// fields are left out; the header is as long as it says; another version's tag is refused
    /// for its version.
    #[test]
    fn headers_round_trip_at_their_encoded_length() {
        let base = Header {
            width: 1,
            height: 1,
            channels: 1,
            bit_depth: 8,
            min_leaf_log2: 2,
            max_leaf_log2: 7,
            stripe: 0,
            deblock: 16,
            payload_len: 127,
            checksum: 0xDEAD_BEEF,
            range: None,
        };
        assert_eq!(base.encoded_len(), MIN_HEADER_LEN);
        for (side, bytes) in [
            (1, 1),
            (128, 1),
            (129, 2),
            (16384, 2),
            (16385, 3),
            (65535, 3),
        ] {
            for stripe in [0, 4] {
                let header = Header {
                    width: side,
                    height: 200,
                    stripe,
                    ..base
                };
                let mut out = [0u8; MAX_HEADER_LEN];
                let n = header.write(&mut out);
                let coding = if stripe == 0 { 0 } else { CODING_BYTES };
                assert_eq!(n, FIXED_HEADER_LEN + bytes + 2 + coding + 1, "side {side}");
                assert_eq!(n, header.encoded_len());
                assert_eq!(Header::parse(&out[..n]), Ok((header, n)));
                assert_eq!(Header::parse(&out[..n - 1]), Err(DecodeError::Truncated));
            }
        }
        // A stream of format 21 or earlier opens with `PIFS`: not a stream's tag.
        assert_eq!(
            Header::parse(b"PIFS\x15\x01\x08"),
            Err(DecodeError::BadMagic)
        );
        let mut out = [0u8; MAX_HEADER_LEN];
        let n = base.write(&mut out);
        out[0] = STREAM_TAG + 1;
        assert_eq!(
            Header::parse(&out[..n]),
            Err(DecodeError::UnsupportedVersion(VERSION + 1))
        );
        // The first tagged version's tag names that version; the byte before it is unknown.
        out[0] = 0x80 | crate::format::FIRST_TAGGED_VERSION;
        assert_eq!(
            Header::parse(&out[..n]),
            Err(DecodeError::UnsupportedVersion(
                crate::format::FIRST_TAGGED_VERSION
            ))
        );
        out[0] = 0x80 | (crate::format::FIRST_TAGGED_VERSION - 1);
        assert_eq!(Header::parse(&out[..n]), Err(DecodeError::BadMagic));
        // A side less one of 65535 would be a side of 65536: refused. So is a smoothing of 17.
        let mut big = [STREAM_TAG, 0, 0, 0, 0, 0, 0xFF, 0xFF, 0x03, 0, 0];
        assert_eq!(
            Header::parse(&big),
            Err(DecodeError::InvalidHeader(HeaderField::Dimensions))
        );
        big[1] = 17 << DEBLOCK_SHIFT;
        big[6] = 0;
        assert_eq!(
            Header::parse(&big[..9]),
            Err(DecodeError::InvalidHeader(HeaderField::Deblock))
        );
    }

    /// Plays the encoder's part (records every bit) or the decoder's (replays them).
    struct Tape {
        bits: [bool; 2048],
        len: usize,
        read: Option<usize>,
    }

    impl Tape {
        fn new() -> Tape {
            Tape {
                bits: [false; 2048],
                len: 0,
                read: None,
            }
        }
    }

    impl Coder for Tape {
        fn bit(&mut self, _p: &mut Prob, bit: &mut bool) -> Result<(), PayloadError> {
            self.bypass(bit)
        }

        fn bypass(&mut self, bit: &mut bool) -> Result<(), PayloadError> {
            match &mut self.read {
                Some(at) => {
                    *bit = *self.bits.get(*at).ok_or(PayloadError::Truncated)?;
                    *at += 1;
                }
                None => {
                    self.bits[self.len] = *bit;
                    self.len += 1;
                }
            }
            Ok(())
        }
    }

    /// Pixels around a leaf at (8, 8): above it a ramp, left of it a step.
    struct Around;

    impl SamplePrediction for Around {
        fn beside(&self, above: bool, x: u32, y: u32) -> Option<i32> {
            Some(if above {
                i32::try_from(x).ok()? * 40 * SAMPLE_ONE / 8
            } else if y < 10 {
                40 * SAMPLE_ONE
            } else {
                200 * SAMPLE_ONE
            })
        }
    }

    /// No neighbours.
    struct Alone;

    impl SamplePrediction for Alone {
        fn beside(&self, _above: bool, _x: u32, _y: u32) -> Option<i32> {
            None
        }
    }

    /// The bits of a DPCM pixel grid of 4 px at (8, 8) whose first row continues the ramp
    /// above it and whose first column the step left of it, and that the decoder reads the
    /// same indices back.
    fn coded_bits<P: SamplePrediction>(prediction: &P) -> usize {
        let node = Node {
            x: 8,
            y: 8,
            log2: 2,
        };
        let model = MODELS[2];
        assert_eq!(model.coded_side(2), 4);
        let step = CONTROL_STEPS[0];
        let mut leaf = LeafSyntax {
            model: 2,
            ..LeafSyntax::default()
        };
        // Sample values: row 0 follows the ramp above (8..11) * 5, column 0 the step.
        let target = |r: usize, c: usize| match (r, c) {
            (0, c) => (8 + c as i32) * 5 * SAMPLE_ONE,
            (r, 0) => (if r < 2 { 40 } else { 200 }) * SAMPLE_ONE,
            _ => 100 * SAMPLE_ONE,
        };
        let mut values = [0i16; MAX_CONTROL];
        for i in 0..16 {
            let (r, c) = (i / 4, i % 4);
            let base = if i == 0 {
                0
            } else {
                intra_prediction(&values, 4, r, c)
            };
            let index = div_round(target(r, c) - base, step);
            leaf.control[i] = index as i16;
            values[i] = dequantise_control(base, step, index);
        }
        let mut tape = Tape::new();
        let mut ctx = Contexts::default();
        code_leaf(&mut tape, &mut ctx, &node, prediction, &mut leaf.clone()).unwrap();
        let written = tape.len;
        tape.read = Some(0);
        let mut read = LeafSyntax::default();
        code_leaf(
            &mut tape,
            &mut Contexts::default(),
            &node,
            prediction,
            &mut read,
        )
        .unwrap();
        assert_eq!(tape.read, Some(written));
        assert_eq!(read.control, leaf.control);
        written
    }

    /// A DPCM leaf's first row and column are coded against the pixels beside them.
    #[test]
    fn edges_are_predicted_from_the_pixels_beside_them() {
        let (near, alone) = (coded_bits(&Around), coded_bits(&Alone));
        assert!(near < alone, "{near} bits with neighbours, {alone} without");
    }

    /// The table of initial probabilities covers every context exactly once, in the order
    /// [`Contexts::start`] reads it.
    #[test]
    fn every_context_starts_from_its_table_entry() {
        let mut contexts = Contexts::UNSTARTED;
        let mut count = 0;
        contexts.for_each_prob(|_| count += 1);
        assert_eq!(count, CONTEXT_COUNT);
        contexts.start();
        let mut table = INITIAL_PROBABILITIES.iter();
        contexts.for_each_prob(|p| {
            let q = *table.next().expect("an entry per context");
            assert_eq!(*p, Prob::initial(q));
            assert_eq!(p.probability(), 16 * u16::from(q.max(1)) + 8);
            assert_eq!(p.count(), crate::entropy::INITIAL_COUNT);
        });
        assert_eq!(contexts, Contexts::default());
    }

    /// The same for the chroma contexts and their table.
    #[test]
    fn every_chroma_context_starts_from_its_table_entry() {
        let mut contexts = ChromaContexts::UNSTARTED;
        let mut count = 0;
        contexts.for_each_prob(|_| count += 1);
        assert_eq!(count, CHROMA_CONTEXT_COUNT);
        contexts.start();
        let mut table = CHROMA_INITIAL_PROBABILITIES.iter();
        contexts.for_each_prob(|p| {
            let q = *table.next().expect("an entry per context");
            assert_eq!(*p, Prob::initial(q));
            assert_eq!(p.count(), crate::entropy::INITIAL_COUNT);
        });
        assert!(table.next().is_none());
        assert_eq!(contexts, ChromaContexts::default());
    }
}

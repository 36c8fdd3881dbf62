//! Entropy coding: adaptive binary arithmetic (range) coding.
//!
//! The bitstream syntax (the `syntax` module) is written once, against the [`Coder`] trait: every
//! syntax element is passed by `&mut`, an encoder reads it and a decoder overwrites it. The
//! decoder here ([`RangeDecoder`]) and the host encoder's writer and rate estimator all implement
//! that trait, so the three can never disagree about what is coded, in which order, with which
//! context.
//!
//! The coder is the classic carry-propagating binary range coder: 32-bit range, 12-bit
//! probabilities, adaptation by a shift that grows with the number of bits a context has coded
//! ([`ADAPT_SHIFTS`]): fast while a context learns, steadier once it has.

/// What the coder's methods fail with (re-exported for the host encoder's coders).
pub use crate::error::PayloadError;
use crate::error::SyntaxElement;

/// Number of bits of a probability.
pub const PROB_BITS: u32 = 12;
/// Probability scale: a [`Prob`] holds `P(bit = 0) * PROB_ONE`.
pub const PROB_ONE: u16 = 1 << PROB_BITS;
/// The range is renormalised (one byte shifted) whenever it falls below this value.
pub const RANGE_TOP: u32 = 1 << 24;

/// An adaptive binary context: the probability that the next bit coded with it is `0`
/// ([`PROB_BITS`] bits, the high ones) and how many bits it has coded (the low
/// [`COUNT_BITS`] bits, saturating), which sets how fast it adapts ([`ADAPT_SHIFTS`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Prob(u16);

impl Default for Prob {
    fn default() -> Self {
        Prob::FRESH
    }
}

/// Bits of a [`Prob`] that count the bits coded with it.
pub const COUNT_BITS: u32 = 4;
const COUNT_MAX: u16 = (1 << COUNT_BITS) - 1;

/// The count a context starts a stream with ([`Prob::initial`]).
pub const INITIAL_COUNT: u16 = 2;

/// Adaptation speed by the number of bits a context has coded: after each bit, its
/// probability moves by `1 / 2^shift` of the distance to the observed outcome.
pub const ADAPT_SHIFTS: [u8; 1 << COUNT_BITS] = [2, 3, 3, 4, 4, 4, 4, 5, 5, 5, 5, 5, 5, 5, 5, 5];

impl Prob {
    /// A fresh context: probability one half, no bits coded.
    pub const FRESH: Prob = Prob((PROB_ONE / 2) << COUNT_BITS);

    /// A context not yet started: all zero bits (probability zero). Contexts are started from
    /// their trained probabilities at the start of every stream; this is what they hold before,
    /// so that a decoder clears them in place rather than copying a constant.
    pub const UNSTARTED: Prob = Prob(0);

    /// A context that starts from probability `p8 / 256` of a `0` (at least 1/256 from either
    /// end) as if it had already coded [`INITIAL_COUNT`] bits, so that it adapts at that
    /// count's speed from the start.
    pub const fn initial(p8: u8) -> Prob {
        let p8 = if p8 == 0 { 1 } else { p8 as u16 };
        // The middle of the 1/256 interval, in PROB_BITS bits.
        let p = (p8 << (PROB_BITS - 8)) | (1 << (PROB_BITS - 9));
        Prob((p << COUNT_BITS) | INITIAL_COUNT)
    }

    /// How many bits the context has coded (saturating at `2^COUNT_BITS - 1`), counting from
    /// [`INITIAL_COUNT`] at the start of a stream.
    pub fn count(self) -> u16 {
        self.0 & COUNT_MAX
    }

    /// `P(bit = 0) * PROB_ONE`.
    #[inline]
    pub fn probability(self) -> u16 {
        self.0 >> COUNT_BITS
    }

    /// The split point of `range` for this probability (the size of the `0` sub-interval).
    #[inline]
    pub fn bound(self, range: u32) -> u32 {
        (range >> PROB_BITS) * u32::from(self.probability())
    }

    /// Moves the probability towards the bit just coded: the one adaptation rule of encoders
    /// and decoders (the range decoder inlines it on each outcome's path).
    #[inline(always)]
    pub fn update(&mut self, bit: bool) {
        let state = AdaptWord::from(self.0);
        let n = state & AdaptWord::from(COUNT_MAX);
        let shift = ADAPT_SHIFTS[n as usize];
        let mut p = state >> COUNT_BITS;
        if bit {
            p -= p >> shift;
        } else {
            p += (AdaptWord::from(PROB_ONE) - p) >> shift;
        }
        // `p < PROB_ONE`: the state fits its 16 bits.
        self.0 = ((p << COUNT_BITS) | (n + AdaptWord::from(n < AdaptWord::from(COUNT_MAX)))) as u16;
    }
}

/// The width [`Prob::update`] computes in: 32 bits (16-bit arithmetic costs extensions on a
/// host and on the Cortex-M0), but 16 on ARMv7-M, where the 32-bit form took 0.2–0.6% more
/// instructions.
#[cfg(not(all(target_has_atomic = "32", target_os = "none")))]
type AdaptWord = u32;
#[cfg(all(target_has_atomic = "32", target_os = "none"))]
type AdaptWord = u16;

/// One side of the arithmetic coder. Syntax elements are passed by `&mut`: an encoder codes the
/// value it is given, a decoder replaces it with the value it read.
pub trait Coder {
    /// Codes one bit with an adaptive context (and updates the context).
    fn bit(&mut self, p: &mut Prob, bit: &mut bool) -> Result<(), PayloadError>;
    /// Codes one equiprobable bit (no context).
    fn bypass(&mut self, bit: &mut bool) -> Result<(), PayloadError>;

    /// Codes a signed integer with the contexts `ints` ([`IntContexts::code`], which calls
    /// this): by default bit by bit through [`Coder::bit`] and [`Coder::bypass`]; a decoder
    /// overrides it with a path where one inlined binary decision serves every context-coded
    /// bit.
    fn int(&mut self, ints: &mut IntContexts, ctx: usize, v: &mut i32) -> Result<(), PayloadError>
    where
        Self: Sized,
    {
        ints.code_bits(self, ctx, v)
    }

    /// [`Coder::int`] at the sites where most integers are zero (a grid transform's details,
    /// DPCM's interior): a decoder decides the zero flag there in line, and calls out only for
    /// the rest.
    #[inline(always)]
    fn int_mostly_zero(
        &mut self,
        ints: &mut IntContexts,
        ctx: usize,
        v: &mut i32,
    ) -> Result<(), PayloadError>
    where
        Self: Sized,
    {
        self.int(ints, ctx, v)
    }
}

/// Sequential source of payload bytes for the [`RangeDecoder`].
///
/// Implemented for byte slices (an image in flash); a streaming source (UART, radio, SPI flash)
/// implements it to decode without holding the stream in memory.
pub trait ByteSource {
    /// The next byte, or `None` at the end of the stream.
    fn next_byte(&mut self) -> Option<u8>;
}

/// A borrowed source, so that the caller keeps it (and can see how far it was read).
impl<B: ByteSource + ?Sized> ByteSource for &mut B {
    #[inline]
    fn next_byte(&mut self) -> Option<u8> {
        (**self).next_byte()
    }
}

/// A [`ByteSource`] over a borrowed slice.
#[derive(Debug, Clone)]
pub struct SliceSource<'a> {
    data: &'a [u8],
    pos: usize,
}

impl<'a> SliceSource<'a> {
    /// Reads `data` from its first byte.
    pub fn new(data: &'a [u8]) -> Self {
        SliceSource { data, pos: 0 }
    }

    /// Bytes consumed so far.
    pub fn position(&self) -> usize {
        self.pos
    }
}

impl ByteSource for SliceSource<'_> {
    #[inline]
    fn next_byte(&mut self) -> Option<u8> {
        let b = self.data.get(self.pos).copied();
        if b.is_some() {
            self.pos += 1;
        }
        b
    }
}

/// Binary range decoder over any [`ByteSource`].
#[derive(Debug)]
pub struct RangeDecoder<S: ByteSource> {
    source: S,
    range: u32,
    code: u32,
}

impl<S: ByteSource> RangeDecoder<S> {
    /// Starts decoding: reads the first four payload bytes.
    pub fn new(source: S) -> Result<Self, PayloadError> {
        Self::start(source).map_err(|(_, e)| e)
    }

    /// Like [`RangeDecoder::new`], but gives the source back on failure.
    pub fn start(mut source: S) -> Result<Self, (S, PayloadError)> {
        let mut code = 0u32;
        for _ in 0..4 {
            match source.next_byte() {
                Some(b) => code = (code << 8) | u32::from(b),
                None => return Err((source, PayloadError::Truncated)),
            }
        }
        Ok(RangeDecoder {
            source,
            range: u32::MAX,
            code,
        })
    }

    /// Gives the byte source back (for example to read what follows the payload).
    pub fn into_source(self) -> S {
        self.source
    }

    #[inline]
    fn normalize(&mut self) -> Result<(), PayloadError> {
        while self.range < RANGE_TOP {
            let b = self.source.next_byte().ok_or(PayloadError::Truncated)?;
            self.range <<= 8;
            self.code = (self.code << 8) | u32::from(b);
        }
        Ok(())
    }
}

impl<S: ByteSource> RangeDecoder<S> {
    /// Decodes one bit with the adaptive context `p` (and updates it): the one binary decision
    /// of the decoder, inlined where it is used. No division: the split is a shift and a
    /// multiply, the adaptation a shift by a table entry.
    #[inline(always)]
    fn decision(&mut self, p: &mut Prob) -> Result<bool, PayloadError> {
        let bound = p.bound(self.range);
        // Each outcome its own path to the end, so that the bit is a constant there rather
        // than a value kept across the refill.
        if self.code >= bound {
            self.code -= bound;
            self.range -= bound;
            p.update(true);
            if self.range < RANGE_TOP {
                self.refill()?;
            }
            Ok(true)
        } else {
            self.range = bound;
            p.update(false);
            if self.range < RANGE_TOP {
                self.refill()?;
            }
            Ok(false)
        }
    }

    /// Decodes one equiprobable bit.
    #[inline(always)]
    fn even(&mut self) -> Result<bool, PayloadError> {
        self.range >>= 1;
        let bit = self.code >= self.range;
        if bit {
            self.code -= self.range;
        }
        if self.range < RANGE_TOP {
            self.refill()?;
        }
        Ok(bit)
    }

    /// Shifts payload bytes in until the range is at least [`RANGE_TOP`] again (out of line:
    /// about one decision in eight needs it).
    #[inline(never)]
    fn refill(&mut self) -> Result<(), PayloadError> {
        self.normalize()
    }
}

impl<S: ByteSource> Coder for RangeDecoder<S> {
    #[inline]
    fn bit(&mut self, p: &mut Prob, bit: &mut bool) -> Result<(), PayloadError> {
        *bit = self.decision(p)?;
        Ok(())
    }

    #[inline]
    fn bypass(&mut self, bit: &mut bool) -> Result<(), PayloadError> {
        *bit = self.even()?;
        Ok(())
    }

    /// The zero flag first, on its own (a zero, the commonest value, costs one decision and
    /// nothing more), then the rest ([`RangeDecoder::nonzero`]).
    #[inline(never)]
    fn int(&mut self, ints: &mut IntContexts, ctx: usize, v: &mut i32) -> Result<(), PayloadError> {
        self.zero_or_nonzero(ints, ctx, v)
    }

    /// Where the core has the registers for it (ARMv7-M, hosts). On ARMv6-M (eight low
    /// registers) the decision in line spills, gains nothing and costs flash: the call stays.
    #[cfg(target_has_atomic = "32")]
    #[inline(always)]
    fn int_mostly_zero(
        &mut self,
        ints: &mut IntContexts,
        ctx: usize,
        v: &mut i32,
    ) -> Result<(), PayloadError> {
        self.zero_or_nonzero(ints, ctx, v)
    }
}

impl<S: ByteSource> RangeDecoder<S> {
    /// [`Coder::int`]: the zero flag, then [`RangeDecoder::nonzero`].
    #[inline(always)]
    fn zero_or_nonzero(
        &mut self,
        ints: &mut IntContexts,
        ctx: usize,
        v: &mut i32,
    ) -> Result<(), PayloadError> {
        if !self.decision(&mut ints.probs[ctx.min(ZERO_CONTEXTS - 1)])? {
            *v = 0;
            return Ok(());
        }
        *v = self.nonzero(ints)?;
        Ok(())
    }

    /// An integer known not to be zero: its sign, then its magnitude's prefix and suffix bits.
    /// Out of line on ARMv7-M, where [`Coder::int_mostly_zero`] decides zeros in line (flash);
    /// in line in [`Coder::int`] on ARMv6-M, and at every call on hosts (1.4% fewer
    /// instructions there).
    #[cfg_attr(all(target_has_atomic = "32", target_os = "none"), inline(never))]
    #[cfg_attr(not(all(target_has_atomic = "32", target_os = "none")), inline(always))]
    fn nonzero(&mut self, ints: &mut IntContexts) -> Result<i32, PayloadError> {
        let probs = &mut ints.probs;
        let negative = self.decision(&mut probs[SIGN])?;
        // Ones of the Exp-Golomb prefix so far: the magnitude has that many suffix bits.
        let mut k = 0;
        while self.decision(&mut probs[PREFIX + k.min(PREFIX_CONTEXTS - 1)])? {
            k += 1;
            if k >= MAX_PREFIX {
                return Err(PayloadError::InvalidData(SyntaxElement::IntegerMagnitude));
            }
        }
        let mut mag: u32 = 1;
        for _ in 0..k {
            mag = (mag << 1) | u32::from(self.even()?);
        }
        // mag < 2^MAX_PREFIX, so the cast is lossless.
        Ok(if negative { -(mag as i32) } else { mag as i32 })
    }
}

/// Contexts for one class of signed integers (residuals), binarised as: zero flag, sign, then
/// an Exp-Golomb magnitude whose unary prefix bits are context coded and whose suffix bits are
/// bypass coded. The contexts are one array (the zero flags, the sign, the prefix bits), so
/// that a decoder reaches any of them by an index from one base address.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct IntContexts {
    probs: [Prob; IntContexts::COUNT],
}

/// Neighbourhood classes of the zero flag (see [`IntContexts::code`]).
pub const ZERO_CONTEXTS: usize = 5;
/// Longest Exp-Golomb prefix: magnitudes are below `2^MAX_PREFIX`.
pub const MAX_PREFIX: usize = 12;
/// Prefix bits with a context of their own; later prefix bits (magnitudes of `2^5` and more,
/// rare) share the last one.
pub const PREFIX_CONTEXTS: usize = 6;
/// Where the sign's context is in [`IntContexts`].
const SIGN: usize = ZERO_CONTEXTS;
/// Where the prefix bits' contexts start in [`IntContexts`].
const PREFIX: usize = ZERO_CONTEXTS + 1;

impl Default for IntContexts {
    fn default() -> Self {
        IntContexts::FRESH
    }
}

impl IntContexts {
    /// Fresh contexts ([`Prob::FRESH`]).
    pub const FRESH: IntContexts = IntContexts {
        probs: [Prob::FRESH; IntContexts::COUNT],
    };

    /// Contexts not yet started ([`Prob::UNSTARTED`]).
    pub const UNSTARTED: IntContexts = IntContexts {
        probs: [Prob::UNSTARTED; IntContexts::COUNT],
    };

    /// Number of contexts ([`IntContexts::for_each_prob`]).
    pub const COUNT: usize = ZERO_CONTEXTS + 1 + PREFIX_CONTEXTS;

    /// Calls `f` on every context, in a fixed order: the zero flags, the sign, the prefix bits.
    pub fn for_each_prob(&mut self, f: impl FnMut(&mut Prob)) {
        self.probs.iter_mut().for_each(f);
    }

    /// Codes a signed integer `v` with `|v| < 2^MAX_PREFIX`. `ctx` (below [`ZERO_CONTEXTS`];
    /// larger values count as the last class) selects the neighbourhood class of the zero flag,
    /// from the sizes of earlier values of the same kind.
    #[inline]
    pub fn code<C: Coder>(
        &mut self,
        c: &mut C,
        ctx: usize,
        v: &mut i32,
    ) -> Result<(), PayloadError> {
        c.int(self, ctx, v)
    }

    /// [`IntContexts::code`] bit by bit (the default of [`Coder::int`]).
    pub fn code_bits<C: Coder>(
        &mut self,
        c: &mut C,
        ctx: usize,
        v: &mut i32,
    ) -> Result<(), PayloadError> {
        let ctx = ctx.min(ZERO_CONTEXTS - 1);
        let mut nonzero = *v != 0;
        c.bit(&mut self.probs[ctx], &mut nonzero)?;
        if !nonzero {
            *v = 0;
            return Ok(());
        }
        let mut negative = *v < 0;
        c.bit(&mut self.probs[SIGN], &mut negative)?;
        // Exp-Golomb of magnitude m >= 1: k = floor(log2 m) in unary, then k low bits.
        let m = v.unsigned_abs();
        let k_in = 31 - m.max(1).leading_zeros() as usize;
        let mut k = 0usize;
        loop {
            if k >= MAX_PREFIX {
                return Err(PayloadError::InvalidData(SyntaxElement::IntegerMagnitude));
            }
            let mut more = k < k_in;
            c.bit(
                &mut self.probs[PREFIX + k.min(PREFIX_CONTEXTS - 1)],
                &mut more,
            )?;
            if !more {
                break;
            }
            k += 1;
        }
        let mut mag: u32 = 1;
        for i in (0..k).rev() {
            let mut b = (m >> i) & 1 == 1;
            c.bypass(&mut b)?;
            mag = (mag << 1) | u32::from(b);
        }
        // mag < 2^15, so the cast is lossless.
        *v = if negative { -(mag as i32) } else { mag as i32 };
        Ok(())
    }
}

/// Codes an unsigned value below `2^bits` as a binary tree of `bits` context-coded decisions
/// (`N`, the number of contexts, is `2^bits`; entry 0 is unused).
pub fn code_tree<C: Coder, const N: usize>(
    c: &mut C,
    ctx: &mut [Prob; N],
    bits: u32,
    v: &mut u32,
) -> Result<(), PayloadError> {
    let mut node = 1usize;
    let mut out = 0u32;
    for i in (0..bits).rev() {
        let mut b = (*v >> i) & 1 == 1;
        c.bit(&mut ctx[node % N], &mut b)?;
        node = (node << 1) | usize::from(b);
        out = (out << 1) | u32::from(b);
    }
    *v = out;
    Ok(())
}

/// Codes an index `0..count` as a truncated unary code with one context per position
/// (`count <= N + 1`).
pub fn code_unary<C: Coder, const N: usize>(
    c: &mut C,
    ctx: &mut [Prob; N],
    count: u32,
    v: &mut u32,
) -> Result<(), PayloadError> {
    let mut i = 0u32;
    while i + 1 < count {
        let mut more = *v > i;
        c.bit(&mut ctx[i as usize % N], &mut more)?;
        if !more {
            break;
        }
        i += 1;
    }
    *v = i;
    Ok(())
}

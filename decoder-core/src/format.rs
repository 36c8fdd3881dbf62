//! The format's shared vocabulary, below every other module: its identity (the first byte of
//! a stream or packet: kind and version), the bounds on leaf sizes, and the small integer
//! helpers both prediction and syntax use.

/// The format version this crate reads and writes: the low six bits of the first byte of
/// every stream and packet.
pub const VERSION: u8 = 23;
/// The first format version whose streams and packets open with a tag byte (earlier ones
/// opened with [`LEGACY_MAGIC`]).
pub const FIRST_TAGGED_VERSION: u8 = 22;
/// The first byte of a stream: kind 2 in its top two bits, [`VERSION`] below them. One byte
/// both recognises the bytes (with the checksum behind it) and versions them.
pub const STREAM_TAG: u8 = 0x80 | VERSION;
/// The first byte of a packet (`docs/bitstream.md`, section 9): kind 3, [`VERSION`].
pub const PACKET_TAG: u8 = 0xC0 | VERSION;
/// The first byte of a parity packet: kind 1, [`VERSION`].
pub const PARITY_TAG: u8 = 0x40 | VERSION;
/// The bytes that opened a stream up to format version 21, before its version byte. A decoder
/// refuses such a stream as unknown bytes ([`STREAM_TAG`] is not there); a tool that meets
/// files may name their version.
pub const LEGACY_MAGIC: [u8; 4] = *b"PIFS";
const _: () = assert!(VERSION < 64, "the version must fit the tag's six bits");

/// What a first byte says about the bytes behind it, against the `tag` expected
/// ([`STREAM_TAG`], [`PACKET_TAG`]): the same kind of another tagged version gives that version.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TagCheck {
    /// The expected kind and version.
    Expected,
    /// The expected kind, written by another tagged format version `.0` (earlier or later).
    OtherVersion(u8),
    /// Not the expected kind, or a version before [`FIRST_TAGGED_VERSION`] (no such version
    /// opened with a tag: the byte is not PIFS's).
    Unknown,
}

/// Checks `byte` against `tag` ([`TagCheck`]).
pub fn check_tag(byte: u8, tag: u8) -> TagCheck {
    if byte == tag {
        TagCheck::Expected
    } else if byte >> 6 == tag >> 6 && byte & 0x3F >= FIRST_TAGGED_VERSION {
        TagCheck::OtherVersion(byte & 0x3F)
    } else {
        TagCheck::Unknown
    }
}

/// Smallest allowed leaf side, as a power of two.
pub const MIN_LEAF_LOG2: u8 = 1;
/// Largest allowed leaf side, as a power of two.
pub const MAX_LEAF_LOG2: u8 = 7;
/// Side of the coding tiles, pixels: the largest leaf. The image is coded tile by tile, in bands
/// of this height, left to right within a stripe (each tile a quadtree in Z order).
pub const CODING_TILE: u32 = 1 << MAX_LEAF_LOG2;
/// The stripe width a decoder holds prediction memory for unless told otherwise, pixels: one
/// byte per column of the stripe.
pub const DEFAULT_STRIPE: usize = 512;

/// Why an unsigned LEB128 value could not be read ([`read_leb128`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Leb128Error {
    /// The bytes ended inside the value.
    Truncated,
    /// Longer than allowed, or with a redundant final zero group.
    Malformed,
}

/// Reads an unsigned LEB128 value (7 bits a byte, least significant group first, bit 7 set on
/// every byte but the last) of at most `max_bytes` bytes at `*pos`, advancing `*pos`; a
/// redundant final zero group (a last byte of 0 after others) is malformed, and so is a value
/// past 32 bits. The headers' sizes and payload length and the packet header's fields are such
/// values (32 bits: no 64-bit shifts on a Cortex-M0).
pub fn read_leb128(data: &[u8], pos: &mut usize, max_bytes: usize) -> Result<u32, Leb128Error> {
    let mut value = 0u32;
    // Five groups hold 32 bits.
    for k in 0..max_bytes.min(5) {
        let b = *data.get(*pos).ok_or(Leb128Error::Truncated)?;
        *pos += 1;
        let (group, shift) = (u32::from(b & 0x7F), 7 * k as u32);
        if (group << shift) >> shift != group {
            return Err(Leb128Error::Malformed);
        }
        value |= group << shift;
        if b & 0x80 == 0 {
            return match k > 0 && b == 0 {
                true => Err(Leb128Error::Malformed),
                false => Ok(value),
            };
        }
    }
    Err(Leb128Error::Malformed)
}

/// Writes `value` as unsigned LEB128 into `out` at `pos` (which must have room: at most five
/// bytes); returns the position after it.
pub fn write_leb128(out: &mut [u8], mut pos: usize, mut value: u32) -> usize {
    loop {
        let low = (value & 0x7F) as u8;
        value >>= 7;
        out[pos] = low | if value != 0 { 0x80 } else { 0 };
        pos += 1;
        if value == 0 {
            return pos;
        }
    }
}

/// Median edge detector (LOCO-I): the median of `left`, `up` and `left + up - up_left`.
#[inline]
pub fn med(left: i32, up: i32, up_left: i32) -> i32 {
    let (lo, hi) = if left < up { (left, up) } else { (up, left) };
    if up_left >= hi {
        lo
    } else if up_left <= lo {
        hi
    } else {
        left + up - up_left
    }
}

/// Rounded division of a sample value by a quantiser step (ties away from zero); used for
/// prediction in the index domain. Steps are positive; one below 1 counts as 1.
pub fn div_round(v: i32, step: i32) -> i32 {
    let step = step.max(1) as u32;
    // |v| + step / 2 < 3 * 2^30: no overflow.
    let q = div_floor(v.unsigned_abs() + (step >> 1), step) as i32;
    if v >= 0 {
        q
    } else {
        -q
    }
}

/// `values[i]`, or 0 past the end. For indices that are in range by construction where the
/// compiler cannot see it: the check costs what a bounds check costs, but there is no panic
/// behind it, and the decoder links no panic path.
#[inline(always)]
pub const fn load(values: &[i16], i: usize) -> i16 {
    if i < values.len() {
        values[i]
    } else {
        0
    }
}

/// Stores `v` at `values[i]`, and nothing past the end (see [`load`]).
#[inline(always)]
pub const fn store(values: &mut [i16], i: usize, v: i16) {
    if i < values.len() {
        values[i] = v;
    }
}

/// The first and the last `N` bytes of `bytes` (at least `N` of them), both read before
/// anything is written: with [`put_ends`], a copy of `N` to `2 N` bytes as two fixed-size
/// moves, where `copy_from_slice` calls `memcpy` for a length it does not know.
#[inline(always)]
pub(crate) fn ends<const N: usize>(bytes: &[u8]) -> Option<([u8; N], [u8; N])> {
    Some((*bytes.first_chunk::<N>()?, *bytes.last_chunk::<N>()?))
}

/// Writes `ends` as the first and the last `N` bytes of `out` (see [`ends`]).
#[inline(always)]
pub(crate) fn put_ends<const N: usize>(out: &mut [u8], (head, tail): ([u8; N], [u8; N])) {
    if let Some(first) = out.first_chunk_mut::<N>() {
        *first = head;
    }
    if let Some(last) = out.last_chunk_mut::<N>() {
        *last = tail;
    }
}

/// `v` clamped to `0..=255`, as a byte. Where the target has 32-bit atomics (ARMv7-M, hosts)
/// a plain clamp, which a Cortex-M3 makes one saturating instruction; on the Cortex-M0
/// (ARMv6-M: no atomics, no saturation) one unsigned compare while `v` is in range, as it
/// nearly always is, where the clamp takes five instructions.
#[inline(always)]
pub fn byte(v: i32) -> u8 {
    #[cfg(target_has_atomic = "32")]
    {
        v.clamp(0, 255) as u8
    }
    #[cfg(not(target_has_atomic = "32"))]
    {
        byte_compared(v)
    }
}

/// [`byte`] for the Cortex-M0.
#[cfg(any(test, not(target_has_atomic = "32")))]
#[inline(always)]
fn byte_compared(v: i32) -> u8 {
    if v as u32 <= 255 {
        v as u8
    } else if v < 0 {
        0
    } else {
        255
    }
}

/// `floor(n / d)` for `d > 0` (0 counts as 1): a shift for a power of two (the pixels beside a
/// leaf, most control steps), else [`divide`] (out of line: one copy for every caller).
#[inline(never)]
pub fn div_floor(n: u32, d: u32) -> u32 {
    if d.is_power_of_two() {
        n >> d.trailing_zeros()
    } else {
        divide(n, d)
    }
}

/// `floor(n / d)` for `d > 0` (0 counts as 1), for the few divisions that are not by a
/// constant or a power of two (set-up, and the prediction's rare divisors). Where the target
/// has 32-bit atomics (ARMv7-M, hosts: a divide instruction) a division; on the Cortex-M0
/// (ARMv6-M), which has none, shifts and subtractions, one per bit of the quotient, so that the
/// decoder links no general division routine there.
pub const fn divide(n: u32, d: u32) -> u32 {
    let d = if d == 0 { 1 } else { d };
    #[cfg(target_has_atomic = "32")]
    {
        n / d
    }
    #[cfg(not(target_has_atomic = "32"))]
    {
        divide_by_bits(n, d)
    }
}

/// [`divide`] for the Cortex-M0, `d > 0`.
#[cfg(any(test, not(target_has_atomic = "32")))]
const fn divide_by_bits(n: u32, d: u32) -> u32 {
    let mut divisor = d;
    if divisor > n {
        return 0;
    }
    // The divisor shifted up to the quotient's top bit (`divisor <= n < 2 divisor`).
    let mut bits = 0;
    while divisor <= n >> 1 {
        divisor <<= 1;
        bits += 1;
    }
    let (mut quotient, mut rest) = (0u32, n);
    loop {
        quotient <<= 1;
        if rest >= divisor {
            rest -= divisor;
            quotient |= 1;
        }
        if bits == 0 {
            return quotient;
        }
        bits -= 1;
        divisor >>= 1;
    }
}

/// `v mod 255`, by folding bytes (`256 = 1 mod 255`): no division on a Cortex-M0.
pub const fn mod255(v: usize) -> usize {
    let mut v = v;
    while v > 255 {
        v = (v >> 8) + (v & 255);
    }
    if v == 255 {
        0
    } else {
        v
    }
}

/// Fractional bits of samples: a grey level `g` is the sample `g << SAMPLE_BITS`.
pub const SAMPLE_BITS: u32 = 4;

/// The values a 16-bit stream's samples stand for, in the data's own units (metres, counts):
/// grey level `g` stands for `low + g step / 128`, and a sample (1/16 of a grey level) likewise,
/// by a multiplication and a shift (no division on a microcontroller without one).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct SampleRange {
    /// The value of grey 0.
    pub low: u16,
    /// Value units per grey level, in 1/[`SampleRange::STEP_ONE`]; not 0.
    pub step: u16,
}

impl SampleRange {
    /// The unit of [`SampleRange::step`]: 128 is one value unit per grey level.
    pub const STEP_ONE: u32 = 128;

    /// The range from `low` with the smallest step whose grey 255 reaches `high` (at least
    /// `low`).
    pub fn covering(low: u16, high: u16) -> SampleRange {
        let span = u32::from(high.saturating_sub(low));
        let step = (span * Self::STEP_ONE).div_ceil(255).max(1);
        SampleRange {
            low,
            step: step as u16,
        }
    }

    /// The value a synthesised sample `s` (1/16 grey level) stands for: `min(65535, low +
    /// ((s step + 1024) >> 11))`, `s` first clamped to `0..=4080` (grey 0 to 255).
    #[inline]
    pub fn value(self, sample: i16) -> u16 {
        const TOP: u32 = 255 << SAMPLE_BITS;
        const SHIFT: u32 = SAMPLE_BITS + SampleRange::STEP_ONE.trailing_zeros();
        let s = (sample.max(0) as u32).min(TOP);
        let offset = (s * u32::from(self.step) + (1 << (SHIFT - 1))) >> SHIFT;
        (u32::from(self.low) + offset).min(u32::from(u16::MAX)) as u16
    }

    /// The value an 8-bit pixel stands for: [`SampleRange::value`] of its sample.
    #[inline]
    pub fn pixel_value(self, pixel: u8) -> u16 {
        self.value(i16::from(pixel) << SAMPLE_BITS)
    }

    /// The value of grey 255, the range's top.
    pub fn high(self) -> u16 {
        self.pixel_value(255)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn both_ways_of_making_a_byte_clamp() {
        for v in (-70_000..70_000).chain([i32::MIN, i32::MAX, i32::MIN + 1, i32::MAX - 1]) {
            assert_eq!(byte(v), v.clamp(0, 255) as u8, "{v}");
            assert_eq!(byte_compared(v), v.clamp(0, 255) as u8, "{v}");
        }
    }

    /// The shift-and-multiply paths are the plain (rounded) division.
    #[test]
    fn rounded_division_without_a_divider_is_exact() {
        let plain = |v: i32, step: i32| {
            if v >= 0 {
                (v + step / 2) / step
            } else {
                -((-v + step / 2) / step)
            }
        };
        let more = [
            256,
            384,
            512,
            768,
            1024,
            1536,
            2048,
            3072,
            4096,
            6144,
            1 << 20,
            3 << 20,
        ];
        for step in (1..=200).chain(more) {
            for v in (-70_000..=70_000)
                .step_by(7)
                .chain([i32::MAX / 2, -(i32::MAX / 2)])
            {
                assert_eq!(div_round(v, step), plain(v, step), "{v} / {step}");
                let n = v.unsigned_abs();
                assert_eq!(div_floor(n, step as u32), n / step as u32, "{n} / {step}");
            }
        }
    }

    /// LEB128 values up to 32 bits read back; past 32 bits, past the byte limit, or with a
    /// redundant final zero group they are malformed, and cut short truncated.
    #[test]
    fn leb128_values_are_32_bits() {
        for v in [
            0,
            1,
            127,
            128,
            16_383,
            16_384,
            1 << 21,
            u32::MAX - 1,
            u32::MAX,
        ] {
            let mut out = [0u8; 5];
            let end = write_leb128(&mut out, 0, v);
            let mut pos = 0;
            assert_eq!(read_leb128(&out[..end], &mut pos, 5), Ok(v));
            assert_eq!(pos, end);
            let mut pos = 0;
            assert_eq!(
                read_leb128(&out[..end - 1], &mut pos, 5),
                Err(Leb128Error::Truncated)
            );
        }
        let read = |bytes: &[u8], max: usize| read_leb128(bytes, &mut 0, max);
        assert_eq!(
            read(&[0x80, 0x80, 0x80, 0x80, 0x10], 5),
            Err(Leb128Error::Malformed)
        );
        assert_eq!(read(&[0xFF, 0xFF, 0xFF, 0xFF, 0x0F], 5), Ok(u32::MAX));
        assert_eq!(
            read(&[0x80, 0x80, 0x80, 0x01], 3),
            Err(Leb128Error::Malformed)
        );
        assert_eq!(read(&[0x85, 0x00], 3), Err(Leb128Error::Malformed));
        assert_eq!(read(&[0x00], 3), Ok(0));
    }

    /// The bit-at-a-time division and the folded remainder are the processor's, over the
    /// whole range of both operands.
    #[test]
    fn division_by_bits_is_division() {
        let mut seed = 0x9e37_79b9u32;
        let mut next = move || {
            seed ^= seed << 13;
            seed ^= seed >> 17;
            seed ^= seed << 5;
            seed
        };
        let edges = [0, 1, 2, 3, 254, 255, 256, 1 << 31, u32::MAX - 1, u32::MAX];
        for _ in 0..20_000 {
            let (n, d) = (next(), next() >> (next() % 32));
            for (n, d) in [(n, d), (n, d.max(1) & 0xffff), (n >> 12, d >> 20)] {
                assert_eq!(divide(n, d), n / d.max(1), "{n} / {d}");
                assert_eq!(divide_by_bits(n, d.max(1)), n / d.max(1), "{n} / {d}");
            }
            assert_eq!(mod255(n as usize), n as usize % 255, "{n} mod 255");
        }
        for n in edges {
            for d in edges {
                assert_eq!(divide(n, d), n / d.max(1), "{n} / {d}");
                assert_eq!(divide_by_bits(n, d.max(1)), n / d.max(1), "{n} / {d}");
            }
            assert_eq!(mod255(n as usize), n as usize % 255, "{n} mod 255");
        }
    }

    /// Grey 0 is `low`, each grey level `step / 128` more, samples between rounded, samples
    /// outside clamped; the covering range reaches its top at grey 255 or just before.
    #[test]
    fn samples_map_onto_the_range() {
        let range = SampleRange::covering(236, 1076);
        // 840 * 128 / 255 = 421.6: 422, 3.297 units a grey level.
        assert_eq!(range.step, 422);
        assert_eq!(range.value(0), 236);
        assert_eq!(range.value(-300), 236);
        // 255 * 422 / 128 = 840.7.
        assert_eq!(range.high(), 1077);
        assert_eq!(range.value(5000), 1077);
        // Half way, grey 127.5: 420.35.
        assert_eq!(range.value(2040), 656);
        // 1/16 of a grey level is 0.206 units: rounds to 0; 3/16 (0.618) to 1.
        assert_eq!(range.value(1), 236);
        assert_eq!(range.value(3), 237);
        assert_eq!(range.pixel_value(1), 236 + 3);
        let full = SampleRange::covering(0, u16::MAX);
        assert_eq!(full.step, 32896);
        assert_eq!(full.high(), u16::MAX);
        assert_eq!(full.value(4079), 65519);
        // A flat or inverted range still steps.
        assert_eq!(SampleRange::covering(7, 7).step, 1);
        assert_eq!(SampleRange::covering(u16::MAX, u16::MAX).high(), u16::MAX);
    }
}

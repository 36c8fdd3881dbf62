//! The format's shared vocabulary, below every other module: its identity (magic bytes and
//! version), the bounds on leaf sizes, and the small integer helpers both prediction and syntax
//! use.

/// The four magic bytes that open every stream.
pub const MAGIC: [u8; 4] = *b"PIFS";
/// The format version this crate reads and writes.
pub const VERSION: u8 = 18;
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
/// redundant final zero group (a last byte of 0 after others) is malformed. The header's
/// payload length and the packet header's fields are such values.
pub fn read_leb128(data: &[u8], pos: &mut usize, max_bytes: usize) -> Result<u64, Leb128Error> {
    let mut value = 0u64;
    for k in 0..max_bytes {
        let b = *data.get(*pos).ok_or(Leb128Error::Truncated)?;
        *pos += 1;
        value |= u64::from(b & 0x7F) << (7 * k);
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
/// prediction in the index domain.
pub fn div_round(v: i32, step: i32) -> i32 {
    if v >= 0 {
        (v + step / 2) / step
    } else {
        -((-v + step / 2) / step)
    }
}

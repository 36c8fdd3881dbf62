//! The format's shared vocabulary, below every other module: its identity (magic bytes and
//! version), the bounds on leaf sizes, and the small integer helpers both prediction and syntax
//! use.

/// The four magic bytes that open every stream.
pub const MAGIC: [u8; 4] = *b"PIFS";
/// The format version this crate reads and writes.
pub const VERSION: u8 = 14;
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

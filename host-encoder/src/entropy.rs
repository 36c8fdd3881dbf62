//! Encoder side of the arithmetic coder: the range encoder that writes streams, and the
//! counting coder the rate optimiser uses. Both implement decoder-core's
//! [`decoder_core::internal::entropy::Coder`], so they run the very syntax code the decoder runs.

use decoder_core::internal::entropy::{Coder, PayloadError, Prob, PROB_BITS, RANGE_TOP};

/// Binary range encoder (mirror of `decoder_core::internal::entropy::RangeDecoder`).
#[derive(Debug, Clone)]
pub struct RangeEncoder {
    low: u64,
    range: u32,
    cache: u8,
    pending: u64,
    first: bool,
    out: Vec<u8>,
}

impl Default for RangeEncoder {
    fn default() -> Self {
        Self::new()
    }
}

impl RangeEncoder {
    /// An encoder with an empty output.
    pub fn new() -> Self {
        RangeEncoder {
            low: 0,
            range: u32::MAX,
            cache: 0,
            pending: 1,
            first: true,
            out: Vec::new(),
        }
    }

    fn shift_low(&mut self) {
        if self.low < 0xFF00_0000 || self.low > 0xFFFF_FFFF {
            let carry = (self.low >> 32) as u8;
            let mut byte = self.cache;
            while self.pending > 0 {
                // The very first byte is always 0 and is not written; the decoder starts
                // with four bytes instead of five.
                if !self.first {
                    self.out.push(byte.wrapping_add(carry));
                }
                self.first = false;
                byte = 0xFF;
                self.pending -= 1;
            }
            self.cache = ((self.low >> 24) & 0xFF) as u8;
        }
        self.pending += 1;
        self.low = (self.low & 0x00FF_FFFF) << 8;
    }

    fn normalize(&mut self) {
        while self.range < RANGE_TOP {
            self.range <<= 8;
            self.shift_low();
        }
    }

    /// Flushes the coder and returns the payload bytes.
    pub fn finish(mut self) -> Vec<u8> {
        for _ in 0..5 {
            self.shift_low();
        }
        self.out
    }
}

impl Coder for RangeEncoder {
    fn bit(&mut self, p: &mut Prob, bit: &mut bool) -> Result<(), PayloadError> {
        let bound = p.bound(self.range);
        if *bit {
            self.low += u64::from(bound);
            self.range -= bound;
        } else {
            self.range = bound;
        }
        p.update(*bit);
        self.normalize();
        Ok(())
    }

    fn bypass(&mut self, bit: &mut bool) -> Result<(), PayloadError> {
        self.range >>= 1;
        if *bit {
            self.low += u64::from(self.range);
        }
        self.normalize();
        Ok(())
    }
}

/// Fractional bits per unit of [`BitCounter`] cost.
pub const COST_SCALE: f64 = 256.0;

/// `-log2(p) * COST_SCALE` for the probability `(i + 0.5) / 256`.
fn cost_table() -> &'static [u32; 256] {
    use std::sync::OnceLock;
    static TABLE: OnceLock<[u32; 256]> = OnceLock::new();
    TABLE.get_or_init(|| {
        let mut t = [0u32; 256];
        for (i, c) in t.iter_mut().enumerate() {
            let p = (i as f64 + 0.5) / 256.0;
            *c = (-p.log2() * COST_SCALE).round() as u32;
        }
        t
    })
}

/// A [`Coder`] that writes nothing and adds up the cost of what it is given (in
/// 1/[`COST_SCALE`] bits), adapting its contexts exactly as the real coder does, or, when
/// [`BitCounter::frozen`], leaving them as they are.
#[derive(Debug, Clone)]
pub struct BitCounter {
    /// Accumulated cost, in 1/256 bit.
    pub cost: u64,
    /// The cost table (looked up once, not per bit).
    table: &'static [u32; 256],
    /// Whether contexts adapt to the bits counted.
    adapt: bool,
}

impl Default for BitCounter {
    fn default() -> Self {
        BitCounter {
            cost: 0,
            table: cost_table(),
            adapt: true,
        }
    }
}

impl BitCounter {
    /// A counter that prices every bit with its context's current probability and does not
    /// change the context: many alternatives can then be priced from one context state
    /// without copying it for each.
    pub fn frozen() -> Self {
        BitCounter {
            adapt: false,
            ..BitCounter::default()
        }
    }

    /// Accumulated cost in bits.
    pub fn bits(&self) -> f64 {
        self.cost as f64 / COST_SCALE
    }
}

impl Coder for BitCounter {
    fn bit(&mut self, p: &mut Prob, bit: &mut bool) -> Result<(), PayloadError> {
        let p0 = u32::from(p.probability()) >> (PROB_BITS - 8);
        let idx = if *bit { 255 - p0.min(255) } else { p0.min(255) };
        self.cost += u64::from(self.table[idx as usize]);
        if self.adapt {
            p.update(*bit);
        }
        Ok(())
    }

    fn bypass(&mut self, _bit: &mut bool) -> Result<(), PayloadError> {
        self.cost += COST_SCALE as u64;
        Ok(())
    }
}

//! The checks: CRC-32 for streams (the IEEE 802.3 / zlib / PNG polynomial, reflected, initial
//! value and final XOR `0xFFFF_FFFF`) and CRC-16 for packets (CRC-16/IBM-3740: polynomial
//! `0x1021`, not reflected, initial value `0xFFFF`, no final XOR), each computed four bits at a
//! time from a 16-entry table: 64 and 32 bytes of flash instead of the usual 1 KiB and 512 B,
//! at about twice the work per byte of the byte-wise tables.

/// `TABLE[i]` is the CRC register after shifting nibble `i` through the reflected polynomial.
const TABLE: [u32; 16] = nibble_table();

const fn nibble_table() -> [u32; 16] {
    let mut table = [0u32; 16];
    let mut i = 0;
    while i < 16 {
        let mut c = i as u32;
        let mut k = 0;
        while k < 4 {
            c = if c & 1 != 0 {
                (c >> 1) ^ 0xEDB8_8320
            } else {
                c >> 1
            };
            k += 1;
        }
        table[i] = c;
        i += 1;
    }
    table
}

/// A running CRC-32.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Crc32 {
    register: u32,
}

impl Default for Crc32 {
    fn default() -> Self {
        Crc32 {
            register: 0xFFFF_FFFF,
        }
    }
}

impl Crc32 {
    /// Feeds one byte.
    #[inline]
    pub fn update_byte(&mut self, byte: u8) {
        let mut c = self.register ^ u32::from(byte);
        c = (c >> 4) ^ TABLE[(c & 0xF) as usize];
        c = (c >> 4) ^ TABLE[(c & 0xF) as usize];
        self.register = c;
    }

    /// Feeds a run of bytes: nibble by nibble on a microcontroller, by `crc32fast`'s tables
    /// elsewhere (a stream's check was 2% of a host decode the nibble way).
    pub fn update(&mut self, bytes: &[u8]) {
        #[cfg(target_os = "none")]
        for &b in bytes {
            self.update_byte(b);
        }
        #[cfg(not(target_os = "none"))]
        {
            let mut hasher = crc32fast::Hasher::new_with_initial(!self.register);
            hasher.update(bytes);
            self.register = !hasher.finalize();
        }
    }

    /// The CRC of the bytes fed so far.
    pub fn value(&self) -> u32 {
        !self.register
    }
}

/// The CRC-32 of `bytes`.
pub fn crc32(bytes: &[u8]) -> u32 {
    let mut c = Crc32::default();
    c.update(bytes);
    c.value()
}

/// `TABLE16[i]` is the CRC-16 register's change after shifting nibble `i` out of its top.
const TABLE16: [u16; 16] = nibble_table16();

const fn nibble_table16() -> [u16; 16] {
    let mut table = [0u16; 16];
    let mut i = 0;
    while i < 16 {
        let mut c = (i as u16) << 12;
        let mut k = 0;
        while k < 4 {
            c = if c & 0x8000 != 0 {
                (c << 1) ^ 0x1021
            } else {
                c << 1
            };
            k += 1;
        }
        table[i] = c;
        i += 1;
    }
    table
}

/// The CRC-16 of `bytes` (CRC-16/IBM-3740): a packet's check. A packet is at most 1024 bytes,
/// where this polynomial still detects every error of up to three bits and every burst of up
/// to 16.
pub fn crc16(bytes: &[u8]) -> u16 {
    let mut c: u16 = 0xFFFF;
    for &b in bytes {
        c = (c << 4) ^ TABLE16[usize::from((c >> 12) as u8 ^ (b >> 4))];
        c = (c << 4) ^ TABLE16[usize::from((c >> 12) as u8 ^ (b & 0xF))];
    }
    c
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_the_standard_check_values() {
        // The catalogue check value of CRC-32/ISO-HDLC, and two values zlib's crc32() gives.
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
        assert_eq!(crc32(b""), 0);
        assert_eq!(
            crc32(b"The quick brown fox jumps over the lazy dog"),
            0x414F_A339
        );
    }

    #[test]
    fn crc16_matches_the_catalogue() {
        // CRC-16/IBM-3740's catalogue check value, and the empty string's (the initial value).
        assert_eq!(crc16(b"123456789"), 0x29B1);
        assert_eq!(crc16(b""), 0xFFFF);
        // A bitwise reference on other bytes.
        let data: [u8; 300] = core::array::from_fn(|i| (i * 89 + 7) as u8);
        let mut reference: u16 = 0xFFFF;
        for &b in &data {
            reference ^= u16::from(b) << 8;
            for _ in 0..8 {
                reference = if reference & 0x8000 != 0 {
                    (reference << 1) ^ 0x1021
                } else {
                    reference << 1
                };
            }
        }
        assert_eq!(crc16(&data), reference);
    }

    #[test]
    fn runs_and_single_bytes_agree() {
        // `update` (tables on a host) against `update_byte` (the nibble table everywhere), on
        // runs of every length up to 70 and every alignment.
        let data: [u8; 300] = core::array::from_fn(|i| (i * 151 + 3 + i / 7) as u8);
        for start in 0..8 {
            for len in 0..70 {
                let run = &data[start..start + len];
                let mut bytes = Crc32::default();
                for &b in run {
                    bytes.update_byte(b);
                }
                let mut whole = Crc32::default();
                whole.update(run);
                assert_eq!(whole.value(), bytes.value(), "start {start}, length {len}");
            }
        }
    }

    #[test]
    fn running_and_one_shot_agree() {
        let data: [u8; 200] = core::array::from_fn(|i| (i * 37 + 11) as u8);
        let mut c = Crc32::default();
        for chunk in data.chunks(7) {
            c.update(chunk);
        }
        assert_eq!(c.value(), crc32(&data));
    }
}

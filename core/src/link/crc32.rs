//! CRC-32 (IEEE 802.3, reflected, polynomial 0xEDB88320): the map file's checksum, the same one
//! zip, PNG and `crc32fast` compute, so any tool can verify a map.

/// The CRC of each 4-bit value: a byte is two table steps. A 256-entry table would take one
/// step, but it is 1 KiB of the firmware image's flash, and a frame's CRC is a small share
/// of a point's cost (a second table step a byte).
const TABLE: [u32; 16] = {
    let mut table = [0u32; 16];
    let mut i = 0;
    while i < 16 {
        let mut c = i as u32;
        let mut bit = 0;
        while bit < 4 {
            c = if c & 1 != 0 {
                0xEDB8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
            bit += 1;
        }
        table[i] = c;
        i += 1;
    }
    table
};

/// Incremental CRC-32, so a map can be checksummed while it is written in pieces.
#[derive(Clone, Copy, Debug)]
pub struct Crc32(u32);

impl Default for Crc32 {
    fn default() -> Self {
        Self::new()
    }
}

impl Crc32 {
    pub const fn new() -> Self {
        Self(0xFFFF_FFFF)
    }

    pub fn update(&mut self, bytes: &[u8]) {
        let mut c = self.0;
        for &b in bytes {
            c ^= u32::from(b);
            c = TABLE[(c & 0xF) as usize] ^ (c >> 4);
            c = TABLE[(c & 0xF) as usize] ^ (c >> 4);
        }
        self.0 = c;
    }

    pub const fn finish(self) -> u32 {
        self.0 ^ 0xFFFF_FFFF
    }
}

pub fn crc32(bytes: &[u8]) -> u32 {
    let mut c = Crc32::new();
    c.update(bytes);
    c.finish()
}

#[cfg(test)]
mod tests {
    #[test]
    fn check_value() {
        // The catalogue's check value for CRC-32/ISO-HDLC.
        assert_eq!(super::crc32(b"123456789"), 0xCBF4_3926);
    }

    #[test]
    fn nibble_steps_are_the_bitwise_crc() {
        // The definition, one bit at a time, over every byte value and a run of bytes.
        let bitwise = |bytes: &[u8]| {
            let mut c = 0xFFFF_FFFFu32;
            for &b in bytes {
                c ^= u32::from(b);
                for _ in 0..8 {
                    c = if c & 1 != 0 {
                        0xEDB8_8320 ^ (c >> 1)
                    } else {
                        c >> 1
                    };
                }
            }
            c ^ 0xFFFF_FFFF
        };
        let all: [u8; 256] = core::array::from_fn(|i| i as u8);
        for n in 0..=256 {
            assert_eq!(super::crc32(&all[..n]), bitwise(&all[..n]), "{n}");
        }
    }
}

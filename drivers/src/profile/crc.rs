//! CRC-32 (IEEE 802.3, as in zlib/PNG/Ethernet): reflected polynomial 0xEDB88320, initial value
//! and final XOR 0xFFFFFFFF. `crc32fast` computes it (already built for the PNG encoder, and
//! faster than a table where the CPU has a carry-less multiply); this module keeps the frame code's
//! names and pins the checksum's parameters in its tests.

/// Incremental CRC-32, for checksumming a frame as it is written or in pieces.
#[derive(Clone, Debug, Default)]
pub struct Crc32(crc32fast::Hasher);

impl Crc32 {
    pub fn new() -> Self {
        Self(crc32fast::Hasher::new())
    }

    pub fn update(&mut self, bytes: &[u8]) {
        self.0.update(bytes);
    }

    pub fn finish(self) -> u32 {
        self.0.finalize()
    }
}

/// CRC-32 of `bytes`.
pub fn crc32(bytes: &[u8]) -> u32 {
    crc32fast::hash(bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn standard_check_value() {
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
    }

    #[test]
    fn empty_and_incremental() {
        assert_eq!(crc32(b""), 0);
        let mut c = Crc32::new();
        c.update(b"1234");
        c.update(b"56789");
        assert_eq!(c.finish(), 0xCBF4_3926);
        // A known zlib value, to pin the reflection and final XOR.
        assert_eq!(crc32(b"The quick brown fox jumps over the lazy dog"), 0x414F_A339);
    }
}

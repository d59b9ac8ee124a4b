//! The CRC of SDO block transfers: CRC-16 with polynomial 0x1021 (x¹⁶ + x¹² + x⁵ + 1), initial
//! value 0, no reflection, no final XOR (CiA 301 §7.2.4.3.16; known elsewhere as CRC-16/XMODEM).

const fn table() -> [u16; 16] {
    let mut t = [0u16; 16];
    let mut i = 0;
    while i < 16 {
        let mut c = (i as u16) << 12;
        let mut b = 0;
        while b < 4 {
            c = if c & 0x8000 != 0 {
                (c << 1) ^ 0x1021
            } else {
                c << 1
            };
            b += 1;
        }
        t[i] = c;
        i += 1;
    }
    t
}

/// Nibble-at-a-time lookup table: 32 bytes of flash where a byte-at-a-time one takes 512, for
/// two lookups a byte instead of one (a microcontroller image counts its flash; the CRC runs
/// once per block transfer and per railway frame, over a few bytes).
static TABLE: [u16; 16] = table();

/// Continues a CRC over `data`.
pub fn update(crc: u16, data: &[u8]) -> u16 {
    data.iter().fold(crc, |c, &b| {
        let c = (c << 4) ^ TABLE[usize::from((c >> 12) as u8 ^ (b >> 4))];
        (c << 4) ^ TABLE[usize::from((c >> 12) as u8 ^ (b & 0x0F))]
    })
}

/// The CRC of `data`.
pub fn crc16(data: &[u8]) -> u16 {
    update(0, data)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Bit-by-bit reference: the polynomial division as the standard writes it.
    fn reference(data: &[u8]) -> u16 {
        let mut crc = 0u16;
        for &b in data {
            crc ^= (b as u16) << 8;
            for _ in 0..8 {
                crc = if crc & 0x8000 != 0 {
                    (crc << 1) ^ 0x1021
                } else {
                    crc << 1
                };
            }
        }
        crc
    }

    #[test]
    fn check_value_of_the_standard_test_string() {
        assert_eq!(crc16(b"123456789"), 0x31C3);
        assert_eq!(crc16(b""), 0);
    }

    proptest! {
        #[test]
        fn table_matches_bitwise_division(data in proptest::collection::vec(any::<u8>(), 0..300), cut in 0usize..300) {
            prop_assert_eq!(crc16(&data), reference(&data));
            let cut = cut.min(data.len());
            prop_assert_eq!(update(crc16(&data[..cut]), &data[cut..]), crc16(&data));
        }
    }
}

//! CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no reflection, no final xor).

use crc::{CRC_16_IBM_3740, Crc, Table};

/// CRC-16/IBM-3740 is the catalogue name of CRC-16/CCITT-FALSE.
const CCITT_FALSE: Crc<u16, Table<16>> = Crc::<u16, Table<16>>::new(&CRC_16_IBM_3740);

/// CRC over `type`, `len` and `payload` of one record.
pub fn record_crc(type_and_len_and_payload: &[u8]) -> u16 {
    CCITT_FALSE.checksum(type_and_len_and_payload)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn check_value_of_the_catalogue() {
        // The catalogue's check value for "123456789".
        assert_eq!(record_crc(b"123456789"), 0x29B1);
    }
}

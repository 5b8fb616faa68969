//! CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no reflection, no final xor).
//!
//! The `crc` crate's slice-by-16 table takes 16 bytes a step and the rest one by one. A
//! record's CRC covers 44 bytes (an IMU record's type, length and payload), whose last 12
//! would go one by one: three quarters of the time. Zero bytes led into the register
//! move its state by a fixed, invertible map (a multiplication by x⁸ modulo the
//! polynomial), so the CRC of `k` zero bytes and then the data, begun from the state
//! that those `k` bytes take to the initial value, is the data's CRC. With `k` making
//! the length a multiple of 16, every byte goes through the 16-byte step: 44 bytes take
//! about half the time (6.0 against 11.4 ms for 240 000 records here).

use crc::{CRC_16_IBM_3740, Crc, Table};

use super::record::IMU_PAYLOAD_LEN;

/// CRC-16/IBM-3740 is the catalogue name of CRC-16/CCITT-FALSE.
const CCITT_FALSE: Crc<u16, Table<16>> = Crc::<u16, Table<16>>::new(&CRC_16_IBM_3740);

/// The longest input led by zero bytes in a buffer on the stack; a longer one (none of
/// the format's records: a resync's candidate frame of a damaged length) is taken as it
/// is.
const LED_MAX: usize = 64;

/// `LEAD_STATES[k]`: the register state that `k` zero bytes take to the initial value.
const LEAD_STATES: [u16; 16] = lead_states();

/// The register state before one zero bit that leaves `after`: the shift of the
/// register undone. A shift that dropped a set top bit added the polynomial, whose
/// lowest bit is set; a shift alone leaves the lowest bit clear.
const fn before_zero_bit(after: u16) -> u16 {
    let poly = CRC_16_IBM_3740.poly;
    if after & 1 == 1 {
        ((after ^ poly) >> 1) | 0x8000
    } else {
        after >> 1
    }
}

const fn lead_states() -> [u16; 16] {
    let mut states = [0u16; 16];
    states[0] = CRC_16_IBM_3740.init;
    let mut k = 1;
    while k < 16 {
        let mut s = states[k - 1];
        let mut bit = 0;
        while bit < 8 {
            s = before_zero_bit(s);
            bit += 1;
        }
        states[k] = s;
        k += 1;
    }
    states
}

/// Bytes an IMU record's CRC covers: its type, length and payload.
const IMU_CRC_LEN: usize = 2 + IMU_PAYLOAD_LEN;

/// CRC over `type`, `len` and `payload` of one record.
pub fn record_crc(type_and_len_and_payload: &[u8]) -> u16 {
    let data = type_and_len_and_payload;
    // Nearly every record is an IMU record: its bytes copied at their fixed length are
    // moves the compiler writes in place, where a length known only at run time is a
    // call to `memcpy` (2.7 % of the ingest's profile).
    if let Ok(imu) = <&[u8; IMU_CRC_LEN]>::try_from(data) {
        const LEAD: usize = IMU_CRC_LEN.wrapping_neg() % 16;
        let mut led = [0u8; LEAD + IMU_CRC_LEN];
        led[LEAD..].copy_from_slice(imu);
        let mut digest = CCITT_FALSE.digest_with_initial(LEAD_STATES[LEAD]);
        digest.update(&led);
        return digest.finalize();
    }
    let lead = data.len().wrapping_neg() % 16;
    if lead + data.len() > LED_MAX {
        return CCITT_FALSE.checksum(data);
    }
    let mut led = [0u8; LED_MAX];
    led[lead..lead + data.len()].copy_from_slice(data);
    let mut digest = CCITT_FALSE.digest_with_initial(LEAD_STATES[lead]);
    digest.update(&led[..lead + data.len()]);
    digest.finalize()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn check_value_of_the_catalogue() {
        // The catalogue's check value for "123456789".
        assert_eq!(record_crc(b"123456789"), 0x29B1);
    }

    #[test]
    fn each_lead_state_is_taken_to_the_initial_value_by_its_zero_bytes() {
        for (k, &state) in LEAD_STATES.iter().enumerate() {
            let mut digest = CCITT_FALSE.digest_with_initial(state);
            digest.update(&[0u8; 16][..k]);
            assert_eq!(digest.finalize(), 0xFFFF, "{k} zero bytes");
        }
    }

    #[test]
    fn led_inputs_give_the_library_s_crc_at_every_length() {
        // Every length to beyond the led buffer's, of bytes that are not all alike.
        let bytes: Vec<u8> = (0..300u32).map(|i| (i * 151 + 7) as u8).collect();
        for n in 0..=bytes.len() {
            for start in [0, 1, 5] {
                let data = &bytes[start..(start + n).min(bytes.len())];
                assert_eq!(
                    record_crc(data),
                    CCITT_FALSE.checksum(data),
                    "{} bytes from {start}",
                    data.len()
                );
            }
        }
    }
}

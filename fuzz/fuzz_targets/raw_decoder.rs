//! Any byte sequence: the decoder never panics, never loops forever, and its accounting
//! identities hold.
#![no_main]

use libfuzzer_sys::fuzz_target;
use unz_formats::raw::{FileHeader, RawReader};

fuzz_target!(|data: &[u8]| {
    // Behind a valid header, so the fuzzer spends its time on the records.
    let mut bytes = FileHeader::unz50(0, "FUZZ").encode().to_vec();
    bytes.extend_from_slice(data);
    for input in [data, bytes.as_slice()] {
        if let Ok(mut reader) = RawReader::new(input) {
            while let Ok(Some(_)) = reader.next_record() {}
            let report = reader.report();
            assert!(report.is_consistent(), "{report:?}");
            let body = input
                .len()
                .saturating_sub(usize::from(reader.header().header_len))
                as u64;
            assert!(report.bytes_skipped + report.truncated_bytes <= body);
        }
    }
});

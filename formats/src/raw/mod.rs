//! The binary UNZ raw log, format version 1 (`shared/spec/unz-raw-format.md` §1).
//!
//! [`RawReader`] is a streaming decoder: it holds at most one buffer of the input
//! (a few hundred KiB) whatever the file size, survives every fault of §1.3 and keeps
//! the accounting of §1.4 in an [`IngestReport`]. [`RawWriter`] writes the same format
//! (used by the simulator and by the round-trip tests).
//!
//! ```
//! use unz_formats::raw::{Accepted, FileHeader, ImuRecord, RawReader, RawWriter};
//! let header = FileHeader::unz50(1_700_000_000_000_000, "SN-1");
//! let mut bytes = Vec::new();
//! let mut writer = RawWriter::new(&mut bytes, &header).unwrap();
//! writer.write_imu(&ImuRecord { seq: 0, t_us: 10_000, dtheta: [1, 2, 3], dvel: [4, 5, -6],
//!     odo_count: 7, status: 0 }).unwrap();
//! writer.finish().unwrap();
//! let mut reader = RawReader::new(bytes.as_slice()).unwrap();
//! let first = reader.next_record().unwrap().unwrap();
//! assert!(matches!(first, Accepted::Imu(s) if s.raw.dtheta == [1, 2, 3]));
//! assert_eq!(reader.report().imu_accepted, 1);
//! ```

mod clock;
mod crc;
pub mod faults;
mod header;
mod reader;
mod record;
mod writer;

pub use clock::{JITTER_TOLERANCE, LEARN_INTERVALS, MAX_TOLERANCE_PERIODS};
pub use faults::{DamagedLog, RawLog};
pub use header::{FileHeader, HEADER_LEN, MAGIC};
pub use reader::{
    Accepted, FaultEvent, FaultKind, ImuSample, MarkSample, RawReader, find_imu_record,
};
pub use record::{
    IMU_PAYLOAD_LEN, ImuRecord, MARK_PAYLOAD_LEN, MAX_FRAME_LEN, MarkRecord, Record, SYNC,
    TYPE_IMU, TYPE_MARK, frame_len,
};
pub use writer::RawWriter;

pub use crate::report::IngestReport;

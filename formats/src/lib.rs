//! File formats of the unz pipeline: the binary UNZ raw log, run manifests, KF-GINS text
//! logs, canonical Arrow schemas, and Parquet / MCAP (ROS 2 messages) I/O.
//!
//! Everything here treats its input as untrusted: no panic on any byte sequence, no
//! allocation sized by a length field, every fault counted and located (file, byte offset
//! or line), and paths named by a manifest kept inside its folder.
//!
//! ```
//! use unz_formats::manifest::RunManifest;
//! let text = "name = \"r1\"\nraw = \"r1.unz\"\nformat = \"unz-binary\"\n\
//!             [site]\nlatitude_deg = 52.0\nlongitude_deg = 21.0\nheight_m = 100.0\n";
//! let m = RunManifest::parse(text, std::path::Path::new("runs/r1/run.toml")).unwrap();
//! assert_eq!(m.raw, std::path::Path::new("runs/r1/r1.unz"));
//! ```

pub mod atomic;
mod chunk_ledger;
mod delta_pages;
pub mod error;
pub mod followed_steps;
pub mod hashing_writer;
mod int_pages;
pub mod kfgins;
mod lines_apart;
pub mod manifest;
pub mod mcap_chunks;
pub mod mcap_io;
mod parquet_columns;
pub mod parquet_io;
pub mod parquet_thread;
mod plain_pages;
pub mod raw;
pub mod regular;
pub mod report;
pub mod resent;
pub mod ros2_msgs;
pub mod schema;
pub mod slot_clock;
pub mod speed_floor;
pub mod speed_spikes;
pub mod split_doubles;
mod split_pages;
pub mod tables;
pub mod text_bursts;
pub mod text_ticks;

pub use error::{FileError, FormatError};
pub use report::{IngestEvents, IngestReport, OdometerFailures, OdometerFileReport, TextClockStep};

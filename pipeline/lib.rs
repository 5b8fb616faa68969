//! `unz`: post-processing of archived UNZ-50 land-navigation logs with the DISUPT
//! initial-settings correction.
//!
//! The binary's commands live in [`commands`], one file each; the stage functions they
//! call (ingest, …) are in this crate's modules and take validated plans, not raw flags.

pub mod artifacts;
pub mod campaign;
pub mod campaign_lag;
pub mod campaign_mark;
pub mod campaign_outliers;
pub mod campaign_pitch;
pub mod campaign_points;
pub mod campaign_pools;
pub mod campaign_settings;
pub mod campaign_yaw;
pub mod cli;
pub mod commands;
pub mod config;
pub mod cpu_time;
pub mod derive_io;
pub mod disupt_stage;
pub mod export;
pub mod file_hashes;
pub mod flow;
pub mod ingest;
pub mod lock;
pub mod memory;
pub mod method_tables;
pub mod nav_writer;
pub mod odometer_bridge;
pub mod odometer_column;
pub mod odometer_gaps;
pub mod odometer_range;
pub mod odometer_stuck;
pub mod picked_rows;
pub mod raw_mcap;
pub mod read_ahead;
pub mod review;
pub mod review_sensors;
pub mod runs;
pub mod simulate_io;
pub mod stage;
pub mod standing_motion;
pub mod sweep;

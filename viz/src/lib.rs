//! Review material built from the pipeline's cached tables; nothing here navigates.
//!
//! - [`recording`]: one Rerun recording (`.rrd`) per run, from a [`review::Review`]: a
//!   map, a 3D view in local east-north-up metres, the criteria and sensor series and
//!   the DISUPT tables, with a [`blueprint`] that lays them out. Entity paths are in
//!   [`paths`].
//! - [`report`]: the campaign's static HTML report with SVG plots.
//!
//! ```no_run
//! use unz_viz::review::Review;
//! let review = Review { name: "run-1".into(), ..Review::default() };
//! let stats = unz_viz::recording::write_rrd(&review, std::path::Path::new("run-1.rrd"))?;
//! println!("{} rows", stats.rows);
//! # Ok::<(), unz_viz::recording::RecordingError>(())
//! ```

pub mod blueprint;
pub mod frames;
pub mod paths;
pub mod recording;
pub mod report;
pub mod review;
mod rrd_sink;

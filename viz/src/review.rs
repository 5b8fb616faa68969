//! What a review recording shows, as plain columns. The pipeline fills a [`Review`]
//! from its cached tables; [`crate::recording`] turns it into a Rerun recording.
//!
//! Times are seconds since the run's first IMU sample. Local positions are metres north
//! and east of the start and up from its height.

/// One run's review material.
#[derive(Debug, Clone, Default)]
pub struct Review {
    /// Run name (the recording's id).
    pub name: String,
    /// Nominal IMU sample period, s.
    pub sample_dt_s: f64,
    /// Raw-rate series, in the recording's blocks.
    pub sensors: SensorBlocks,
    /// Where the odometer failed (its distance bridged by the inertial speed, or held).
    pub odometer_failures: Vec<OdometerFailure>,
    /// Criteria series at the ΔTg epochs, initial settings.
    pub epochs: EpochSeries,
    /// Cumulative Kryt1 per settings (`initial` first).
    pub kryt1: Vec<Kryt1Curve>,
    /// Trajectories per settings (`initial`, methods, `truth` when known).
    pub tracks: Vec<Track>,
    /// Label of the track that drives the vehicle (the corrected navigation).
    pub vehicle_track: Option<String>,
    /// Surveyed control points with the errors of each settings.
    pub control_points: Vec<ControlPointView>,
    /// The vehicle's mark (what the control points are compared with) from the navigated
    /// point, in the IMU's axes (x forward, y right, z down), m, when away from it: the
    /// configured lever arm, moved by the joint fit when it estimated the mark and drives
    /// the vehicle.
    pub mark_lever_arm_m: Option<[f64; 3]>,
    /// Sensitivity map, when a sweep exists.
    pub sweep: Option<Sweep>,
    /// 1σ of the corrected route, when the joint fit made it.
    pub route_sigma: Option<RouteSigmaView>,
    /// The DISUPT tables (Markdown).
    pub tables_markdown: String,
    /// A few lines on the run (Markdown), shown in the read-me document.
    pub summary_markdown: String,
}

/// IMU samples over which the odometer failed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct OdometerFailure {
    /// The first sample.
    pub first_sample: i64,
    /// Samples.
    pub samples: i64,
    /// Bridged by the inertial along-track speed; else the distance held.
    pub bridged: bool,
}

/// The raw-rate series as the recording plots them: per block of [`SensorBlocks::step`]
/// IMU samples (the last one may be shorter), the block's first time and sample, the
/// means of u, u̇ and ru, and the body rates from the block's increments. Built sample by
/// sample ([`SensorBlocksBuilder`]), so a run's per-sample series are never held whole.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SensorBlocks {
    /// Samples per block.
    pub step: usize,
    /// Time of each block's first sample, s.
    pub t_s: Vec<f64>,
    /// Index of each block's first sample.
    pub sample: Vec<i64>,
    /// Mean odometer speed u, m/s.
    pub u_mps: Vec<f64>,
    /// Mean u̇, m/s².
    pub u_dot_mps2: Vec<f64>,
    /// Mean ru, m/s².
    pub ru_mps2: Vec<f64>,
    /// Body angular rate about x, y, z (angle increments over the block's duration), °/s.
    pub gyro_deg_s: [Vec<f64>; 3],
    /// Body specific force along x, y, z (velocity increments over the block's duration),
    /// m/s².
    pub accel_mps2: [Vec<f64>; 3],
}

impl SensorBlocks {
    /// The sample at `t_s` (the blocks' time base), samples `sample_dt_s` apart within
    /// the block that holds it; 0 without blocks.
    pub fn sample_at(&self, t_s: f64, sample_dt_s: f64) -> i64 {
        let b = self.t_s.partition_point(|&t| t <= t_s).saturating_sub(1);
        let (Some(&t0), Some(&first)) = (self.t_s.get(b), self.sample.get(b)) else {
            return 0;
        };
        let within = ((t_s - t0) / sample_dt_s.max(1e-9)).round().max(0.0);
        first + (within as i64).min(self.step.saturating_sub(1) as i64)
    }

    /// The blocks that hold a sample of one of `failures` (in order) that is `bridged`
    /// (or held, with `false`).
    pub fn blocks_of(&self, failures: &[OdometerFailure], bridged: bool) -> Vec<usize> {
        let mut spans = failures.iter().filter(|f| f.bridged == bridged).peekable();
        let mut out = Vec::new();
        for (k, &first) in self.sample.iter().enumerate() {
            let end = first + self.step as i64;
            // Spans wholly before this block are done.
            while spans
                .next_if(|f| f.first_sample + f.samples <= first)
                .is_some()
            {}
            if spans.peek().is_some_and(|f| f.first_sample < end) {
                out.push(k);
            }
        }
        out
    }

    /// Room for `blocks` more blocks in every column, reserved once.
    pub fn reserve_exact(&mut self, blocks: usize) {
        for v in [
            &mut self.t_s,
            &mut self.u_mps,
            &mut self.u_dot_mps2,
            &mut self.ru_mps2,
        ]
        .into_iter()
        .chain(&mut self.gyro_deg_s)
        .chain(&mut self.accel_mps2)
        {
            v.reserve_exact(blocks);
        }
        self.sample.reserve_exact(blocks);
    }
}

/// One IMU sample of the derive, as [`SensorBlocksBuilder`] takes it.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SensorSample {
    /// Time, s.
    pub t_s: f64,
    /// Interval, s.
    pub dt_s: f64,
    /// Angle increments, rad, body frame.
    pub dtheta_rad: [f64; 3],
    /// Velocity increments, m/s, body frame.
    pub dvel_mps: [f64; 3],
    /// Odometer speed u, m/s.
    pub u_mps: f64,
    /// u̇, m/s².
    pub u_dot_mps2: f64,
    /// ru, m/s².
    pub ru_mps2: f64,
}

/// Builds [`SensorBlocks`] from samples handed in order.
#[derive(Debug, Clone)]
pub struct SensorBlocksBuilder {
    out: SensorBlocks,
    block: Vec<SensorSample>,
    samples: usize,
}

impl SensorBlocksBuilder {
    /// Blocks of `step` samples (at least one).
    pub fn new(step: usize) -> Self {
        let step = step.max(1);
        Self {
            out: SensorBlocks {
                step,
                ..SensorBlocks::default()
            },
            block: Vec::with_capacity(step),
            samples: 0,
        }
    }

    /// Blocks as long as the recording's series rate ([`crate::recording::SERIES_RATE_HZ`])
    /// for IMU samples `sample_dt_s` apart.
    pub fn at_series_rate(sample_dt_s: f64) -> Self {
        Self::new(
            (1.0 / (crate::recording::SERIES_RATE_HZ * sample_dt_s.max(1e-6))).round() as usize,
        )
    }

    /// Room for the blocks of `samples` samples, reserved once (a bound from trusted
    /// counts: the caller's own series, or a Parquet footer bounded by its file's size).
    pub fn with_room_for(mut self, samples: usize) -> Self {
        let blocks = samples.div_ceil(self.out.step);
        self.out.reserve_exact(blocks);
        self
    }

    /// The next sample.
    pub fn push(&mut self, s: SensorSample) {
        self.block.push(s);
        self.samples += 1;
        if self.block.len() == self.out.step {
            self.close();
        }
    }

    /// The blocks, the last (shorter) one included.
    pub fn finish(mut self) -> SensorBlocks {
        if !self.block.is_empty() {
            self.close();
        }
        self.out
    }

    fn close(&mut self) {
        let c = &self.block;
        let n = c.len() as f64;
        let mean = |f: fn(&SensorSample) -> f64| c.iter().map(f).sum::<f64>() / n;
        let out = &mut self.out;
        out.t_s.push(c[0].t_s);
        out.sample.push((self.samples - c.len()) as i64);
        out.u_mps.push(mean(|s| s.u_mps));
        out.u_dot_mps2.push(mean(|s| s.u_dot_mps2));
        out.ru_mps2.push(mean(|s| s.ru_mps2));
        // The block's duration as its mean interval times its length.
        let dt_s = (mean(|s| s.dt_s) * n).max(1e-9);
        for a in 0..3 {
            let sum = |inc: fn(&SensorSample) -> [f64; 3]| c.iter().map(|s| inc(s)[a]).sum::<f64>();
            out.gyro_deg_s[a].push(sum(|s| s.dtheta_rad) * (180.0 / std::f64::consts::PI) / dt_s);
            out.accel_mps2[a].push(sum(|s| s.dvel_mps) / dt_s);
        }
        self.block.clear();
    }
}

/// Per ΔTg epoch, with the initial settings.
#[derive(Debug, Clone, Default)]
pub struct EpochSeries {
    /// Time, s.
    pub t_s: Vec<f64>,
    /// Gyro (navigated) pitch Θ_n, rad.
    pub theta_gyro_rad: Vec<f64>,
    /// Gyro roll Φ_n, rad.
    pub phi_gyro_rad: Vec<f64>,
    /// Accelerometer pitch Θ_p, rad.
    pub theta_acc_rad: Vec<f64>,
    /// Accelerometer roll Φ_p, rad.
    pub phi_acc_rad: Vec<f64>,
    /// ΔΘ, rad.
    pub d_theta_rad: Vec<f64>,
    /// ΔΦ, rad.
    pub d_phi_rad: Vec<f64>,
    /// Kalman estimate of ΔΘ, rad.
    pub kf_d_theta_rad: Vec<f64>,
    /// Kalman estimate of ΔΦ, rad.
    pub kf_d_phi_rad: Vec<f64>,
    /// Filtered accelerometer a_x, m/s².
    pub ax_f_mps2: Vec<f64>,
    /// Filtered accelerometer a_y, m/s².
    pub ay_f_mps2: Vec<f64>,
    /// Filtered u̇, m/s².
    pub u_dot_f_mps2: Vec<f64>,
    /// Filtered ru, m/s².
    pub ru_f_mps2: Vec<f64>,
}

/// Cumulative Kryt1 of one settings.
#[derive(Debug, Clone, Default)]
pub struct Kryt1Curve {
    /// `initial`, `oepi`, `owpi` or `joint`.
    pub label: String,
    /// Time, s.
    pub t_s: Vec<f64>,
    /// Cumulative Kryt1, rad.
    pub kryt1_cum_rad: Vec<f64>,
}

/// One trajectory.
#[derive(Debug, Clone, Default)]
pub struct Track {
    /// `initial`, `oepi`, `owpi`, `joint` or `truth`.
    pub label: String,
    /// Time, s.
    pub t_s: Vec<f64>,
    /// Latitude, degrees.
    pub lat_deg: Vec<f64>,
    /// Longitude, degrees.
    pub lon_deg: Vec<f64>,
    /// North of the start, m.
    pub north_m: Vec<f64>,
    /// East of the start, m.
    pub east_m: Vec<f64>,
    /// Up from the start's height, m.
    pub up_m: Vec<f64>,
    /// Roll, degrees.
    pub roll_deg: Vec<f64>,
    /// Pitch, degrees.
    pub pitch_deg: Vec<f64>,
    /// Heading, degrees clockwise from north.
    pub heading_deg: Vec<f64>,
}

/// A surveyed control point.
#[derive(Debug, Clone, Default)]
pub struct ControlPointView {
    /// Id.
    pub id: u32,
    /// Latitude, degrees.
    pub lat_deg: f64,
    /// Longitude, degrees.
    pub lon_deg: f64,
    /// North of the start, m.
    pub north_m: f64,
    /// East of the start, m.
    pub east_m: f64,
    /// Up from the start's height, m.
    pub up_m: f64,
    /// (settings label, ΔX north m, ΔY east m).
    pub errors: Vec<(String, f64, f64)>,
}

/// A sweep of Kryt1 and Kryt2 over one or two components.
#[derive(Debug, Clone, Default)]
pub struct Sweep {
    /// Axis names and their values (one or two axes; the first varies slowest).
    pub axes: Vec<(String, Vec<f64>)>,
    /// Kryt1 at each grid point, rad, row-major.
    pub kryt1_rad: Vec<f64>,
    /// Kryt2 at each grid point, m, row-major.
    pub kryt2_m: Vec<f64>,
}

/// Colour of a settings label, RGBA (initial red, OEPI orange, OWPI purple, joint
/// green, truth dark grey).
pub fn color_of(label: &str) -> [u8; 4] {
    match label {
        "initial" => [214, 39, 40, 255],
        "oepi" => [255, 127, 14, 255],
        "owpi" => [148, 103, 189, 255],
        "joint" => [44, 160, 44, 255],
        "truth" => [60, 60, 60, 255],
        _ => [31, 119, 180, 255],
    }
}

/// Display name of a settings label.
pub fn display_name(label: &str) -> String {
    match label {
        "initial" => "initial settings".into(),
        "oepi" => "OEPI".into(),
        "owpi" => "OWPI".into(),
        "joint" => "joint".into(),
        "truth" => "truth".into(),
        other => other.into(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_time_is_a_sample_of_its_block() {
        let blocks = SensorBlocks {
            step: 10,
            t_s: vec![0.0, 1.0, 2.0],
            sample: vec![0, 10, 20],
            ..SensorBlocks::default()
        };
        assert_eq!(blocks.sample_at(1.3, 0.1), 13);
        assert_eq!(blocks.sample_at(0.0, 0.1), 0);
        assert_eq!(blocks.sample_at(-5.0, 0.1), 0);
        // Beyond the last block's samples: its last.
        assert_eq!(blocks.sample_at(9.0, 0.1), 29);
        assert_eq!(SensorBlocks::default().sample_at(1.0, 0.1), 0);
    }

    #[test]
    fn sensor_blocks_cover_a_short_last_block() {
        let mut b = SensorBlocksBuilder::new(2);
        for k in 0..5 {
            let x = k as f64;
            b.push(SensorSample {
                t_s: 0.01 * x,
                dt_s: 0.01,
                dtheta_rad: [1e-3 * x, 0.0, -2e-3],
                dvel_mps: [0.0, 0.1, -0.098],
                u_mps: 1.0 + 2.0 * x,
                u_dot_mps2: 0.0,
                ru_mps2: x,
            });
        }
        let s = b.finish();
        assert_eq!(s.sample, vec![0, 2, 4]);
        assert_eq!(s.t_s, vec![0.0, 0.02, 0.04]);
        assert_eq!(s.u_mps, vec![2.0, 6.0, 9.0]);
        assert_eq!(s.ru_mps2, vec![0.5, 2.5, 4.0]);
        // Rates over each block's own duration, the short last one's too.
        for (j, want) in [(0, 0.05), (1, 0.25), (2, 0.4)] {
            let got = s.gyro_deg_s[0][j].to_radians();
            assert!((got - want).abs() < 1e-12, "block {j}: {got} rad/s");
            assert!((s.gyro_deg_s[2][j].to_radians() + 0.2).abs() < 1e-12);
            assert!((s.accel_mps2[2][j] + 9.8).abs() < 1e-12);
        }
    }

    /// The blocks a failure's samples fall in, by kind: one sample in a block is enough,
    /// and a block between two failures is not one.
    #[test]
    fn a_failure_s_blocks_are_those_that_hold_its_samples() {
        // Blocks of 10 samples, the last short: 0, 10, …, 90, 100 (of 105 samples).
        let blocks = SensorBlocks {
            step: 10,
            sample: (0..=100).step_by(10).collect(),
            ..SensorBlocks::default()
        };
        let failure = |first_sample, samples, bridged| OdometerFailure {
            first_sample,
            samples,
            bridged,
        };
        let failures = [
            failure(5, 10, true),   // samples 5–14: blocks 0 and 1
            failure(30, 10, false), // 30–39: block 3
            failure(40, 1, true),   // 40: block 4
            failure(69, 2, false),  // 69–70: blocks 6 and 7
            failure(104, 1, true),  // 104: the short last block
        ];
        assert_eq!(blocks.blocks_of(&failures, true), vec![0, 1, 4, 10]);
        assert_eq!(blocks.blocks_of(&failures, false), vec![3, 6, 7]);
        assert!(blocks.blocks_of(&[], true).is_empty());
    }
}

/// 1σ of the corrected route over time.
#[derive(Debug, Clone, Default)]
pub struct RouteSigmaView {
    /// Time since the first IMU sample, s.
    pub t_s: Vec<f64>,
    /// North, m.
    pub north_m: Vec<f64>,
    /// East, m.
    pub east_m: Vec<f64>,
    /// Heading, degrees.
    pub heading_deg: Vec<f64>,
}

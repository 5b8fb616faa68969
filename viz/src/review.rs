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
    /// Raw-rate series (decimated by the recording).
    pub imu: ImuSeries,
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
    /// Sensitivity map, when a sweep exists.
    pub sweep: Option<Sweep>,
    /// 1σ of the corrected route, when the joint fit made it.
    pub route_sigma: Option<RouteSigmaView>,
    /// The DISUPT tables (Markdown).
    pub tables_markdown: String,
    /// A few lines on the run (Markdown), shown in the read-me document.
    pub summary_markdown: String,
}

/// Per IMU sample.
#[derive(Debug, Clone, Default)]
pub struct ImuSeries {
    /// Time, s (shared with the derive it comes from, not copied).
    pub t_s: std::sync::Arc<[f64]>,
    /// Interval, s.
    pub dt_s: std::sync::Arc<[f64]>,
    /// Angle increments, rad, body frame.
    pub dtheta_rad: std::sync::Arc<[[f64; 3]]>,
    /// Velocity increments, m/s, body frame.
    pub dvel_mps: std::sync::Arc<[[f64; 3]]>,
    /// Odometer speed u, m/s.
    pub u_mps: Vec<f64>,
    /// u̇, m/s².
    pub u_dot_mps2: Vec<f64>,
    /// ru, m/s².
    pub ru_mps2: Vec<f64>,
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

/// Block means of `v` over `step` samples: (index of each block's first sample, mean).
pub fn block_means(v: &[f64], step: usize) -> impl Iterator<Item = (usize, f64)> + '_ {
    let step = step.max(1);
    v.chunks(step)
        .enumerate()
        .map(move |(j, c)| (j * step, c.iter().sum::<f64>() / c.len() as f64))
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
    fn block_means_cover_a_short_last_block() {
        let v = [1.0, 3.0, 5.0, 7.0, 9.0];
        let m: Vec<_> = block_means(&v, 2).collect();
        assert_eq!(m, vec![(0, 2.0), (2, 6.0), (4, 9.0)]);
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

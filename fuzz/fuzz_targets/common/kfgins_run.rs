//! The fuzz targets' KF-GINS runs: any text as the log and its odometer (an 8th column, a
//! speed file or a distance file), with a manifest at Kingston's site (the seeds are
//! stretches of the shipped Kingston segment, `fuzz/make_seeds.py`).
//!
//! The input's first byte picks the odometer (its value mod 3: the log's 8th column, a
//! speed file, a distance file), the start (its value / 3, even: the alignment over the
//! first 5 s; odd: no static start, the heading given) and, for speeds, a speed floor
//! (its value / 6, odd: `speed_floor_mps = 0.04`) and, for a file, its value's column
//! (its value / 12 mod 4: 1, `value_column = 2`, the file's lines read column by column;
//! 3, `value_column = "speed"`, the column its header line names so); the rest up to its
//! first NUL byte is the log, the rest after it the odometer file.

use std::path::PathBuf;

#[path = "scratch.rs"]
mod scratch;

/// The manifest's odometer section for each choice.
const ODOMETER: [&str; 3] = [
    "",
    "[odometer]\nfile = \"odometer.txt\"\nkind = \"speed_mps\"\n",
    "[odometer]\nfile = \"odometer.txt\"\nkind = \"distance_m\"\n",
];

/// The manifest's start for each choice: a static start, or none with the heading given
/// (Kingston's at its first stop, 152 825 s).
const START: [&str; 2] = [
    "[initial]\nstatic_s = 5.0\n",
    "[initial]\nstatic_s = 0.0\nazimuth_deg = 25.0\n",
];

/// Kingston's first control point, where its drive stops at 152 825 s.
const CONTROL_POINT: &str = "[[control_point]]\nid = 1\nlatitude_deg = 44.236711682\n\
    longitude_deg = -76.465835437\nheight_m = 44.419\nt_s = 152825.0\n";

/// Writes the input as a run in this process's scratch folder, with the control point if
/// `control_point`, and returns the run's folder and an output folder emptied.
pub fn write_run(data: &[u8], control_point: bool) -> Option<(PathBuf, PathBuf)> {
    let (&choice, rest) = data.split_first()?;
    let (log, odometer) = match rest.iter().position(|&b| b == 0) {
        Some(k) => (&rest[..k], &rest[k + 1..]),
        None => (rest, &[][..]),
    };
    let (run, out) = scratch::run_and_out();
    std::fs::write(run.join("imu.txt"), log).unwrap();
    std::fs::write(run.join("odometer.txt"), odometer).unwrap();
    let choice = usize::from(choice);
    let odometer = ODOMETER[choice % ODOMETER.len()];
    // A floor for speeds only: the manifest refuses one for distances.
    let floored = choice / 6 % 2 == 1 && choice % ODOMETER.len() != 2;
    let mut odometer = match (floored, odometer) {
        (false, _) => odometer.to_owned(),
        (true, "") => "[odometer]\nspeed_floor_mps = 0.04\n".to_owned(),
        (true, file) => format!("{file}speed_floor_mps = 0.04\n"),
    };
    // A column for a file only: the manifest refuses one without.
    if choice % ODOMETER.len() != 0 {
        match choice / 12 % 4 {
            1 => odometer.push_str("value_column = 2\n"),
            3 => odometer.push_str("value_column = \"speed\"\n"),
            _ => {}
        }
    }
    let manifest = format!(
        "name = \"fuzz\"\nraw = \"imu.txt\"\nformat = \"kf-gins\"\n\n[site]\n\
         latitude_deg = 44.23632744\nlongitude_deg = -76.465406407\nheight_m = 46.2\n\n{}\n{}\n{}",
        START[choice / ODOMETER.len() % START.len()],
        odometer,
        if control_point { CONTROL_POINT } else { "" },
    );
    std::fs::write(run.join("run.toml"), manifest).unwrap();
    Some((run, out))
}

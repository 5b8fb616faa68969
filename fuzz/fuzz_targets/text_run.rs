//! Any text as a KF-GINS log and its odometer (an 8th column, a speed file or a distance
//! file), ingested and derived by the pipeline itself: an error or a derive, never a
//! panic or a hang (libFuzzer's `-timeout`).
//!
//! The input's first byte picks the odometer (its value mod 3: the log's 8th column, a
//! speed file, a distance file); the rest up to its first NUL byte is the log, the rest
//! after it the odometer file.
#![no_main]

#[path = "common/scratch.rs"]
mod scratch;

use libfuzzer_sys::fuzz_target;
use unz::flow::{RunCtx, ensure_derive};
use unz::runs::load_run;

/// The manifest's odometer section for each choice.
const ODOMETER: [&str; 3] = [
    "",
    "[odometer]\nfile = \"odometer.txt\"\nkind = \"speed_mps\"\n",
    "[odometer]\nfile = \"odometer.txt\"\nkind = \"distance_m\"\n",
];

fuzz_target!(|data: &[u8]| {
    let Some((&choice, rest)) = data.split_first() else {
        return;
    };
    let (log, odometer) = match rest.iter().position(|&b| b == 0) {
        Some(k) => (&rest[..k], &rest[k + 1..]),
        None => (rest, &[][..]),
    };
    let dir = scratch::scratch();
    let (run, out) = (dir.join("run"), dir.join("out"));
    let _ = std::fs::remove_dir_all(&out);
    std::fs::create_dir_all(&run).unwrap();
    std::fs::write(run.join("imu.txt"), log).unwrap();
    std::fs::write(run.join("odometer.txt"), odometer).unwrap();
    let manifest = format!(
        "name = \"fuzz\"\nraw = \"imu.txt\"\nformat = \"kf-gins\"\n\n[site]\n\
         latitude_deg = 44.2\nlongitude_deg = -76.5\nheight_m = 40.0\n\n\
         [initial]\nstatic_s = 5.0\n\n{}",
        ODOMETER[usize::from(choice) % ODOMETER.len()]
    );
    std::fs::write(run.join("run.toml"), manifest).unwrap();
    let ctx = RunCtx::new(load_run(&run).unwrap(), out, false);
    let params = unz::config::for_run(&toml::Table::new(), &ctx.manifest).unwrap();
    let _ = ensure_derive(&ctx, &params);
});

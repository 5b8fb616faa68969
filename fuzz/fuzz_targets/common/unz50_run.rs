//! The fuzz targets' UNZ-50 runs: any sequence of records, framed with valid CRCs (the
//! fuzzer would seldom forge one), described by the input as operations, each a byte and
//! its arguments: a run of samples of a level vehicle at rest or driving, accelerating
//! and turning on the rotating Earth (the counts, time tags and odometer advancing as an
//! UNZ-50 writes them), a sample of any fields, a mark, or bytes between records.

use std::path::PathBuf;

use unz_formats::raw::{FileHeader, ImuRecord, MarkRecord, RawWriter};

/// Samples a run may hold at most: ten minutes at 100 Hz.
const MAX_SAMPLES: usize = 60_000;

/// The run's manifest: the alignment over the first 5 s, and one control point, where
/// the seed `drive-turn-stop-mark` stops (338.5 m north and 130.4 m east of the site).
const MANIFEST: &str = "name = \"fuzz\"\nraw = \"run.unz\"\nformat = \"unz-binary\"\n\n\
    [site]\nlatitude_deg = 52.2\nlongitude_deg = 21.0\nheight_m = 110.0\n\n\
    [initial]\nstatic_s = 5.0\n\n\
    [[control_point]]\nid = 1\nlatitude_deg = 52.203042058\nlongitude_deg = 21.001906675\n\
    height_m = 110.0\n";

#[path = "scratch.rs"]
mod scratch;

/// The input's bytes, taken in order (zeros once it ends).
struct Args<'a>(&'a [u8]);

impl Args<'_> {
    fn u8(&mut self) -> u8 {
        let Some((&b, rest)) = self.0.split_first() else {
            return 0;
        };
        self.0 = rest;
        b
    }
    fn i8(&mut self) -> i32 {
        i32::from(self.u8() as i8)
    }
    fn u32(&mut self) -> u32 {
        u32::from_le_bytes([self.u8(), self.u8(), self.u8(), self.u8()])
    }
}

/// The site's latitude (the manifest's), rad, and the Earth's rate, rad/s.
const LATITUDE_RAD: f64 = 52.2 * std::f64::consts::PI / 180.0;
const EARTH_RATE_RAD_S: f64 = 7.292_115e-5;
/// Sample period, s.
const DT_S: f64 = 0.01;

/// A level vehicle driving on a plane as an UNZ-50 would record it: its increments and
/// odometer count carried over from sample to sample (a count is the rounding of the
/// running total, so no rounding accumulates).
struct Vehicle {
    header: FileHeader,
    /// Speed, m/s; heading from north, rad; distance, m.
    speed_mps: f64,
    heading_rad: f64,
    distance_m: f64,
    /// Running totals of the increments (body FRD, rad and m/s) and what was written.
    total: [f64; 6],
    written: [i64; 6],
    /// Pulses added by samples of any counts (op 5).
    pulse_offset: u32,
    /// The recorder's clock, µs: the last sample's time tag (a glitched one aside).
    clock_us: u64,
}

impl Vehicle {
    /// The next sample over `DT_S`: along-track acceleration `accel_mps2` (the speed
    /// stops at zero), yaw rate `yaw_rad_s`, and `dz` counts more along z.
    fn step(&mut self, r: &mut ImuRecord, accel_mps2: f64, yaw_rad_s: f64, dz: i32) {
        let v0 = self.speed_mps;
        let v1 = (v0 + accel_mps2 * DT_S).max(0.0);
        let v_mid = 0.5 * (v0 + v1);
        let (cos_lat, sin_lat) = (LATITUDE_RAD.cos(), LATITUDE_RAD.sin());
        let (sin_h, cos_h) = self.heading_rad.sin_cos();
        let earth_rad_s = [
            EARTH_RATE_RAD_S * cos_lat * cos_h,
            -EARTH_RATE_RAD_S * cos_lat * sin_h,
            -EARTH_RATE_RAD_S * sin_lat,
        ];
        let step = [
            earth_rad_s[0] * DT_S,
            earth_rad_s[1] * DT_S,
            (earth_rad_s[2] + yaw_rad_s) * DT_S,
            v1 - v0,
            v_mid * yaw_rad_s * DT_S,
            -9.81 * DT_S,
        ];
        for k in 0..6 {
            self.total[k] += step[k];
            let lsb = if k < 3 {
                self.header.dtheta_lsb_rad
            } else {
                self.header.dvel_lsb_mps
            };
            let now = (self.total[k] / lsb).round() as i64;
            let count = (now - self.written[k]) as i32;
            self.written[k] = now;
            if k < 3 {
                r.dtheta[k] = count;
            } else {
                r.dvel[k - 3] = count;
            }
        }
        r.dvel[2] = r.dvel[2].saturating_add(dz);
        self.speed_mps = v1;
        self.heading_rad += yaw_rad_s * DT_S;
        self.distance_m += v_mid * DT_S;
        let pulses = (self.distance_m / self.header.odo_lsb_m) as u64 as u32;
        r.odo_count = pulses.wrapping_add(self.pulse_offset);
        r.seq = r.seq.wrapping_add(1);
        self.clock_us = self.clock_us.saturating_add(10_000);
        r.t_us = self.clock_us;
        r.status = 0;
    }
}

/// The records `data` describes, encoded behind an UNZ-50 header.
fn log(data: &[u8]) -> Vec<u8> {
    let header = FileHeader::unz50(1_700_000_000_000_000, "FUZZ");
    let mut w = RawWriter::new(Vec::new(), &header).unwrap();
    let mut vehicle = Vehicle {
        header,
        speed_mps: 0.0,
        heading_rad: 0.0,
        distance_m: 0.0,
        total: [0.0; 6],
        written: [0; 6],
        pulse_offset: 0,
        clock_us: 0,
    };
    let mut r = ImuRecord {
        seq: 0,
        t_us: 0,
        dtheta: [0; 3],
        dvel: [0; 3],
        odo_count: 0,
        status: 0,
    };
    let (mut args, mut samples) = (Args(data), 0usize);
    while !args.0.is_empty() && samples < MAX_SAMPLES {
        match args.u8() % 8 {
            // A run of `n` samples at an along-track acceleration (±2.5 m/s²) and a yaw
            // rate (±0.25 rad/s), z's increments nudged.
            0..=4 => {
                let n = 1 + usize::from(args.u8()) * 8;
                let accel_mps2 = f64::from(args.i8()) * 0.02;
                let yaw_rad_s = f64::from(args.i8()) * 0.002;
                let dz = args.i8() * 64;
                for _ in 0..n.min(MAX_SAMPLES - samples) {
                    vehicle.step(&mut r, accel_mps2, yaw_rad_s, dz);
                    w.write_imu(&r).unwrap();
                    samples += 1;
                }
            }
            // A sample of any counts, step of its time tag (or any tag at all) and status.
            5 => {
                let flags = args.u8();
                r.seq = r.seq.wrapping_add(args.u32() % 4);
                // The clock steps (a pause, a jump back), or this tag alone is any u64 (a
                // glitch: the samples after it go on from the clock).
                let clock = &mut vehicle.clock_us;
                r.t_us = if flags & 1 == 0 {
                    *clock = clock.saturating_add_signed(i64::from(args.i8()) * 5_000);
                    *clock
                } else {
                    u64::from(args.u32()) << 32 | u64::from(args.u32())
                };
                r.dtheta = [args.u32() as i32, args.i8(), args.i8()];
                r.dvel = [args.i8() << 16, args.u32() as i32, r.dvel[2]];
                let jump = args.u32() % 1024;
                vehicle.pulse_offset = vehicle.pulse_offset.wrapping_add(jump);
                r.odo_count = r.odo_count.wrapping_add(jump);
                r.status = u16::from(args.u8() & 7);
                w.write_imu(&r).unwrap();
                samples += 1;
            }
            // A mark of a control point (the manifest's, or another).
            6 => {
                let point_id = u32::from(args.u8() % 3);
                w.write_mark(&MarkRecord {
                    t_us: vehicle.clock_us,
                    point_id,
                })
                .unwrap();
            }
            // Bytes between records: noise, a torn frame.
            _ => {
                let n = usize::from(args.u8() % 64);
                let bytes: Vec<u8> = (0..n).map(|_| args.u8()).collect();
                w.write_raw(&bytes).unwrap();
            }
        }
    }
    w.finish().unwrap()
}

/// Writes the run `data` describes into the scratch folder's `run/`, and empties its
/// `out/`; returns both.
#[allow(dead_code)] // Not every target that shares this module calls it.
pub fn write_run(data: &[u8]) -> (PathBuf, PathBuf) {
    write_run_with(data, MANIFEST.as_bytes())
}

/// [`write_run`] with `manifest` as its `run.toml`, whatever it holds.
pub fn write_run_with(data: &[u8], manifest: &[u8]) -> (PathBuf, PathBuf) {
    let (run, out) = scratch::run_and_out();
    std::fs::write(run.join("run.unz"), log(data)).unwrap();
    std::fs::write(run.join("run.toml"), manifest).unwrap();
    (run, out)
}

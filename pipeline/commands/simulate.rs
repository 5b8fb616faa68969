//! `unz simulate`: write simulated field runs.

use std::process::ExitCode;

use anyhow::bail;
use rayon::prelude::*;
use unz_stages::simulate::{SensorErrors, SimConfig, simulate};

use crate::cli::SimulateArgs;
use crate::simulate_io::{write_faulty_copy, write_run};

/// The configurations `args` asks for.
pub fn configs(args: &SimulateArgs) -> anyhow::Result<Vec<SimConfig>> {
    // Beyond, a right angle of --imu-axes is nearer.
    let max = unz_stages::imu_mounting::MAX_SIMULATED_MOUNTING_DEG;
    for (flag, deg) in [
        ("--odo-boresight-deg", args.odo_boresight_deg),
        ("--odo-pitch-deg", args.odo_pitch_deg),
    ] {
        if deg.is_nan() || deg.abs() > max {
            bail!("{flag} {deg} is not a mounting error (at most {max}°)");
        }
    }
    if args.odo_lag_s.is_nan() || args.odo_lag_s.abs() > 5.0 {
        bail!(
            "--odo-lag-s {} is not an odometer's lag (at most 5 s)",
            args.odo_lag_s
        );
    }
    if args.static_s < 60.0 {
        bail!(
            "--static-s {} is shorter than the 60 s a static start needs",
            args.static_s
        );
    }
    if !(args.duration_s >= args.static_s + 60.0 && args.duration_s <= 12.0 * 3600.0) {
        bail!(
            "--duration-s {} must be between static-s + 60 s and 12 h",
            args.duration_s
        );
    }
    if let Some(s) = args.log_start_s
        && !(s > 0.0 && s < args.duration_s - 60.0)
    {
        bail!(
            "--log-start-s {s} must be after the start and at least 60 s before the end ({} s)",
            args.duration_s
        );
    }
    if args.out_and_back && args.mark_lever_arm_m.is_some() {
        bail!(
            "--out-and-back stops the navigated point over each point both ways: it takes no \
             --mark-lever-arm-m"
        );
    }
    let mut mark_lever_arm_m = [0.0; 3];
    if let Some(arm) = &args.mark_lever_arm_m {
        let Ok(a) = <[f64; 3]>::try_from(arm.as_slice()) else {
            bail!("--mark-lever-arm-m {arm:?} must be three numbers x,y,z");
        };
        mark_lever_arm_m = a;
        // The range the manifest's `[params.vehicle]` is held to.
        crate::config::validate(&crate::flow::Params {
            vehicle: crate::flow::VehicleParams {
                mark_lever_arm_m,
                ..Default::default()
            },
            ..Default::default()
        })
        .map_err(|e| anyhow::anyhow!("--mark-lever-arm-m: {e}"))?;
    }
    Ok((0..args.runs)
        .map(|i| {
            let seed = args.seed + u64::from(i);
            let mut c = SimConfig::new(&format!("sim-{seed:04}"), seed);
            c.duration_s = args.duration_s;
            c.static_s = args.static_s;
            c.azimuth_error_deg = args.azimuth_error_deg;
            c.odo_boresight_deg = args.odo_boresight_deg;
            c.odo_pitch_deg = args.odo_pitch_deg;
            c.odo_lag_s = args.odo_lag_s;
            c.cp_at_every_stop = args.cp_at_every_stop;
            c.log_start_s = args.log_start_s;
            c.mark_lever_arm_m = mark_lever_arm_m;
            c.out_and_back = args.out_and_back;
            c.imu_axes = args.imu_axes;
            c.errors = SensorErrors {
                noise: !args.no_noise,
                gyro_drift: !args.no_gyro_drift,
                accel_bias: !args.no_accel_bias,
                odo_scale_error: !args.no_odo_scale_error,
            };
            c
        })
        .collect())
}

/// Runs the command.
pub fn run(args: &SimulateArgs) -> anyhow::Result<ExitCode> {
    let configs = configs(args)?;
    std::fs::create_dir_all(&args.out)?;
    let written: Vec<anyhow::Result<Vec<std::path::PathBuf>>> = configs
        .par_iter()
        .map(|c| {
            let run = simulate(c);
            let mut dirs = vec![write_run(&run, &args.out)?];
            if args.faults {
                dirs.push(write_faulty_copy(&run, &args.out)?);
            }
            Ok(dirs)
        })
        .collect();
    for w in written {
        for d in w? {
            println!("{}", d.display());
        }
    }
    Ok(ExitCode::SUCCESS)
}

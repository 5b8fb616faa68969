//! Writing simulated runs: `run.toml`, `<name>.unz`, `truth.parquet` (with the true
//! settings in its metadata and in `truth.json`), and with faults a damaged copy.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use anyhow::Context;
use arrow::array::{Float64Array, Int64Array, RecordBatch};
use unz_formats::atomic::{write_atomic, write_json_atomic};
use unz_formats::parquet_io::write_batch;
use unz_formats::raw::{FileHeader, ImuRecord, MarkRecord, RawLog};
use unz_formats::{schema, tables};
use unz_stages::earth;
use unz_stages::simulate::{SensorSpec, SimRun};

/// What the simulator makes of a configuration changes when its code does: bump this with
/// it, so that [`simulated_before`] does not trust runs of an older simulator.
const SIMULATOR_VERSION: u32 = 3;

/// The marker written last into a simulated run's folder: which configuration made it.
const MARKER: &str = "simulated.json";

/// The marker's content for `config` (written as the file's only line).
fn marker_of(config: &unz_stages::simulate::SimConfig, faulty: bool) -> String {
    serde_json::json!({
        "simulator": SIMULATOR_VERSION,
        "config": format!("{config:?}"),
        "faulty": faulty,
    })
    .to_string()
}

/// The run folder `dir/<name>/` if it already holds what `config` simulates (its marker,
/// written after every other file, says so); otherwise `None`.
pub fn simulated_before(
    config: &unz_stages::simulate::SimConfig,
    faulty: bool,
    dir: &Path,
) -> Option<PathBuf> {
    let name = if faulty {
        format!("{}-faulty", config.name)
    } else {
        config.name.clone()
    };
    let run_dir = dir.join(name);
    let marker = std::fs::read_to_string(run_dir.join(MARKER)).ok()?;
    (marker == marker_of(config, faulty)).then_some(run_dir)
}

/// Records in `run_dir` that it holds what `config` simulates (call after every file).
fn mark_simulated(run: &SimRun, faulty: bool, run_dir: &Path) -> anyhow::Result<()> {
    write_atomic(
        &run_dir.join(MARKER),
        marker_of(&run.config, faulty).as_bytes(),
    )?;
    Ok(())
}

/// A run simulated with `seed` over `duration_s` into `dir/<name>/`, to be processed into
/// `dir/out` (what the benchmarks and the stages' own tests run on).
pub fn simulated_ctx(
    dir: &Path,
    name: &str,
    seed: u64,
    duration_s: f64,
) -> anyhow::Result<crate::flow::RunCtx> {
    let mut config = unz_stages::simulate::SimConfig::new(name, seed);
    config.duration_s = duration_s;
    let run_dir = write_run(&unz_stages::simulate::simulate(&config), dir)?;
    Ok(crate::flow::RunCtx::new(
        crate::runs::load_run(&run_dir)?,
        dir.join("out"),
        false,
    ))
}

/// Writes one simulated run into `dir/<name>/`; returns the run folder.
pub fn write_run(run: &SimRun, dir: &Path) -> anyhow::Result<PathBuf> {
    let name = &run.config.name;
    let run_dir = dir.join(name);
    std::fs::create_dir_all(&run_dir)
        .with_context(|| format!("cannot create {}", run_dir.display()))?;
    let raw_name = format!("{name}.unz");
    write_atomic(&run_dir.join(&raw_name), &raw_log(run).encode())?;
    write_truth(run, &run_dir)?;
    write_atomic(
        &run_dir.join("run.toml"),
        run.manifest_toml(name, &raw_name).as_bytes(),
    )?;
    mark_simulated(run, false, &run_dir)?;
    Ok(run_dir)
}

/// Writes the damaged copy `dir/<name>-faulty/` with `expected_ingest.json`.
pub fn write_faulty_copy(run: &SimRun, dir: &Path) -> anyhow::Result<PathBuf> {
    let name = format!("{}-faulty", run.config.name);
    let run_dir = dir.join(&name);
    std::fs::create_dir_all(&run_dir)
        .with_context(|| format!("cannot create {}", run_dir.display()))?;
    let damaged = raw_log(run).damage(run.config.seed);
    let raw_name = format!("{name}.unz");
    write_atomic(&run_dir.join(&raw_name), &damaged.bytes)?;
    write_json_atomic(&run_dir.join("expected_ingest.json"), &damaged.expected)?;
    write_truth(run, &run_dir)?;
    write_atomic(
        &run_dir.join("run.toml"),
        run.manifest_toml(&name, &raw_name).as_bytes(),
    )?;
    mark_simulated(run, true, &run_dir)?;
    Ok(run_dir)
}

/// The raw header stating the simulated device's timing and scales.
pub fn raw_header(s: &SensorSpec) -> FileHeader {
    FileHeader {
        sample_period_us: s.sample_period_us,
        start_time_us: s.start_time_us,
        dtheta_lsb_rad: s.dtheta_lsb_rad,
        dvel_lsb_mps: s.dvel_lsb_mps,
        odo_lsb_m: s.odo_lsb_m,
        device_serial: s.serial.clone(),
        ..FileHeader::unz50(s.start_time_us, &s.serial)
    }
}

/// The simulated run as a raw log (header, records and marks in the format's types).
pub fn raw_log(run: &SimRun) -> RawLog {
    RawLog {
        header: raw_header(&run.sensor),
        records: run
            .records
            .iter()
            .map(|r| ImuRecord {
                seq: r.seq,
                t_us: r.t_us,
                dtheta: r.dtheta_counts,
                dvel: r.dvel_counts,
                odo_count: r.odo_count,
                status: r.status,
            })
            .collect(),
        marks: run
            .marks
            .iter()
            .map(|(k, m)| {
                (
                    *k,
                    MarkRecord {
                        t_us: m.t_us,
                        point_id: m.point_id,
                    },
                )
            })
            .collect(),
    }
}

fn write_truth(run: &SimRun, run_dir: &Path) -> anyhow::Result<()> {
    let settings_json = serde_json::to_string(&run.settings)?;
    let t = &run.truth;
    let origin = run.sensor.start_time_us.checked_mul(1000);
    let sch = schema::truth(origin, &settings_json);
    let deg = |v: &[f64]| {
        Arc::new(Float64Array::from(
            v.iter().map(|x| x.to_degrees()).collect::<Vec<_>>(),
        ))
    };
    let (lat0, lon0) = (run.site.lat_rad, run.site.lon_rad);
    let (north, east): (Vec<f64>, Vec<f64>) = t
        .lat_rad
        .iter()
        .zip(&t.lon_rad)
        .map(|(&la, &lo)| earth::local_offset_m(la, lo, lat0, lon0, run.site.h_m))
        .unzip();
    let batch = RecordBatch::try_new(
        sch,
        vec![
            Arc::new(Int64Array::from(t.t_ns.clone())),
            deg(&t.lat_rad),
            deg(&t.lon_rad),
            Arc::new(Float64Array::from(t.h_m.clone())),
            tables::vec3_to_array(&t.vel_ned_mps),
            Arc::new(Float64Array::from(
                t.euler
                    .iter()
                    .map(|e| e.roll_rad.to_degrees())
                    .collect::<Vec<_>>(),
            )),
            Arc::new(Float64Array::from(
                t.euler
                    .iter()
                    .map(|e| e.pitch_rad.to_degrees())
                    .collect::<Vec<_>>(),
            )),
            Arc::new(Float64Array::from(
                t.euler
                    .iter()
                    .map(|e| e.heading_rad.to_degrees())
                    .collect::<Vec<_>>(),
            )),
            Arc::new(Float64Array::from(t.distance_m.clone())),
            Arc::new(Float64Array::from(north)),
            Arc::new(Float64Array::from(east)),
        ],
    )?;
    write_batch(&run_dir.join("truth.parquet"), &batch)?;
    write_json_atomic(&run_dir.join("truth.json"), &run.settings)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use unz_stages::simulate::{SimConfig, simulate};

    #[test]
    fn a_run_is_reused_only_for_the_configuration_that_made_it() {
        let tmp = tempfile::tempdir().unwrap();
        let mut config = SimConfig::new("reuse", 5);
        config.duration_s = 160.0;
        assert_eq!(simulated_before(&config, false, tmp.path()), None);
        let run_dir = write_run(&simulate(&config), tmp.path()).unwrap();
        assert_eq!(
            simulated_before(&config, false, tmp.path()),
            Some(run_dir.clone())
        );
        // Another configuration, or the damaged copy, is not what is there.
        let mut other = config.clone();
        other.azimuth_error_deg = Some(3.0);
        assert_eq!(simulated_before(&other, false, tmp.path()), None);
        assert_eq!(simulated_before(&config, true, tmp.path()), None);
        // Without the marker (a write cut short) nothing is trusted.
        std::fs::remove_file(run_dir.join(MARKER)).unwrap();
        assert_eq!(simulated_before(&config, false, tmp.path()), None);
    }
}

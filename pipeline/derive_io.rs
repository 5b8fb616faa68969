//! Parquet form of the derive stage's outputs: `derived.parquet` (per IMU sample) and
//! `epochs.parquet` (per ΔTg epoch), and loading them back.

use crate::artifacts::files;
use std::path::Path;
use std::sync::Arc;

use anyhow::{Context, bail};
use arrow::array::{AsArray, BooleanArray, Float64Array, Int64Array, RecordBatch, UInt64Array};
use arrow::datatypes::{DataType, Field, Schema, UInt64Type};
use unz_formats::parquet_io::{read_table, write_batch};
use unz_formats::schema::{FRAME_BODY, scalar, vec3};
use unz_formats::tables::{f64_column, i64_column, vec3_column, vec3_to_array};
use unz_stages::derive::{Derived, Epochs};

/// Metadata key: samples per block of the filter F.
const META_BLOCK: &str = "unz.block";
/// Metadata key: nominal sample period, s.
const META_NOMINAL_DT: &str = "unz.nominal_dt_s";
/// Metadata key: samples whose time tag derive repaired.
const META_REPAIRED_TIMES: &str = "unz.repaired_times";
/// Metadata key: samples that closed a gap and were scaled to it.
const META_FILLED_GAPS: &str = "unz.filled_gaps";
/// Metadata key: samples flagged with an IMU failure.
const META_IMU_FAILURES: &str = "unz.imu_failure_samples";
/// Metadata key: samples flagged with an odometer failure.
const META_ODO_FAILURES: &str = "unz.odometer_failure_samples";

fn f64s(v: &[f64]) -> Arc<Float64Array> {
    Arc::new(Float64Array::from(v.to_vec()))
}

/// Writes `derived.parquet` and `epochs.parquet` into `dir`.
pub fn write_derived(d: &Derived, dir: &Path) -> anyhow::Result<()> {
    let f = |n: &str, unit: &str| scalar(n, DataType::Float64, false, unit);
    let meta = std::collections::HashMap::from([
        (META_BLOCK.to_owned(), d.block.to_string()),
        (META_NOMINAL_DT.to_owned(), d.nominal_dt_s.to_string()),
        (META_REPAIRED_TIMES.to_owned(), d.repaired_times.to_string()),
        (META_FILLED_GAPS.to_owned(), d.filled_gaps.to_string()),
        (
            META_IMU_FAILURES.to_owned(),
            d.imu_failure_samples.to_string(),
        ),
        (
            META_ODO_FAILURES.to_owned(),
            d.odometer_failure_samples.to_string(),
        ),
        ("unz.table".to_owned(), "derived".to_owned()),
    ]);
    let schema = Arc::new(Schema::new_with_metadata(
        vec![
            scalar("t_ns", DataType::Int64, false, "ns"),
            f("dt_s", "s"),
            vec3("dtheta_rad", "rad", FRAME_BODY),
            vec3("dvel_mps", "m/s", FRAME_BODY),
            f("odo_dist_m", "m"),
            f("u_mps", "m/s"),
            f("u_dot_mps2", "m/s^2"),
            f("r_rad_s", "rad/s"),
            f("ru_mps2", "m/s^2"),
        ],
        meta,
    ));
    let t_ns: Vec<i64> = d.t_ns();
    let batch = RecordBatch::try_new(
        schema,
        vec![
            Arc::new(Int64Array::from(t_ns)),
            f64s(&d.dt_s),
            vec3_to_array(&d.dtheta_rad),
            vec3_to_array(&d.dvel_mps),
            f64s(&d.odo_dist_m),
            f64s(&d.u_mps),
            f64s(&d.u_dot_mps2),
            f64s(&d.r_rad_s),
            f64s(&d.ru_mps2),
        ],
    )?;
    write_batch(&dir.join(files::DERIVED), &batch)?;

    let e = &d.epochs;
    let at = |v: &[f64]| f64s(&e.block.iter().map(|&j| v[j]).collect::<Vec<_>>());
    let schema = Arc::new(Schema::new_with_metadata(
        vec![
            scalar("t_ns", DataType::Int64, false, "ns"),
            scalar("block", DataType::UInt64, false, "1"),
            f("theta_p_rad", "rad"),
            f("phi_p_rad", "rad"),
            f("theta_p_per_yaw", "rad/rad"),
            f("phi_p_per_yaw", "rad/rad"),
            f("theta_p_per_bias", "rad/(m/s)"),
            f("phi_p_per_bias", "rad/(m/s)"),
            Field::new("valid", DataType::Boolean, false),
            f("ax_f_mps2", "m/s^2"),
            f("ay_f_mps2", "m/s^2"),
            f("u_dot_f_mps2", "m/s^2"),
            f("ru_f_mps2", "m/s^2"),
        ],
        std::collections::HashMap::from([("unz.table".to_owned(), "epochs".to_owned())]),
    ));
    let batch = RecordBatch::try_new(
        schema,
        vec![
            Arc::new(Int64Array::from(d.epoch_t_ns())),
            Arc::new(UInt64Array::from(
                e.block.iter().map(|&b| b as u64).collect::<Vec<_>>(),
            )),
            f64s(&e.theta_p_rad),
            f64s(&e.phi_p_rad),
            f64s(&e.theta_p_per_yaw),
            f64s(&e.phi_p_per_yaw),
            f64s(&e.theta_p_per_bias),
            f64s(&e.phi_p_per_bias),
            Arc::new(BooleanArray::from(e.valid.clone())),
            at(&d.ax_f),
            at(&d.ay_f),
            at(&d.u_dot_f),
            at(&d.ru_f),
        ],
    )?;
    write_batch(&dir.join(files::EPOCHS), &batch)?;
    Ok(())
}

/// Loads what [`write_derived`] wrote, counts included (the per-block filtered series
/// are not kept).
pub fn load_derived(dir: &Path) -> anyhow::Result<Derived> {
    let path = dir.join(files::DERIVED);
    let (schema, b) = read_table(&path)?;
    let meta = |k: &str| -> anyhow::Result<String> {
        schema
            .metadata()
            .get(k)
            .cloned()
            .with_context(|| format!("{} lacks metadata {k}", path.display()))
    };
    let t_ns = i64_column(&b, "t_ns")?;
    let t0_ns = t_ns.first().copied().unwrap_or(0);
    let mut d = Derived {
        t0_ns,
        nominal_dt_s: meta(META_NOMINAL_DT)?.parse()?,
        t_s: t_ns.iter().map(|t| (t - t0_ns) as f64 * 1e-9).collect(),
        dt_s: f64_column(&b, "dt_s")?,
        dtheta_rad: vec3_column(&b, "dtheta_rad")?,
        dvel_mps: vec3_column(&b, "dvel_mps")?,
        odo_dist_m: f64_column(&b, "odo_dist_m")?,
        u_mps: f64_column(&b, "u_mps")?,
        u_dot_mps2: f64_column(&b, "u_dot_mps2")?,
        r_rad_s: f64_column(&b, "r_rad_s")?,
        ru_mps2: f64_column(&b, "ru_mps2")?,
        block: meta(META_BLOCK)?.parse()?,
        repaired_times: meta(META_REPAIRED_TIMES)?.parse()?,
        filled_gaps: meta(META_FILLED_GAPS)?.parse()?,
        imu_failure_samples: meta(META_IMU_FAILURES)?.parse()?,
        odometer_failure_samples: meta(META_ODO_FAILURES)?.parse()?,
        // The per-block filtered series are not stored: their values at the epochs are
        // in epochs.parquet, and nothing downstream reads the rest.
        ..Derived::default()
    };
    let epath = dir.join(files::EPOCHS);
    let (_, e) = read_table(&epath)?;
    let blocks = e
        .column_by_name("block")
        .and_then(|c| c.as_primitive_opt::<UInt64Type>())
        .context("epochs.parquet: block")?;
    let valid = e
        .column_by_name("valid")
        .and_then(|c| c.as_boolean_opt())
        .context("epochs.parquet: valid")?;
    d.epochs = Epochs {
        block: blocks.values().iter().map(|&b| b as usize).collect(),
        t_s: i64_column(&e, "t_ns")?
            .iter()
            .map(|t| (t - t0_ns) as f64 * 1e-9)
            .collect(),
        theta_p_rad: f64_column(&e, "theta_p_rad")?,
        phi_p_rad: f64_column(&e, "phi_p_rad")?,
        theta_p_per_yaw: f64_column(&e, "theta_p_per_yaw")?,
        phi_p_per_yaw: f64_column(&e, "phi_p_per_yaw")?,
        theta_p_per_bias: f64_column(&e, "theta_p_per_bias")?,
        phi_p_per_bias: f64_column(&e, "phi_p_per_bias")?,
        valid: (0..valid.len()).map(|i| valid.value(i)).collect(),
    };
    let n_blocks = d.t_s.len().div_ceil(d.block.max(1));
    if d.epochs.block.iter().any(|&j| j >= n_blocks) {
        bail!("{}: epoch block beyond the samples", epath.display());
    }
    Ok(d)
}

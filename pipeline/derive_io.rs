//! Parquet form of the derive stage's outputs: `derived.parquet` (per IMU sample) and
//! `epochs.parquet` (per ΔTg epoch), and loading them back.

use crate::artifacts::files;
use std::path::Path;
use std::sync::Arc;

use anyhow::{Context, bail};
use arrow::array::{AsArray, BooleanArray, Float64Array, Int64Array, RecordBatch, UInt64Array};
use arrow::datatypes::UInt64Type;
use unz_formats::parquet_io::{read_table, write_batch};
use unz_formats::schema::{self, derived_meta};
use unz_formats::tables::{f64_column, i64_column, vec3_column, vec3_to_array};
use unz_stages::derive::{Derived, Epochs};

fn f64s(v: &[f64]) -> Arc<Float64Array> {
    Arc::new(Float64Array::from(v.to_vec()))
}

/// Writes `derived.parquet` and `epochs.parquet` into `dir`.
pub fn write_derived(d: &Derived, dir: &Path) -> anyhow::Result<()> {
    let schema = schema::derived([
        (derived_meta::BLOCK, d.block.to_string()),
        (derived_meta::NOMINAL_DT_S, d.nominal_dt_s.to_string()),
        (derived_meta::REPAIRED_TIMES, d.repaired_times.to_string()),
        (derived_meta::FILLED_GAPS, d.filled_gaps.to_string()),
        (
            derived_meta::IMU_FAILURES,
            d.imu_failure_samples.to_string(),
        ),
        (
            derived_meta::ODO_FAILURES,
            d.odometer_failure_samples.to_string(),
        ),
        (
            derived_meta::OUT_OF_RANGE,
            d.out_of_range_samples.to_string(),
        ),
    ]);
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
    let schema = schema::epochs();
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
        nominal_dt_s: meta(derived_meta::NOMINAL_DT_S)?.parse()?,
        t_s: t_ns.iter().map(|t| (t - t0_ns) as f64 * 1e-9).collect(),
        dt_s: f64_column(&b, "dt_s")?,
        dtheta_rad: vec3_column(&b, "dtheta_rad")?,
        dvel_mps: vec3_column(&b, "dvel_mps")?,
        odo_dist_m: f64_column(&b, "odo_dist_m")?,
        u_mps: f64_column(&b, "u_mps")?,
        u_dot_mps2: f64_column(&b, "u_dot_mps2")?,
        r_rad_s: f64_column(&b, "r_rad_s")?,
        ru_mps2: f64_column(&b, "ru_mps2")?,
        block: meta(derived_meta::BLOCK)?.parse()?,
        repaired_times: meta(derived_meta::REPAIRED_TIMES)?.parse()?,
        filled_gaps: meta(derived_meta::FILLED_GAPS)?.parse()?,
        imu_failure_samples: meta(derived_meta::IMU_FAILURES)?.parse()?,
        out_of_range_samples: meta(derived_meta::OUT_OF_RANGE)?.parse()?,
        odometer_failure_samples: meta(derived_meta::ODO_FAILURES)?.parse()?,
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

//! Sensitivity maps (the paper's Figs 2–6): Kryt1 and Kryt2 over a grid of one or two
//! components of the initial settings, evaluated in parallel → `sweep.parquet`.

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::AtomicUsize;

use anyhow::{Context, bail};
use arrow::array::{Float64Array, RecordBatch};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use unz_formats::atomic::write_json_atomic;
use unz_formats::parquet_io::write_batch;
use unz_formats::schema;
use unz_stages::disupt::{Problem, X};
use unz_stages::linearized::Setting;
use unz_stages::units::DEG_PER_H;

use crate::artifacts::StageName;
use crate::disupt_stage::{case_inputs, problem_of};
use crate::flow::{Overrides, Params, RunCtx, load_case};
use crate::stage::{Stage, params_hash};

/// Largest grid evaluated (points).
pub const MAX_POINTS: usize = 250_000;

/// One swept component: `name=from:to:count`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Axis {
    /// `azimuth_deg`, `drift_x_rad_s`, `drift_y_rad_s`, `drift_z_rad_s`, `odo_scale` or
    /// `odo_yaw_deg`.
    pub name: String,
    /// First value.
    pub from: f64,
    /// Last value.
    pub to: f64,
    /// Number of values (≥ 1).
    pub count: usize,
}

/// The settings a sweep can move, by the name and unit it takes them in, with what turns
/// a value into the optimisers' unit.
type ToOptimiser = fn(f64) -> f64;

const SWEEPABLE: [(&str, Setting, ToOptimiser); 6] = [
    ("azimuth_deg", Setting::Azimuth, |v| v),
    ("drift_x_rad_s", Setting::DriftX, |v| v / DEG_PER_H),
    ("drift_y_rad_s", Setting::DriftY, |v| v / DEG_PER_H),
    ("drift_z_rad_s", Setting::DriftZ, |v| v / DEG_PER_H),
    ("odo_scale", Setting::OdoScale, |v| (v - 1.0) * 1e6),
    ("odo_yaw_deg", Setting::OdoYaw, |v| v),
];

/// The setting a sweep name stands for and its conversion (names are checked by
/// [`parse_over`]).
fn sweepable(name: &str) -> Option<(Setting, ToOptimiser)> {
    SWEEPABLE
        .iter()
        .find(|(n, _, _)| *n == name)
        .map(|&(_, s, f)| (s, f))
}

impl Axis {
    fn values(&self) -> Vec<f64> {
        if self.count == 1 {
            return vec![self.from];
        }
        (0..self.count)
            .map(|i| self.from + (self.to - self.from) * i as f64 / (self.count - 1) as f64)
            .collect()
    }

    fn apply(&self, x: &mut X, v: f64) {
        if let Some((setting, to_optimiser)) = sweepable(&self.name) {
            x.set(setting, to_optimiser(v));
        }
    }
}

/// Parses `--over`: one or two `name=from:to:count`, comma-separated.
pub fn parse_over(spec: &str) -> anyhow::Result<Vec<Axis>> {
    let axes = spec
        .split(',')
        .map(|part| {
            let (name, range) = part
                .split_once('=')
                .with_context(|| format!("{part:?}: expected name=from:to:count"))?;
            if sweepable(name).is_none() {
                let names: Vec<&str> = SWEEPABLE.iter().map(|s| s.0).collect();
                bail!("{name:?} is not a setting; one of {}", names.join(", "));
            }
            let f: Vec<&str> = range.split(':').collect();
            let [from, to, count] = f[..] else {
                bail!("{part:?}: expected name=from:to:count")
            };
            let (from, to): (f64, f64) = (from.parse()?, to.parse()?);
            let count: usize = count.parse()?;
            if !(from.is_finite() && to.is_finite()) || count == 0 {
                bail!("{part:?}: finite bounds and at least one value");
            }
            Ok(Axis {
                name: name.to_owned(),
                from,
                to,
                count,
            })
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    if axes.is_empty() || axes.len() > 2 || (axes.len() == 2 && axes[0].name == axes[1].name) {
        bail!("--over takes one or two different settings");
    }
    if axes.iter().map(|a| a.count).product::<usize>() > MAX_POINTS {
        bail!("the grid has more than {MAX_POINTS} points");
    }
    Ok(axes)
}

/// `sweep.json`.
#[derive(Debug, Serialize)]
struct SweepSummary<'a> {
    axes: &'a [Axis],
    points: usize,
    passes: usize,
    min_kryt1: Option<Vec<f64>>,
    min_kryt2: Option<Vec<f64>>,
}

/// One point of a sweep.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GridPoint {
    /// Values of the first and second axis (NaN without a second axis).
    pub at: (f64, f64),
    /// Kryt1, rad.
    pub kryt1_rad: f64,
    /// RMS Kryt2 over the control points, m.
    pub kryt2_m: f64,
}

/// The grid of `axes` around the problem's base settings (the first axis varying
/// slowest) with the criteria at each point: exact passes, many side by side in vector
/// lanes, in parallel.
pub fn evaluate_grid(problem: &Problem<'_>, axes: &[Axis]) -> Vec<GridPoint> {
    let x0 = problem.x0();
    let a = axes[0].values();
    let b = axes.get(1).map_or(vec![f64::NAN], Axis::values);
    let grid: Vec<(f64, f64)> = a
        .iter()
        .flat_map(|&u| b.iter().map(move |&v| (u, v)))
        .collect();
    let xs: Vec<X> = grid
        .iter()
        .map(|&(u, v)| {
            let mut x = x0;
            axes[0].apply(&mut x, u);
            if let Some(ax) = axes.get(1) {
                ax.apply(&mut x, v);
            }
            x
        })
        .collect();
    problem
        .observe_many_by(&xs, &AtomicUsize::new(0))
        .par_iter()
        .zip(grid)
        .map(|(y, at)| {
            let e = problem.evaluation_of(y);
            GridPoint {
                at,
                kryt1_rad: e.kryt1,
                kryt2_m: e.kryt2_rms(),
            }
        })
        .collect()
}

/// Runs the sweep (cached like a stage).
pub fn ensure_sweep(ctx: &RunCtx, params: &Params, axes: &[Axis]) -> anyhow::Result<PathBuf> {
    let inputs = case_inputs(ctx, params)?;
    let dir = ctx.layout().create(StageName::Sweep)?;
    let stage = Stage {
        dir: dir.clone(),
        name: "sweep",
        // 2: a mounted unit's manifest angles and drifts are turned into the body's.
        // 3: a static start given past the odometer's first sign of motion is cut there.
        version: 3,
        params_hash: params_hash(&(params.before_export(), axes))?,
        inputs,
        outputs: &["sweep.parquet", "sweep.json"],
        hashed_as_read: vec![],
    };
    ctx.run_stage(&stage, || {
        let t0 = std::time::Instant::now();
        let case = load_case(ctx, params, &Overrides::default())?;
        let problem = problem_of(&case, params);
        let grid = evaluate_grid(&problem, axes);
        let column = |f: fn(&GridPoint) -> f64| -> Arc<dyn arrow::array::Array> {
            Arc::new(Float64Array::from(grid.iter().map(f).collect::<Vec<_>>()))
        };
        let mut columns = vec![column(|g| g.at.0)];
        if axes.len() > 1 {
            columns.push(column(|g| g.at.1));
        }
        columns.push(column(|g| g.kryt1_rad));
        columns.push(column(|g| g.kryt2_m));
        let names: Vec<&str> = axes.iter().map(|a| a.name.as_str()).collect();
        let batch = RecordBatch::try_new(schema::sweep(&names), columns)?;
        write_batch(&dir.join("sweep.parquet"), &batch)?;
        let argmin = |f: fn(&GridPoint) -> f64| {
            grid.iter()
                .filter(|g| f(g).is_finite())
                .min_by(|x, y| f(x).total_cmp(&f(y)))
                .map(|g| [g.at.0, g.at.1].into_iter().take(axes.len()).collect())
        };
        ctx.say(
            "sweep",
            &format!(
                "{} points in {:.2} s",
                grid.len(),
                t0.elapsed().as_secs_f64()
            ),
        );
        write_json_atomic(
            &dir.join("sweep.json"),
            &SweepSummary {
                axes,
                points: grid.len(),
                passes: problem.passes(),
                min_kryt1: argmin(|g| g.kryt1_rad),
                min_kryt2: argmin(|g| g.kryt2_m),
            },
        )?;
        Ok(())
    })?;
    Ok(dir)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn over_specs_parse_and_bad_ones_are_refused() {
        let a = parse_over("azimuth_deg=100:120:41,drift_z_rad_s=-5e-6:5e-6:41").unwrap();
        assert_eq!(a.len(), 2);
        assert_eq!(a[1].values()[20], 0.0);
        let yaw = parse_over("odo_yaw_deg=-1:1:5").unwrap();
        let mut x = X::default();
        yaw[0].apply(&mut x, yaw[0].values()[3]);
        assert_eq!(x.odo_yaw_deg, 0.5);
        for bad in [
            "azimuth=1:2:3",
            "azimuth_deg=1:2",
            "azimuth_deg=1:2:0",
            "azimuth_deg=1:2:3,azimuth_deg=1:2:3",
            "azimuth_deg=1:2:1000,drift_z_rad_s=0:1:1000",
        ] {
            assert!(parse_over(bad).is_err(), "{bad}");
        }
    }
}

#!/usr/bin/env python3
"""How well the joint fit's σ covers the truth, over simulated runs, as binary logs and as
the same runs written as text logs with an OBD-like speed file.

Simulates `--runs` runs (`unz simulate --seed S --runs N`), runs every stage on them, then
writes each one again as a KF-GINS text log (its ingested IMU increments, 7 columns, the
same time base shifted to seconds of week) with its odometer as a speed file of one
line every `--speed-period-s` (the mean speed over the interval before the tag, as an
OBD-II logger's), its control points timed by its marks, and runs those. For each run
and form it prints the joint fit's azimuth and drifts less the truth's, in units of the
fit's σ (z), and the RMS of those z over the runs: about 1 where the σ are honest.

Session 86 (five runs from seed 51, 40 minutes): binary RMS z 2.22, text with a 1-Hz
speed file 5.84 (one azimuth 8.8σ off). Session 87, with the gyros' angle random walk
and the odometer lag's uncertainty in the covariance: 0.47 and 0.88, none beyond 2σ;
`--instant` 0.75, was 6.16 (the test
`joint_sigma_covers_the_truth_over_seeds_binary_and_text` checks the first two in Rust).
It also prints the corrected route's errors in units of its σ columns (every second past
the static start). Session 89, with the heading walk weighed once in the route's σ
(north, east, heading RMS z): binary 0.31, 0.36, 0.40 (were 0.29, 0.19, 0.31), text
0.72, 0.96, 1.01 (were 0.57, 0.63, 0.80); with `--config` setting `[disupt]
position_sigma_m = 0.1` binary 0.62, 0.77, 0.75 and text 1.58, 1.70, 1.64.
Not a test: a study for the joint fit's covariance, with the `--instant` and
`--speed-period-s` variants the test does not run.
Needs pyarrow and numpy (the test venv, `.venv/bin/python`, has them).
"""

import argparse
import json
import math
import os
import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq

# Seconds of GPS week at the run's time origin (a text log's tags).
T0_S = 100000.0


def as_text_run(run: Path, ingest: Path, dst: Path, speed_period_s: float, instant: bool) -> None:
    """`run` (a simulated binary run, `ingest` its ingest stage's folder) as a text run in
    `dst`: its speeds the odometer's mean over each interval, or (`instant`) the vehicle's
    speed at each tag as the odometer reads it (the truth's, over its scale error)."""
    name = run.name
    shutil.rmtree(dst, ignore_errors=True)
    dst.mkdir(parents=True)
    imu = pq.read_table(ingest / "imu.parquet", columns=["t_ns", "dtheta_rad", "dvel_mps"]).to_pydict()
    odo = pq.read_table(ingest / "odometer.parquet", columns=["t_ns", "distance_m"]).to_pydict()
    marks = pq.read_table(ingest / "marks.parquet").to_pydict()
    with open(dst / "imu.txt", "w") as f:
        for t, th, dv in zip(imu["t_ns"], imu["dtheta_rad"], imu["dvel_mps"]):
            f.write("%.3f %.12e %.12e %.12e %.12e %.12e %.12e\n" % (T0_S + t * 1e-9, *th, *dv))
    t_s = np.array(odo["t_ns"]) * 1e-9
    dist_m = np.array(odo["distance_m"])
    step = max(1, round(speed_period_s / float(np.median(np.diff(t_s)))))
    truth = pq.read_table(run / "truth.parquet", columns=["t_ns", "vel_ned_mps"]).to_pydict()
    meta = json.loads(pq.read_table(run / "truth.parquet").schema.metadata[b"unz.true_settings"])
    reads = meta["nominal_odo_m_per_pulse"] / meta["odo_scale_m_per_pulse"]
    truth_t_s = np.array(truth["t_ns"]) * 1e-9
    truth_speed = np.array([math.hypot(v[0], v[1]) for v in truth["vel_ned_mps"]])
    with open(dst / "odometer.txt", "w") as f:
        for j in range(step, len(t_s), step):
            if instant:
                speed = reads * float(np.interp(t_s[j], truth_t_s, truth_speed))
            else:
                speed = (dist_m[j] - dist_m[j - step]) / (t_s[j] - t_s[j - step])
            f.write("%.3f %.4f\n" % (T0_S + t_s[j], speed))
    manifest = (run / "run.toml").read_text()
    binary = f'raw = "{name}.unz"\nformat = "unz-binary"'
    if binary not in manifest:
        raise SystemExit(f"{run / 'run.toml'}: not a simulated binary run's manifest")
    manifest = manifest.replace(binary, 'raw = "imu.txt"\nformat = "kf-gins"')
    manifest += '\n[odometer]\nfile = "odometer.txt"\nkind = "speed_mps"\n'
    for point, t_ns in zip(marks["point_id"], marks["t_ns"]):
        manifest = manifest.replace(f"id = {point}\n", f"id = {point}\nt_s = {T0_S + t_ns * 1e-9:.3f}\n", 1)
    (dst / "run.toml").write_text(manifest)
    shutil.copy(run / "truth.parquet", dst / "truth.parquet")


def z_scores(runs: Path, out: Path) -> list[tuple[str, list[float], float]]:
    """Per run: (name, z of azimuth and drifts x, y, z, azimuth error in degrees)."""
    rows = []
    for run in sorted(p for p in runs.iterdir() if (p / "truth.parquet").exists()):
        meta = json.loads(pq.read_table(run / "truth.parquet").schema.metadata[b"unz.true_settings"])
        d = json.loads((out / run.name / "disupt" / "disupt.json").read_text())
        x = d["methods"]["joint"]["x"]
        s = x["sigma"]
        az_deg = x["azimuth_deg"] - meta["azimuth_deg"]
        z = [az_deg / s["azimuth_deg"]]
        z += [(x["drift_rad_s"][i] - meta["drift_rad_s"][i]) / s["drift_rad_s"][i] for i in range(3)]
        rows.append((run.name, z, az_deg))
    return rows


def route_z(runs: Path, out: Path) -> list[np.ndarray]:
    """The corrected route's errors against the truth in units of its σ columns, every
    second where the σ are above 1 cm and 0.001° (the static start's are micrometres):
    north, east and heading, over the runs."""
    z: list[list[float]] = [[], [], []]
    for run in sorted(p for p in runs.iterdir() if (p / "truth.parquet").exists()):
        nav = pq.read_table(out / run.name / "disupt" / "corrected_nav.parquet").to_pydict()
        truth = pq.read_table(run / "truth.parquet", columns=["north_m", "east_m", "heading_deg"]).to_pydict()
        err = [
            np.array(nav["north_m"][::100]) - np.array(truth["north_m"][::100]),
            np.array(nav["east_m"][::100]) - np.array(truth["east_m"][::100]),
            (np.array(nav["heading_deg"][::100]) - np.array(truth["heading_deg"][::100]) + 180.0) % 360.0 - 180.0,
        ]
        sigma = [np.array(nav[c][::100]) for c in ("sigma_north_m", "sigma_east_m", "sigma_heading_deg")]
        kept = (sigma[0] > 0.01) & (sigma[1] > 0.01) & (sigma[2] > 0.001)
        for q in range(3):
            z[q] += list(err[q][kept] / sigma[q][kept])
    return [np.array(v) for v in z]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--unz", default="target/release/unz", help="the unz binary")
    p.add_argument("--work", help="folder for the runs and outputs (default: a temporary one)")
    p.add_argument("--seed", type=int, default=51)
    p.add_argument("--runs", type=int, default=5)
    p.add_argument("--speed-period-s", type=float, default=1.0)
    p.add_argument("--instant", action="store_true",
                   help="speeds at each tag (the truth's as the odometer reads it), not means over the interval")
    p.add_argument("--config", help="a unz config file for every run (`[disupt] position_sigma_m = 0.1`, say)")
    a = p.parse_args()
    unz = str(Path(a.unz).resolve())
    work = Path(a.work or tempfile.mkdtemp(prefix="joint-sigma-coverage-")).resolve()
    work.mkdir(parents=True, exist_ok=True)
    sims, texts = work / "binary", work / "text"
    if not sims.exists():
        subprocess.run([unz, "simulate", "--out", str(sims), "--seed", str(a.seed), "--runs", str(a.runs)],
                       capture_output=True, check=True)
    config = ["--config", str(Path(a.config).resolve())] if a.config else []
    subprocess.run([unz, "run", str(sims), "--out", str(work / "out-binary"), *config], capture_output=True, check=True)
    for run in sorted(p for p in sims.iterdir() if (p / "truth.parquet").exists()):
        as_text_run(run, work / "out-binary" / run.name / "ingest", texts / run.name, a.speed_period_s, a.instant)
    subprocess.run([unz, "run", str(texts), "--out", str(work / "out-text"), *config], capture_output=True, check=True)
    for form, runs in [("binary", sims), ("text", texts)]:
        rows = z_scores(runs, work / f"out-{form}")
        for name, z, az_deg in rows:
            print(f"{form:6} {name}: azimuth {az_deg:+.3f}° off; z (azimuth, drift x, y, z) "
                  + " ".join(f"{v:+.1f}" for v in z))
        flat = [v for _, z, _ in rows for v in z]
        print(f"{form:6} RMS z {math.sqrt(sum(v * v for v in flat) / len(flat)):.2f} over {len(flat)}")
        for q, z in zip(("north", "east", "heading"), route_z(runs, work / f"out-{form}")):
            print(f"{form:6} route σ, {q}: RMS z {math.sqrt(float(np.mean(z * z))):.2f} over {len(z)} epochs, "
                  f"within 1σ {np.mean(np.abs(z) <= 1):.2f}, 2σ {np.mean(np.abs(z) <= 2):.3f}, "
                  f"3σ {np.mean(np.abs(z) <= 3):.3f}")
    if not a.work:
        shutil.rmtree(work)


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Writes the fuzz targets' seeds into corpus/<target>/ (gitignored), from the shipped
Kingston segment (text logs) and from operations of the UNZ-50 run generator
(fuzz_targets/common/unz50_run.rs). Python 3 standard library only; run from fuzz/."""

import bisect
import math
import pathlib

HERE = pathlib.Path(__file__).resolve().parent
KINGSTON = HERE.parent / "tests" / "data" / "kingston2008-seg1"


def records(name):
    lines = (KINGSTON / name).read_text().splitlines(keepends=True)
    return [l for l in lines if l.strip() and not l.startswith("#")]


def text_seeds(out):
    """Stretches of Kingston's drive, its start and a stop (fuzz_targets/common/kfgins_run.rs),
    and the drive stamped by clocks coarser than its period (formats/src/text_ticks.rs)."""
    stretches(out, {"drive": (152700, 152725), "start": (152143, 152160), "stop": (152820, 152835)}, [0])
    on_ticks(out, "drive", (152700, 152725))


def on_ticks(out, name, span):
    """The stretch `span` of Kingston with its IMU's tags floored to a clock's tick of 1.25,
    1.5625 and 2.5 periods, and its speed file."""
    imu, odo = records("imu.txt"), records("odometer.txt")
    t = lambda line: float(line.split()[0])
    t0, t1 = span
    speeds = "".join(l for l in odo if t0 - 1 <= t(l) <= t1 + 1).encode()
    for tick in (0.125, 0.15625, 0.25):
        floored = ("%.3f %s" % (math.floor(t(l) / tick) * tick, l.split(None, 1)[1]) for l in imu if t0 <= t(l) <= t1)
        (out / f"{name}-ticks-{tick}").write_bytes(bytes([1]) + "".join(floored).encode() + b"\x00" + speeds)


def text_chain_seeds(out):
    """The drive into Kingston's first stop, where its first control point is, with the
    alignment over a static start (the first byte's value / 3 even) and without one (odd)."""
    stretches(out, {"to-point": (152790, 152840)}, [0, 3])
    on_ticks(out, "to-point", (152790, 152840))


def stretches(out, spans, starts):
    """Each stretch with its odometer as an 8th column (first byte 0, plus each of
    `starts`), a speed file (1), a distance file (2) and a speed file as a CSV of three
    columns read at `value_column = 2` (13), and under a header line at `value_column =
    "speed"` (37)."""
    imu, odo = records("imu.txt"), records("odometer.txt")
    t = lambda line: float(line.split()[0])
    for (name, (t0, t1)), start in ((s, b) for s in spans.items() for b in starts):
        name += "-moving" if start % 2 else ""
        i = [l for l in imu if t0 <= t(l) <= t1]
        o = [l for l in odo if t0 - 1 <= t(l) <= t1 + 1]
        ot, ov = [t(l) for l in o], [float(l.split()[1]) for l in o]

        def speed(x):
            k = max(1, min(len(ot) - 1, bisect.bisect_left(ot, x)))
            a, b = ot[k - 1], ot[k]
            return ov[k - 1] + (ov[k] - ov[k - 1]) * (x - a) / (b - a)

        column = "".join(l.rstrip("\n") + " %.3f\n" % speed(t(l)) for l in i)
        distance, d = [], 0.0
        for k, line in enumerate(o):
            if k:
                d += 0.5 * (ov[k] + ov[k - 1]) * (ot[k] - ot[k - 1])
            distance.append("%s %.3f\n" % (line.split()[0], d))
        (out / f"{name}-col").write_bytes(bytes([start]) + column.encode() + b"\x00")
        log, speeds = "".join(i).encode(), "".join(o).encode()
        (out / f"{name}-speed").write_bytes(bytes([start + 1]) + log + b"\x00" + speeds)
        (out / f"{name}-dist").write_bytes(bytes([start + 2]) + log + b"\x00" + "".join(distance).encode())
        csv = "".join("%s,%s,%d\n" % (l.split()[0], l.split()[1], 800 + 120 * float(l.split()[1])) for l in o)
        (out / f"{name}-csv").write_bytes(bytes([start + 13]) + log + b"\x00" + csv.encode())
        named = "time,speed,rpm\n" + csv
        (out / f"{name}-csv-named").write_bytes(bytes([start + 37]) + log + b"\x00" + named.encode())


def drive_ops():
    """Operations of the run generator: a drive that starts, turns, stops and marks the
    manifest's control point (where it stops)."""

    def run(ops, n8, accel=0, yaw=0):  # 1 + 8·n8 samples at accel·0.02 m/s², yaw·0.002 rad/s
        ops += bytes([0, n8, accel & 0xFF, yaw & 0xFF, 0])

    ops = bytearray()
    run(ops, 125)
    run(ops, 125)  # 20 s at rest
    run(ops, 250, 25)  # 0.5 m/s² for 20 s: 10 m/s
    run(ops, 125)
    run(ops, 125, 0, 50)  # 10 s straight, 10 s turning at 0.1 rad/s
    run(ops, 250, -25)  # to a stop
    run(ops, 125)
    ops += bytes([6, 1])  # the mark of point 1
    run(ops, 125)
    return bytes(ops)


def binary_seeds(out):
    """The drive (`drive_ops`), and the same with an odometer flagged failed and a
    record's time tag leapt."""
    ops = drive_ops()
    (out / "drive-turn-stop-mark").write_bytes(ops)
    # Op 5 after the first 20 s (its bytes: flags, seq step u32, time step i8 ×5 ms or,
    # with flags bit 0, the tag as two u32; dtheta u32 i8 i8; dvel i8 u32; pulses u32;
    # status): a sample with the odometer flagged failed (status bit 1), then one whose
    # time tag is u64::MAX.
    sample = lambda flags, tag, status: bytes([5, flags, 1, 0, 0, 0] + tag + [0] * 15 + [status])
    flagged = ops[:10] + sample(0, [2], 2) + ops[10:]
    (out / "odometer-flagged").write_bytes(flagged)
    leapt = ops[:10] + sample(1, [0xFF] * 8, 0) + ops[10:]
    (out / "tag-leapt").write_bytes(leapt)


# The binary runs' manifest (MANIFEST in fuzz_targets/common/unz50_run.rs), and every
# parameter of `unz config` with a value of its own, for the fuzzer to vary.
MANIFEST = """name = "fuzz"
raw = "run.unz"
format = "unz-binary"

[site]
latitude_deg = 52.2
longitude_deg = 21.0
height_m = 110.0

[initial]
static_s = 5.0

[[control_point]]
id = 1
latitude_deg = 52.203042058
longitude_deg = 21.001906675
height_m = 110.0
"""
PARAMS = """
[params.ingest]
raw_mcap_compression = "zstd"

[params.derive]
epoch_s = 0.5
odo_time_offset_s = -0.1
gate_long_mps2 = 2.0
gate_lat_mps2 = 1.0
max_gap_s = 1.0

[params.derive.filter]
block_s = 0.2
cutoff_hz = 0.5

[params.align]
drift_sigma_rad_s = 1e-5
arw_rad_sqrt_s = 3e-5
drift_z_from_static = false

[params.kalman]
r_rad = 0.002
rate_walk_rad_s_sqrt_s = 2e-6

[params.disupt]
azimuth_bound_deg = 10.0
drift_bound_deg_h = 3.0
attitude_sigma_rad = 0.001
position_sigma_m = 2.0
joint_odo_scale = false
joint_odo_yaw = true
joint_odo_lag = false
odo_lag_bound_s = 0.5
odo_scale_bound_ppm = 5000.0
joint_exclude_inconsistent = false

[params.vehicle]
mark_lever_arm_m = [0.5, -0.2, 1.0]
imu_axes = "FRD"
imu_mounting_deg = [0.5, -0.5, 1.0]
odo_pitch_deg = 0.5

[params.export]
mcap_compression = "none"
"""


def manifest_seeds(out):
    """The binary runs' manifest and log, with every parameter set, the heading given and
    no static start, and the control point's time given."""
    variants = {
        "as-is": MANIFEST,
        "params": MANIFEST + PARAMS,
        "moving": MANIFEST.replace("static_s = 5.0", "static_s = 0.0\nazimuth_deg = 1.0\npitch_deg = 0.5\nroll_deg = -0.5"),
        "point-time": MANIFEST + "t_s = 95.0\n\n[[control_point]]\nid = 2\nlatitude_deg = 52.2\nlongitude_deg = 21.0\nheight_m = 110.0\nt_s = 1.0\n",
    }
    for name, text in variants.items():
        (out / name).write_bytes(text.encode() + b"\x00" + drive_ops())


if __name__ == "__main__":
    for target, make in [
        ("text_run", text_seeds),
        ("text_chain", text_chain_seeds),
        ("binary_run", binary_seeds),
        ("binary_chain", binary_seeds),
        ("manifest_chain", manifest_seeds),
    ]:
        out = HERE / "corpus" / target
        out.mkdir(parents=True, exist_ok=True)
        make(out)
        print(f"{out}: {len(list(out.iterdir()))} inputs")

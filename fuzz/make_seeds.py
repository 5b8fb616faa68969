#!/usr/bin/env python3
"""Writes the fuzz targets' seeds into corpus/<target>/ (gitignored), from the shipped
Kingston segment (text logs) and from operations of the UNZ-50 run generator
(fuzz_targets/common/unz50_run.rs). Python 3 standard library only; run from fuzz/."""

import bisect
import pathlib

HERE = pathlib.Path(__file__).resolve().parent
KINGSTON = HERE.parent / "tests" / "data" / "kingston2008-seg1"


def records(name):
    lines = (KINGSTON / name).read_text().splitlines(keepends=True)
    return [l for l in lines if l.strip() and not l.startswith("#")]


def text_seeds(out):
    """A stretch of Kingston's drive, its start and a stop, each with its odometer as an
    8th column (byte 0), a speed file (byte 1) and a distance file (byte 2)."""
    imu, odo = records("imu.txt"), records("odometer.txt")
    t = lambda line: float(line.split()[0])
    for name, (t0, t1) in {
        "drive": (152700, 152725),
        "start": (152143, 152160),
        "stop": (152820, 152835),
    }.items():
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
        (out / f"{name}-col").write_bytes(b"\x00" + column.encode() + b"\x00")
        (out / f"{name}-speed").write_bytes(b"\x01" + "".join(i).encode() + b"\x00" + "".join(o).encode())
        (out / f"{name}-dist").write_bytes(b"\x02" + "".join(i).encode() + b"\x00" + "".join(distance).encode())


def binary_seeds(out):
    """Operations of the run generator: a drive that starts, turns, stops and marks the
    manifest's control point (where it stops), and the same with an odometer flagged
    failed and a record's time tag leapt."""

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


if __name__ == "__main__":
    for target, make in [("text_run", text_seeds), ("binary_run", binary_seeds), ("binary_chain", binary_seeds)]:
        out = HERE / "corpus" / target
        out.mkdir(parents=True, exist_ok=True)
        make(out)
        print(f"{out}: {len(list(out.iterdir()))} inputs")

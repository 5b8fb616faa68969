"""Reads an ingest folder with third-party readers (pyarrow, mcap with its ROS 2
decoder) and prints what it found as JSON, for the Rust tests to assert on."""
import json
import sys

import numpy as np
import pyarrow.parquet as pq
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory


def table_info(path):
    table = pq.read_table(path)
    fields = {}
    for f in table.schema:
        meta = {k.decode(): v.decode() for k, v in (f.metadata or {}).items()}
        fields[f.name] = {"type": str(f.type), "unit": meta.get("unit"), "frame": meta.get("frame")}
    return {"rows": table.num_rows, "columns": table.column_names, "fields": fields}


def mcap_info(path, keep=()):
    """Channels, message counts, log-time order, and every message decoded by the ROS 2
    decoder; the messages of the topics in `keep` are returned as lists of dicts."""
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        channels = {}
        for cid, ch in summary.channels.items():
            channels[ch.topic] = {
                "message_encoding": ch.message_encoding,
                "schema_name": summary.schemas[ch.schema_id].name,
                "schema_encoding": summary.schemas[ch.schema_id].encoding,
                "count": summary.statistics.channel_message_counts.get(cid, 0),
            }
        last = {}
        monotonic = True
        decoded = 0
        first_log_time = None
        kept = {t: [] for t in keep}
        for _schema, channel, message, ros in reader.iter_decoded_messages(log_time_order=False):
            if first_log_time is None or message.log_time < first_log_time:
                first_log_time = message.log_time
            if channel.topic in last and message.log_time < last[channel.topic]:
                monotonic = False
            last[channel.topic] = message.log_time
            decoded += 1
            if channel.topic in kept:
                kept[channel.topic].append((message.log_time, ros))
        return {
            "channels": channels,
            "monotonic": monotonic,
            "first_log_time": first_log_time,
            "decoded": decoded,
        }, kept


def imu_agreement(folder, imu_msgs):
    """Largest relative difference between the decoded /imu messages and imu.parquet's
    increments over the nominal period, and whether seq and status agree."""
    t = pq.read_table(f"{folder}/imu.parquet")
    seq = t.column("seq").to_numpy()
    status = t.column("status").to_numpy()
    dtheta = np.stack(t.column("dtheta_rad").to_numpy(zero_copy_only=False))
    dvel = np.stack(t.column("dvel_mps").to_numpy(zero_copy_only=False))
    if len(imu_msgs) != len(seq):
        return {"same_count": False}
    rate = np.array([list(m.rate_rad_s) for _, m in imu_msgs], dtype=np.float64)
    accel = np.array([list(m.accel_mps2) for _, m in imu_msgs], dtype=np.float64)
    # The nominal period is the ratio of the two (the writer divides by it).
    big = np.abs(dtheta) > 1e-9
    dt = np.median(dtheta[big] / rate[big])
    rel = lambda a, b: float(np.max(np.abs(a - b) / np.maximum(np.abs(b), 1e-12)))
    return {
        "same_count": True,
        "seq_equal": bool(np.array_equal([m.seq for _, m in imu_msgs], seq)),
        "status_equal": bool(np.array_equal([m.status for _, m in imu_msgs], status)),
        "period_s": float(dt),
        "rate_rel_err": rel(rate * dt, dtheta),
        "accel_rel_err": rel(accel * dt, dvel),
    }


def main():
    folder = sys.argv[1]
    out = {name: table_info(f"{folder}/{name}.parquet") for name in ("imu", "odometer", "marks")}
    out["mcap"], kept = mcap_info(f"{folder}/raw.mcap", keep=("/imu", "/marks"))
    out["imu_vs_parquet"] = imu_agreement(folder, kept["/imu"])
    marks = pq.read_table(f"{folder}/marks.parquet").column("point_id").to_pylist()
    out["marks_equal"] = [m.point_id for _, m in kept["/marks"]] == marks
    print(json.dumps(out))


if __name__ == "__main__":
    main()

"""Reads an ingest folder with third-party readers (pyarrow, mcap) and prints what it
found as JSON, for the Rust tests to assert on."""
import json
import sys

import pyarrow.parquet as pq
from mcap.reader import make_reader


def table_info(path):
    table = pq.read_table(path)
    fields = {}
    for f in table.schema:
        meta = {k.decode(): v.decode() for k, v in (f.metadata or {}).items()}
        fields[f.name] = {"type": str(f.type), "unit": meta.get("unit"), "frame": meta.get("frame")}
    return {"rows": table.num_rows, "columns": table.column_names, "fields": fields}


def mcap_info(path):
    with open(path, "rb") as f:
        reader = make_reader(f)
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
        for _schema, channel, message in reader.iter_messages(log_time_order=False):
            if first_log_time is None or message.log_time < first_log_time:
                first_log_time = message.log_time
            if channel.topic in last and message.log_time < last[channel.topic]:
                monotonic = False
            last[channel.topic] = message.log_time
            if decoded < 1000:
                json.loads(message.data)
                decoded += 1
        return {"channels": channels, "monotonic": monotonic, "first_log_time": first_log_time}


def main():
    folder = sys.argv[1]
    out = {name: table_info(f"{folder}/{name}.parquet") for name in ("imu", "odometer", "marks")}
    out["mcap"] = mcap_info(f"{folder}/raw.mcap")
    print(json.dumps(out))


if __name__ == "__main__":
    main()

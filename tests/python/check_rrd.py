"""Reads a Rerun recording with the rerun-sdk package and prints what it holds as JSON:
the rows of every temporal entity per timeline, the static entities, the blueprints,
and whether `rerun rrd verify` verified the file (it exits 0 even on garbage, so its
"1 file verified" line is what counts). Exits non-zero when the file cannot be read."""
import json
import os
import subprocess
import sys

import rerun
import rerun.experimental as rx

path = sys.argv[1]
verify = subprocess.run(
    [os.path.join(os.path.dirname(sys.executable), "rerun"), "rrd", "verify", path],
    capture_output=True,
    text=True,
    env={**os.environ, "RERUN_ANALYTICS": "0"},
)
reader = rx.RrdReader(path)
temporal = {}
timelines = {}
static = set()
for chunk in reader.stream():
    entity = str(chunk.entity_path)
    if chunk.is_static:
        static.add(entity)
        continue
    temporal[entity] = temporal.get(entity, 0) + chunk.num_rows
    timelines.setdefault(entity, set()).update(chunk.timeline_names)
print(
    json.dumps(
        {
            "rerun_version": rerun.__version__,
            "verified": "1 file verified" in verify.stderr + verify.stdout,
            "temporal_rows": temporal,
            "timelines": {k: sorted(v) for k, v in timelines.items()},
            "static": sorted(static),
            "blueprints": len(list(reader.blueprints())),
            "recordings": len(list(reader.recordings())),
        }
    )
)

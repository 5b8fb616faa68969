"""Imports an MCAP file with Rerun's own importer (`rerun mcap convert`, the code the
viewer runs when it opens an .mcap) and prints, per entity, the temporal rows and the
data columns it made, as JSON. Exits non-zero when the import fails."""
import json
import os
import re
import subprocess
import sys
import tempfile

rerun = os.path.join(os.path.dirname(sys.executable), "rerun")
env = {**os.environ, "RERUN_ANALYTICS": "0"}
with tempfile.TemporaryDirectory() as tmp:
    rrd = os.path.join(tmp, "import.rrd")
    subprocess.run(
        [rerun, "mcap", "convert", sys.argv[1], "-o", rrd],
        check=True, capture_output=True, env=env,
    )
    printed = subprocess.run(
        [rerun, "rrd", "print", rrd], check=True, capture_output=True, text=True, env=env
    ).stdout
entities = {}
pattern = re.compile(r"with (\d+) rows .* - (\S+) - data columns: \[(.*)\]")
for line in printed.splitlines():
    m = pattern.search(line)
    if not m:
        continue
    rows, entity, columns = int(m.group(1)), m.group(2), m.group(3).split()
    e = entities.setdefault(entity, {"rows": 0, "columns": []})
    if not any(c.startswith("McapChannel:") for c in columns):
        e["rows"] += rows
    e["columns"] = sorted(set(e["columns"]) | set(columns))
print(json.dumps(entities))

"""Runs a SQL query with DuckDB (the README's example) and prints its rows as JSON.

Usage: run_duckdb.py QUERY_FILE
"""
import json
import sys

import duckdb

query = open(sys.argv[1]).read()
con = duckdb.connect()
cur = con.execute(query)
names = [d[0] for d in cur.description]
rows = [dict(zip(names, r)) for r in cur.fetchall()]
print(json.dumps({"columns": names, "rows": rows}, default=str))

"""Prints the channels (schema names, encodings, message counts) of an MCAP file and
whether each channel's timestamps increase, as JSON."""
import json
import sys

from check_ingest import mcap_info

print(json.dumps(mcap_info(sys.argv[1])))

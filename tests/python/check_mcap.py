"""Prints the channels (schema names, encodings, message counts) of an MCAP file, whether
each channel's timestamps increase, and each channel's first message as decoded by the
ROS 2 decoder, as JSON."""
import json
import sys

from check_ingest import mcap_info


def plain(value):
    """A decoded ROS 2 message as plain JSON values."""
    if hasattr(value, "__slots__") or hasattr(value, "__dict__"):
        names = getattr(value, "__slots__", None) or vars(value).keys()
        return {n: plain(getattr(value, n)) for n in names if not n.startswith("_")}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    return value


info, kept = mcap_info(sys.argv[1], keep=tuple(sys.argv[2:]))
info["first"] = {t: plain(m[0][1]) for t, m in kept.items() if m}
print(json.dumps(info))

#!/usr/bin/env python3
"""What a process's heap holds at its peak, by call site, from a heaptrack record.

heaptrack's own `--print-peaks` gives each call site's highest, not what is alive
together at the heap's peak; its massif export drops the call sites. This replays the
record (each block's allocation and free) and sums the blocks alive at the peak, or at the
highest point within a stretch of the run (heaptrack's own time stamps, ms), by the first
frames of the project's code on their stacks:

    heaptrack -o /tmp/ht target/release/unz disupt RUN --out OUT
    scripts/heaptrack_peak.py /tmp/ht.zst                  # at the peak
    scripts/heaptrack_peak.py /tmp/ht.zst --from 400 --to 450 --depth 3
    scripts/heaptrack_peak.py /tmp/ht.zst --timeline       # the heap, stamp by stamp

Session 91 found with it where the 40-minute disupt process's tail took its memory
(docs/performance.md). Needs `zstd` on the PATH for a compressed record.
"""

import argparse
import collections
import re
import subprocess
import sys


def read_lines(path):
    if path.endswith(".zst"):
        out = subprocess.run(["zstd", "-dc", path], capture_output=True, text=True, check=True)
        return out.stdout.splitlines()
    with open(path) as f:
        return f.read().splitlines()


def replay(lines, t_from, t_to):
    """The record's strings, frames, traces and blocks, the heap at each time stamp, and the
    blocks alive at the highest point within [t_from, t_to]."""
    strings, ips, traces, blocks = [""], [[]], [(0, 0)], []
    live = collections.Counter()
    total, peak, at_peak, peak_t, t = 0, -1, None, None, 0
    timeline = []
    for line in lines:
        kind, fields = line[:1], line[2:].split()
        if kind == "s":
            strings.append(line[2:].split(" ", 1)[1] if " " in line[2:] else "")
        elif kind == "i":
            values = [int(x, 16) for x in fields]
            # ip, module, then (function, file, line) per frame, inlined ones after.
            ips.append(values[2::3] if len(values) > 2 else [])
        elif kind == "t":
            ip, parent = (int(x, 16) for x in fields[:2])
            traces.append((ip, parent))
        elif kind == "a":
            size, trace = (int(x, 16) for x in fields[:2])
            blocks.append((size, trace))
        elif kind == "+":
            i = int(fields[0], 16)
            live[i] += 1
            total += blocks[i][0]
            if t_from <= t <= t_to and total > peak:
                peak, at_peak, peak_t = total, collections.Counter(live), t
        elif kind == "-":
            i = int(fields[0], 16)
            live[i] -= 1
            total -= blocks[i][0]
        elif kind == "c":
            t = int(fields[0], 16)
            timeline.append((t, total))
    return strings, ips, traces, blocks, peak, at_peak, peak_t, timeline


def demangled(name):
    name = re.sub(r"::h[0-9a-f]{16}$", "", name)
    for code, text in (("$LT$", "<"), ("$GT$", ">"), ("$u20$", " "), ("$RF$", "&"),
                       ("$C$", ","), ("..", "::")):
        name = name.replace(code, text)
    return name


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("record", help="heaptrack's record (.zst or plain)")
    ap.add_argument("--from", dest="t_from", type=float, default=0.0, help="stretch start, ms")
    ap.add_argument("--to", dest="t_to", type=float, default=float("inf"), help="stretch end, ms")
    ap.add_argument("--depth", type=int, default=2, help="frames of the project's code a site")
    ap.add_argument("--code", default="unz", help="what names the project's frames contain")
    ap.add_argument("--top", type=int, default=30, help="sites shown")
    ap.add_argument("--timeline", action="store_true", help="the heap at each time stamp")
    args = ap.parse_args()

    strings, ips, traces, blocks, peak, at_peak, peak_t, timeline = replay(
        read_lines(args.record), args.t_from, args.t_to)
    if args.timeline:
        for t, total in timeline:
            print(f"{t:8d} ms {total / 1e6:8.2f} MB")
        return
    if at_peak is None:
        sys.exit("no allocation in that stretch")

    def frames(trace):
        out = []
        while trace:
            ip, trace = traces[trace]
            out.extend(demangled(strings[f]) for f in ips[ip] if f < len(strings))
        return out

    by_site = collections.Counter()
    for i, n in at_peak.items():
        if n > 0:
            size, trace = blocks[i]
            own = [f for f in frames(trace) if args.code in f][: args.depth]
            by_site[" < ".join(own) or "(outside the project's code)"] += size * n
    print(f"heap at its peak {peak / 1e6:.2f} MB, at {peak_t} ms")
    for site, size in by_site.most_common(args.top):
        print(f"{size / 1e6:8.3f} MB  {site}")


if __name__ == "__main__":
    main()

#!/usr/bin/env python3
"""Open a review recording in the Rerun web viewer and save a screenshot.

Serves the recording with the pinned rerun-sdk (`rerun --serve-web`), opens the viewer in
headless Chromium (software GL: SwiftShader) over the DevTools protocol, waits until the
viewer has started and the recording has streamed in, and saves a PNG. Fails (exit 1) on
an error in the viewer's console or an uncaught exception; failed map-tile fetches are
expected without a network and only reported.

    python scripts/viewer_screenshot.py OUT/run/review/run.rrd shot.png

Needs: the test venv's `rerun` (rerun-sdk 0.36.3) and `websocket-client`, and Chromium
(`UNZ_CHROMIUM` or `chromium` on PATH); `scripts/test.sh` installs them.
"""

import argparse
import base64
import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
import urllib.parse
import urllib.request

import websocket

# Console errors that only say the map tiles could not be fetched (no network here).
TILE_HINTS = ("tile", "openstreetmap", "mapbox", "ERR_NAME_NOT_RESOLVED", "Failed to fetch")


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def wait_http(url, deadline):
    while time.monotonic() < deadline:
        try:
            with urllib.request.urlopen(url, timeout=2) as r:
                return r.read()
        except OSError:
            time.sleep(0.2)
    raise TimeoutError(f"nothing answers at {url}")


class DevTools:
    """A minimal DevTools-protocol client over one page's websocket."""

    def __init__(self, ws_url):
        self.ws = websocket.create_connection(ws_url, timeout=60)
        self.next_id = 0
        self.events = []

    def call(self, method, **params):
        self.next_id += 1
        my_id = self.next_id
        self.ws.send(json.dumps({"id": my_id, "method": method, "params": params}))
        while True:
            msg = json.loads(self.ws.recv())
            if msg.get("id") == my_id:
                if "error" in msg:
                    raise RuntimeError(f"{method}: {msg['error']}")
                return msg.get("result", {})
            self.events.append(msg)

    def pump(self, seconds):
        """Collects events for `seconds`."""
        end = time.monotonic() + seconds
        self.ws.settimeout(0.2)
        while time.monotonic() < end:
            try:
                self.events.append(json.loads(self.ws.recv()))
            except websocket.WebSocketTimeoutException:
                pass
        self.ws.settimeout(60)

    def grab_handle(self):
        """Keeps the viewer's `WebHandle` as `window.__unz_handle` (the page's own
        `window._handle` is set to what `start()` resolves to, which is nothing): every
        object with its prototype, through the DevTools heap query."""
        if self.evaluate("!!window.__unz_handle"):
            return
        proto = self.call(
            "Runtime.evaluate",
            expression="typeof wasm_bindgen !== 'undefined' && wasm_bindgen.WebHandle ? wasm_bindgen.WebHandle.prototype : null",
        ).get("result", {})
        if "objectId" not in proto:
            return
        found = self.call("Runtime.queryObjects", prototypeObjectId=proto["objectId"])
        self.call(
            "Runtime.callFunctionOn",
            objectId=found["objects"]["objectId"],
            functionDeclaration="function () { if (this.length) window.__unz_handle = this[0]; }",
        )

    def evaluate(self, expression):
        r = self.call("Runtime.evaluate", expression=expression, returnByValue=True)
        if "exceptionDetails" in r and os.environ.get("UNZ_VIEWER_DEBUG"):
            print("evaluate:", r["exceptionDetails"].get("exception", {}).get("description"))
        return r.get("result", {}).get("value")


def console_lines(events):
    """(level, text) of every console message and exception seen."""
    out = []
    for e in events:
        m, p = e.get("method"), e.get("params", {})
        if m == "Runtime.consoleAPICalled":
            text = " ".join(str(a.get("value", a.get("description", ""))) for a in p.get("args", []))
            out.append((p.get("type", "log"), text))
        elif m == "Runtime.exceptionThrown":
            d = p.get("exceptionDetails", {})
            out.append(("exception", d.get("exception", {}).get("description", d.get("text", ""))))
        elif m == "Log.entryAdded":
            entry = p.get("entry", {})
            out.append((entry.get("level", "info"), f"{entry.get('text', '')} {entry.get('url', '')}"))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("rrd")
    ap.add_argument("png")
    ap.add_argument("--timeout-s", type=float, default=180.0, help="for the whole check")
    ap.add_argument("--settle-s", type=float, default=3.0, help="after the data arrived")
    ap.add_argument("--size", default="1600,1000")
    args = ap.parse_args()

    deadline = time.monotonic() + args.timeout_s
    rerun = os.path.join(os.path.dirname(sys.executable), "rerun")
    if not os.path.exists(rerun):
        rerun = shutil.which("rerun") or sys.exit("no rerun (rerun-sdk) next to this python")
    chromium = os.environ.get("UNZ_CHROMIUM") or shutil.which("chromium") or shutil.which("chromium-browser")
    if not chromium:
        sys.exit("no chromium: set UNZ_CHROMIUM")

    grpc, web, devtools = free_port(), free_port(), free_port()
    server = subprocess.Popen(
        [rerun, "--serve-web", "--bind", "127.0.0.1", "--port", str(grpc),
         "--web-viewer-port", str(web), "--hide-welcome-screen", args.rrd],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        # The venv's `rerun` is a wrapper that starts the real viewer binary as its child:
        # a session of their own lets one signal stop both.
        start_new_session=True,
    )
    profile = tempfile.mkdtemp(prefix="unz-chromium-")
    browser = None
    try:
        wait_http(f"http://127.0.0.1:{web}/", deadline)
        browser = subprocess.Popen(
            [chromium, "--headless", "--no-sandbox", "--use-angle=swiftshader",
             "--enable-unsafe-swiftshader", "--disable-gpu-sandbox", f"--window-size={args.size}",
             f"--remote-debugging-port={devtools}", "--remote-allow-origins=*",
             f"--user-data-dir={profile}", "about:blank"],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            start_new_session=True,
        )
        wait_http(f"http://127.0.0.1:{devtools}/json/version", deadline)
        pages = json.loads(wait_http(f"http://127.0.0.1:{devtools}/json/list", deadline))
        page = next(p for p in pages if p.get("type") == "page")
        dt = DevTools(page["webSocketDebuggerUrl"])
        for domain in ("Runtime", "Log", "Page"):
            dt.call(f"{domain}.enable")
        w, h = (int(x) for x in args.size.split(","))
        dt.call("Emulation.setDeviceMetricsOverride", width=w, height=h, deviceScaleFactor=1, mobile=False)
        source = urllib.parse.quote(f"rerun+http://127.0.0.1:{grpc}/proxy", safe="")
        url = f"http://127.0.0.1:{web}/?url={source}"
        dt.call("Page.navigate", url=url)

        # The viewer has started when its web handle exists; the recording has streamed
        # in when the time range of its `time` timeline has stopped growing.
        probe = (
            "(() => { const h = window.__unz_handle; if (!h) return null;"
            " if (h.has_panicked()) return {panic: h.panic_message()};"
            " const id = h.get_active_recording_id(); if (!id) return {started: true};"
            " const r = h.get_timeline_time_range(id, 'time');"
            " return {started: true, id: id, range: r ? JSON.stringify(r) : null}; })()"
        )
        started, last, stable = None, None, 0
        while time.monotonic() < deadline:
            dt.pump(1.0)
            dt.grab_handle()
            state = dt.evaluate(probe) or {}
            if os.environ.get("UNZ_VIEWER_DEBUG"):
                print(f"{time.monotonic() - deadline + args.timeout_s:.1f} s: {state}", flush=True)
            if "panic" in state:
                raise RuntimeError(f"the viewer panicked: {state['panic']}")
            if state.get("started") and started is None:
                started = time.monotonic()
            rng = state.get("range")
            stable = stable + 1 if rng is not None and rng == last else 0
            last = rng
            if stable >= 3:
                break
        else:
            raise TimeoutError(f"the recording did not finish loading (last state {state})")
        print(f"viewer started, recording {state.get('id')} loaded, time range {last}")
        t_started = time.monotonic()
        dt.pump(args.settle_s)
        shot = dt.call("Page.captureScreenshot", format="png")
        with open(args.png, "wb") as f:
            f.write(base64.b64decode(shot["data"]))

        lines = console_lines(dt.events)
        errors = [(lvl, t) for lvl, t in lines if lvl in ("error", "exception")]
        tiles = [e for e in errors if any(k in e[1] for k in TILE_HINTS)]
        real = [e for e in errors if e not in tiles]
        print(f"screenshot {time.monotonic() - t_started:.1f} s later: {args.png}")
        print(f"console: {len(lines)} messages, {len(tiles)} map-tile errors (no network), "
              f"{len(real)} other errors")
        if os.environ.get("UNZ_VIEWER_DEBUG"):
            from collections import Counter
            print(Counter(lvl for lvl, _ in lines))
            for lvl, t in lines[:15] + lines[-15:]:
                print(f"  [{lvl}] {t[:200]}")
        for lvl, t in real:
            print(f"  {lvl}: {t[:400]}")
        return 1 if real else 0
    finally:
        for proc in (browser, server):
            if proc:
                stop_group(proc)
        shutil.rmtree(profile, ignore_errors=True)


def stop_group(proc):
    """Kills `proc` and every process of its session, and reaps it."""
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    proc.wait()


if __name__ == "__main__":
    sys.exit(main())

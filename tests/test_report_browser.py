"""The report in a real browser: headless Chromium (Debian's ``chromium``, which ``.ci/run`` installs)
loads it from a file, and through the DevTools protocol the test checks that no console error or exception
appears, every image has loaded, every figure has a size, nothing overflows a 1280 px wide window, and
saves a full-page screenshot (in the test's temporary folder; ``FRICTID_REPORT_ARTIFACTS=DIR`` also copies
the report and the screenshot to DIR).

The DevTools websocket is spoken by :class:`DevTools`, a small client on the standard library (text
frames, masking, fragmented and long messages), so the test needs no extra package. It skips, saying why,
only when no Chromium is installed.
"""
from __future__ import annotations

import base64
import json
import os
import shutil
import socket
import struct
import subprocess
import tempfile
import time
import urllib.request
from pathlib import Path

import pytest

BROWSERS = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")
WIDTH = 1280


def find_browser() -> str | None:
    env = os.environ.get("FRICTID_CHROMIUM")
    if env and shutil.which(env):
        return shutil.which(env)
    for name in BROWSERS:
        path = shutil.which(name)
        if path:
            return path
    return None


class DevTools:
    """A minimal websocket client for the Chrome DevTools protocol (RFC 6455 client side)."""

    def __init__(self, ws_url: str, timeout: float = 60.0):
        rest = ws_url.split("://", 1)[1]
        hostport, path = rest.split("/", 1)
        host, port = hostport.rsplit(":", 1)
        self.sock = socket.create_connection((host, int(port)), timeout=timeout)
        key = base64.b64encode(os.urandom(16)).decode()
        req = (f"GET /{path} HTTP/1.1\r\nHost: {hostport}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
               f"Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n\r\n")
        self.sock.sendall(req.encode())
        head = b""
        while b"\r\n\r\n" not in head:
            chunk = self.sock.recv(4096)
            if not chunk:
                raise ConnectionError("DevTools closed the connection during the handshake")
            head += chunk
        head, self.buf = head.split(b"\r\n\r\n", 1)
        if b" 101 " not in head.split(b"\r\n", 1)[0]:
            raise ConnectionError(f"DevTools refused the websocket: {head[:200]!r}")
        self.next_id = 0
        self.events: list[dict] = []

    def _read(self, n: int) -> bytes:
        while len(self.buf) < n:
            chunk = self.sock.recv(max(65536, n - len(self.buf)))
            if not chunk:
                raise ConnectionError("DevTools closed the connection")
            self.buf += chunk
        out, self.buf = self.buf[:n], self.buf[n:]
        return out

    def _send_frame(self, opcode: int, payload: bytes) -> None:
        head = bytes([0x80 | opcode])
        n = len(payload)
        if n < 126:
            head += bytes([0x80 | n])
        elif n < 1 << 16:
            head += bytes([0x80 | 126]) + struct.pack(">H", n)
        else:
            head += bytes([0x80 | 127]) + struct.pack(">Q", n)
        mask = os.urandom(4)
        body = bytes(b ^ mask[i % 4] for i, b in enumerate(payload)) if n < 4096 else _mask(payload, mask)
        self.sock.sendall(head + mask + body)

    def _recv_message(self) -> dict:
        data = b""
        while True:
            b0, b1 = self._read(2)
            opcode, n = b0 & 0x0F, b1 & 0x7F
            if n == 126:
                n = struct.unpack(">H", self._read(2))[0]
            elif n == 127:
                n = struct.unpack(">Q", self._read(8))[0]
            mask = self._read(4) if b1 & 0x80 else None
            payload = self._read(n)
            if mask:
                payload = _mask(payload, mask)
            if opcode == 0x9:  # ping
                self._send_frame(0xA, payload)
                continue
            if opcode == 0x8:
                raise ConnectionError("DevTools closed the websocket")
            data += payload
            if b0 & 0x80:
                return json.loads(data.decode("utf-8"))

    def call(self, method: str, params: dict | None = None, timeout: float = 60.0) -> dict:
        self.next_id += 1
        mid = self.next_id
        self._send_frame(0x1, json.dumps({"id": mid, "method": method, "params": params or {}}).encode())
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            msg = self._recv_message()
            if msg.get("id") == mid:
                if "error" in msg:
                    raise RuntimeError(f"{method}: {msg['error']}")
                return msg.get("result", {})
            self.events.append(msg)
        raise TimeoutError(method)

    def wait_event(self, method: str, timeout: float = 60.0) -> dict:
        for e in self.events:
            if e.get("method") == method:
                return e
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            msg = self._recv_message()
            self.events.append(msg)
            if msg.get("method") == method:
                return msg
        raise TimeoutError(method)

    def close(self) -> None:
        try:
            self.sock.close()
        except OSError:
            pass


def _mask(payload: bytes, mask: bytes) -> bytes:
    n = len(payload)
    key = (mask * (n // 4 + 1))[:n]
    return (int.from_bytes(payload, "big") ^ int.from_bytes(key, "big")).to_bytes(n, "big")


class Browser:
    """Headless Chromium with a DevTools port on 127.0.0.1 and a throw-away profile."""

    def __init__(self, exe: str):
        self.profile = tempfile.mkdtemp(prefix="frictid-chromium-")
        args = [exe, "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
                "--no-first-run", "--disable-component-update", "--disable-sync", "--disable-extensions",
                "--disable-dev-shm-usage", "--hide-scrollbars", "--mute-audio",
                f"--user-data-dir={self.profile}", "--remote-debugging-address=127.0.0.1",
                "--remote-debugging-port=0", f"--window-size={WIDTH},900", "about:blank"]
        self.proc = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        port_file = Path(self.profile) / "DevToolsActivePort"
        end = time.monotonic() + 60
        while not (port_file.exists() and port_file.read_text().strip()):
            if self.proc.poll() is not None or time.monotonic() > end:
                err = self.proc.stderr.read().decode("utf-8", "replace")[-1500:] if self.proc.stderr else ""
                self.stop()
                raise RuntimeError(f"chromium did not start: {err}")
            time.sleep(0.1)
        self.port = int(port_file.read_text().split()[0])

    def page(self) -> DevTools:
        with urllib.request.urlopen(f"http://127.0.0.1:{self.port}/json/list", timeout=30) as r:
            targets = json.load(r)
        page = next(t for t in targets if t.get("type") == "page")
        return DevTools(page["webSocketDebuggerUrl"])

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(timeout=15)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(timeout=15)
        if self.proc.stderr:
            self.proc.stderr.close()
        shutil.rmtree(self.profile, ignore_errors=True)


CHECKS = """(() => {
  const W = window.innerWidth;
  const imgs = Array.from(document.images);
  const broken = imgs.filter(i => !(i.complete && i.naturalWidth > 0)).map(i => i.alt || i.src.slice(0, 40));
  const figs = Array.from(document.querySelectorAll('svg.fig, figure img'));
  const empty = figs.filter(f => { const r = f.getBoundingClientRect(); return !(r.width > 50 && r.height > 50); })
                    .map(f => f.getAttribute('aria-label') || f.alt);
  const over = [];
  for (const el of document.body.querySelectorAll('*')) {
    const r = el.getBoundingClientRect();
    if (r.width > 0 && (r.right > W + 0.5 || r.left < -0.5)) {
      over.push(el.tagName.toLowerCase() + (el.id ? '#' + el.id : '') + ' ' + Math.round(r.left) + '..' + Math.round(r.right));
      if (over.length > 10) break;
    }
  }
  return {width: W, scrollWidth: document.documentElement.scrollWidth, height: document.documentElement.scrollHeight,
          images: imgs.length, broken: broken, figures: figs.length, empty: empty, overflow: over,
          sections: document.querySelectorAll('section.part').length,
          absent: document.querySelectorAll('section.part.absent').length};
})()"""


def load_report(exe: str, html_path: Path, screenshot: Path | None = None) -> dict:
    """Load a report file and return the checks, console errors, load time and screenshot path."""
    b = Browser(exe)
    try:
        dt = b.page()
        try:
            for dom in ("Page", "Runtime", "Log"):
                dt.call(f"{dom}.enable")
            dt.call("Emulation.setDeviceMetricsOverride",
                    {"width": WIDTH, "height": 900, "deviceScaleFactor": 1, "mobile": False})
            t0 = time.monotonic()
            nav = dt.call("Page.navigate", {"url": html_path.resolve().as_uri()})
            assert not nav.get("errorText"), nav
            dt.wait_event("Page.loadEventFired", timeout=120)
            load_s = time.monotonic() - t0
            time.sleep(0.3)  # let late errors arrive
            res = dt.call("Runtime.evaluate", {"expression": CHECKS, "returnByValue": True})
            checks = res["result"]["value"]
            if screenshot is not None:
                h = min(int(checks["height"]), 16000)
                shot = dt.call("Page.captureScreenshot", {"format": "png", "captureBeyondViewport": True,
                                                          "clip": {"x": 0, "y": 0, "width": WIDTH, "height": h,
                                                                   "scale": 1}}, timeout=120)
                screenshot.write_bytes(base64.b64decode(shot["data"]))
            errors = []
            for e in dt.events:
                m, p = e.get("method"), e.get("params", {})
                if m == "Runtime.exceptionThrown":
                    errors.append("exception: " + json.dumps(p.get("exceptionDetails", {}))[:300])
                elif m == "Runtime.consoleAPICalled" and p.get("type") in ("error", "assert", "warning"):
                    errors.append(f"console.{p.get('type')}: " + json.dumps(p.get("args", []))[:300])
                elif m == "Log.entryAdded" and p.get("entry", {}).get("level") in ("error", "warning"):
                    errors.append("log: " + p["entry"].get("text", "")[:300])
            return {"checks": checks, "errors": errors, "load_s": load_s}
        finally:
            dt.close()
    finally:
        b.stop()


@pytest.fixture(scope="module")
def browser():
    exe = find_browser()
    if exe is None:
        # CI installs it (.ci/run): there a missing browser is a failure, not a skip
        (pytest.fail if os.environ.get("CI") else pytest.skip)("no Chromium found (looked for " + ", ".join(BROWSERS) + "): install Debian's chromium "
                    "package (apt-get install chromium; .ci/run does) to run the browser test")
    return exe


def test_report_loads_cleanly_in_chromium(browser, tmp_path_factory, tmp_path):
    from test_report import build_scenario, truth_segments

    from frictid.io.logs import read_many
    from frictid.io.params_load import load_params_dict
    from frictid.report import write_report

    sc = build_scenario(tmp_path_factory)
    params = load_params_dict(sc["params"])
    # a second joint without logs, so that the index and the "absent" explanations are rendered too
    params["joints"]["second"] = dict(params["joints"][sc["joint"]], diagnosis=[])
    out = tmp_path / "report.html"
    write_report(str(out), params, read_many([sc["log"]]), params_path=sc["params"],
                 command="frictid report (browser test)", segmenter=truth_segments)
    shot = tmp_path / "report.png"
    r = load_report(browser, out, shot)
    c = r["checks"]
    print(f"report {out} ({out.stat().st_size / 1e6:.2f} MB) loaded in {r['load_s']:.2f} s; "
          f"screenshot {shot}; {c['figures']} figures, {c['images']} images")
    assert not r["errors"], r["errors"]
    assert c["width"] == WIDTH
    assert c["sections"] == 16 and c["absent"] >= 3
    assert c["figures"] >= 7 and not c["empty"], c["empty"]
    assert not c["broken"], c["broken"]
    assert c["scrollWidth"] <= WIDTH and not c["overflow"], c["overflow"]
    assert r["load_s"] < 10.0
    assert shot.stat().st_size > 50_000 and shot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    keep = os.environ.get("FRICTID_REPORT_ARTIFACTS")  # e.g. a CI artifact folder
    if keep:
        Path(keep).mkdir(parents=True, exist_ok=True)
        shutil.copy(out, Path(keep) / "report.html")
        shutil.copy(shot, Path(keep) / "report.png")


def test_a_png_figure_loads_as_an_image(browser, tmp_path):
    """A figure heavy enough to be written as PNG is an <img> that the browser decodes."""
    import numpy as np

    from frictid.report import figures as fg

    t = np.linspace(0, 10, 5000)
    r = fg.replay(t, np.sin(t), np.sin(t) + 0.1, {"tau": "N m", "q": "rad", "qd": "rad/s"}, "PNG figure",
                  "png-test")
    assert r.kind == "svg"
    fig = fg.new_figure(3.0)
    ax = fig.subplots()
    ax.plot(t, np.cos(t))
    ax.set_xlabel("time [s]")
    ax.set_ylabel("torque [N m]")
    png = fg.render(fig, "a PNG figure", "png-test-2", points=10 ** 6)
    assert png.kind == "png"
    page = tmp_path / "png.html"
    page.write_text("<!DOCTYPE html><html><head><meta charset='utf-8'><title>png</title></head><body>"
                    f"<figure><img src='data:image/png;base64,{png.data}' alt='{png.alt}' style='width:100%'>"
                    "</figure></body></html>")
    res = load_report(browser, page)
    assert not res["errors"], res["errors"]
    assert res["checks"]["images"] == 1 and not res["checks"]["broken"]

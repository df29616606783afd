"""The report in a real browser: headless Chromium (Debian's ``chromium``, which ``.ci/run`` installs)
loads it from a file, at a desktop width (1280 px) and a phone's (390 px), and through the DevTools protocol
the test checks that no console error or exception appears, every image has loaded, every figure has a
size, no two texts overlap (the boxes of the page's text and of the figures' SVG text: tick labels, legends,
titles), nothing is wider than the window outside a scrollable container, no table header breaks inside a
word, and saves a full-page screenshot per width (in the test's temporary folder;
``FRICTID_REPORT_ARTIFACTS=DIR`` also copies the report and the screenshots to DIR), which it compares: not
blank, a sane page height, the phone's page taller than the desktop's.

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
PHONE = 390


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
  // inside a container that scrolls sideways, content wider than the window is reachable
  const scrolls = el => { for (let p = el.parentElement; p && p !== document.body; p = p.parentElement) {
      const o = getComputedStyle(p).overflowX; if (o === 'auto' || o === 'scroll') return true; } return false; };
  const over = [];
  for (const el of document.body.querySelectorAll('*')) {
    if (el.closest('svg') && el.tagName.toLowerCase() !== 'svg') continue;
    const r = el.getBoundingClientRect();
    if (r.width > 0 && (r.right > W + 0.5 || r.left < -0.5) && !scrolls(el)) {
      over.push(el.tagName.toLowerCase() + (el.id ? '#' + el.id : '') + ' ' + Math.round(r.left) + '..' + Math.round(r.right));
      if (over.length > 10) break;
    }
  }
  // text boxes: every line of every HTML text node, every SVG <text>
  const boxes = [];
  const walk = document.createTreeWalker(document.body, NodeFilter.SHOW_TEXT);
  for (let n = walk.nextNode(); n; n = walk.nextNode()) {
    if (!n.textContent.trim() || n.parentElement.closest('svg, script, style')) continue;
    const cs = getComputedStyle(n.parentElement);
    if (cs.visibility === 'hidden' || cs.display === 'none') continue;
    const rg = document.createRange(); rg.selectNodeContents(n);
    for (const r of rg.getClientRects()) if (r.width > 1 && r.height > 1)
      boxes.push({r: r, id: boxes.length, node: n, what: n.textContent.trim().slice(0, 40)});
  }
  for (const t of document.querySelectorAll('svg text')) {
    const r = t.getBoundingClientRect();
    if (r.width > 1 && r.height > 1 && t.textContent.trim()) boxes.push({r: r, node: t, what: 'svg: ' + t.textContent.trim().slice(0, 40)});
  }
  const tol = 1.0, overlaps = [];
  boxes.sort((a, b) => a.r.top - b.r.top);
  for (let i = 0; i < boxes.length && overlaps.length < 12; i++) {
    const a = boxes[i].r;
    for (let k = i + 1; k < boxes.length && boxes[k].r.top < a.bottom - tol; k++) {
      const b = boxes[k].r;
      if (boxes[k].node === boxes[i].node) continue;
      if (b.left < a.right - tol && a.left < b.right - tol && b.top < a.bottom - tol && a.top < b.bottom - tol) {
        overlaps.push(boxes[i].what + ' | ' + boxes[k].what); if (overlaps.length >= 12) break;
      }
    }
  }
  // table headers broken inside a word: a word whose characters lie on more than one line
  const midword = [];
  for (const th of document.querySelectorAll('th')) {
    const tw = document.createTreeWalker(th, NodeFilter.SHOW_TEXT);
    for (let n = tw.nextNode(); n; n = tw.nextNode()) {
      const re = /\\S+/g; let m;
      while ((m = re.exec(n.textContent)) !== null) {
        const rg = document.createRange(); rg.setStart(n, m.index); rg.setEnd(n, m.index + m[0].length);
        const tops = new Set(Array.from(rg.getClientRects()).filter(r => r.width > 0).map(r => Math.round(r.top)));
        if (tops.size > 1) midword.push(th.textContent.trim().slice(0, 40));
      }
    }
  }
  return {width: W, scrollWidth: document.documentElement.scrollWidth, height: document.documentElement.scrollHeight,
          images: imgs.length, broken: broken, figures: figs.length, empty: empty, overflow: over,
          texts: boxes.length, overlaps: overlaps, midword: midword,
          sections: document.querySelectorAll('section.part').length,
          absent: document.querySelectorAll('section.part.absent').length};
})()"""


def load_report(exe: str, html_path: Path, screenshot: Path | None = None, width: int = WIDTH) -> dict:
    """Load a report file in a window ``width`` px wide (a phone's, with its viewport, below 600 px) and
    return the checks, console errors, load time and screenshot path."""
    b = Browser(exe)
    try:
        dt = b.page()
        try:
            for dom in ("Page", "Runtime", "Log"):
                dt.call(f"{dom}.enable")
            dt.call("Emulation.setDeviceMetricsOverride",
                    {"width": width, "height": 900, "deviceScaleFactor": 1, "mobile": width < 600})
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
                                                          "clip": {"x": 0, "y": 0, "width": width, "height": h,
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


def screenshot_stats(path: Path) -> dict:
    """Size, share of non-white pixels and the number of distinct grey levels of a screenshot (Pillow comes
    with matplotlib)."""
    from PIL import Image

    with Image.open(path) as im:
        g = im.convert("L")
        small = g.resize((max(1, g.width // 4), max(1, g.height // 4)))
        px = list(small.tobytes())
    return {"width": g.width, "height": g.height, "ink": sum(1 for v in px if v < 240) / max(len(px), 1),
            "levels": len(set(px))}


_PAGE: dict = {}


def report_page(tmp_path_factory) -> Path:
    """The scenario's report with a second joint without logs (the index and the "absent" explanations
    are rendered too), written once."""
    if _PAGE:
        return _PAGE["path"]
    from test_report import build_scenario, truth_segments

    from frictid.io.logs import read_many
    from frictid.io.params_load import load_params_dict
    from frictid.report import write_report

    sc = build_scenario(tmp_path_factory)
    params = load_params_dict(sc["params"])
    params["joints"]["second"] = dict(params["joints"][sc["joint"]], diagnosis=[])
    out = tmp_path_factory.mktemp("browser") / "report.html"
    write_report(str(out), params, read_many([sc["log"]]), params_path=sc["params"],
                 command="frictid report (browser test)", segmenter=truth_segments)
    _PAGE["path"] = out
    return out


@pytest.mark.parametrize("width", [WIDTH, PHONE])
def test_report_loads_cleanly_in_chromium(browser, tmp_path_factory, tmp_path, width):
    out = report_page(tmp_path_factory)
    shot = out.parent / f"report-{width}.png"
    r = load_report(browser, out, shot, width=width)
    c = r["checks"]
    print(f"{width} px: report {out} ({out.stat().st_size / 1e6:.2f} MB) loaded in {r['load_s']:.2f} s; "
          f"screenshot {shot}; {c['figures']} figures, {c['images']} images, {c['texts']} text boxes, "
          f"page {c['height']} px high")
    assert not r["errors"], r["errors"]
    assert c["width"] == width
    assert c["sections"] == 16 and c["absent"] >= 3
    assert c["figures"] >= 7 and not c["empty"], c["empty"]
    assert not c["broken"], c["broken"]
    assert c["scrollWidth"] <= width and not c["overflow"], c["overflow"]
    assert not c["overlaps"], c["overlaps"]
    assert not c["midword"], c["midword"]
    assert c["texts"] > 500  # the check saw the page's text and the figures'
    assert r["load_s"] < 10.0
    st = screenshot_stats(shot)
    assert st["width"] == width and st["height"] == min(c["height"], 16000)
    assert st["ink"] > 0.02 and st["levels"] > 20, st  # not blank
    assert 3 * 900 < c["height"] < 60 * 900, c["height"]  # a sane page: several screens, not endless
    _PAGE[width] = c["height"]
    if WIDTH in _PAGE and PHONE in _PAGE:
        assert _PAGE[PHONE] > _PAGE[WIDTH]  # the narrow page stacks what the wide one lays side by side
    keep = os.environ.get("FRICTID_REPORT_ARTIFACTS")  # e.g. a CI artifact folder
    if keep:
        Path(keep).mkdir(parents=True, exist_ok=True)
        shutil.copy(out, Path(keep) / "report.html")
        shutil.copy(shot, Path(keep) / shot.name)


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


def test_the_checks_catch_overlap_overflow_and_broken_headers(browser, tmp_path):
    """The layout checks fail where they should: two SVG labels on top of each other, a header cell
    broken inside its word, a block wider than the window (and not when it sits in a scrolling box)."""
    page = tmp_path / "bad.html"
    page.write_text(
        "<!DOCTYPE html><html><head><meta charset='utf-8'><meta name='viewport' content='width=device-width'>"
        "<title>bad</title></head><body style='margin:0'>"
        "<svg width='300' height='60'><text x='10' y='30' font-size='14'>0.05</text>"
        "<text x='22' y='32' font-size='14'>0.1</text></svg>"
        "<table style='width:40px'><tr><th style='overflow-wrap:anywhere'>extension</th></tr></table>"
        "<div style='overflow-x:auto'><div style='width:2000px'>scrolls</div></div>"
        "<div id='wide' style='width:2000px'>too wide</div></body></html>")
    for width in (WIDTH, PHONE):
        c = load_report(browser, page, width=width)["checks"]
        assert any("0.05" in o and "0.1" in o for o in c["overlaps"]), c["overlaps"]
        assert c["midword"] == ["extension"], c["midword"]
        assert [o.split(" ")[0] for o in c["overflow"]] == ["div#wide"], c["overflow"]

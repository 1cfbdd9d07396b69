"""Headless Chromium for the page tests, driven over the DevTools protocol (websocket-client from
python3-websocket; no npm, nothing fetched at test time), and what they read off its screenshots:
PNG decoding (8-bit RGB/RGBA, what Chromium writes) and the count of open-mouth pixels.

Used by tests/server/viewer_browser_test.py (the page following sessions),
tests/server/viewer_microphone_test.py (the page's own voice through a fake microphone) and
tests/server/viewer_file_test.py (the page playing a file as its voice).
"""

import base64
import json
import re
import struct
import subprocess
import threading
import time
import urllib.request
import zlib

import websocket  # python3-websocket


def decode_png(data):
    """8-bit RGB or RGBA, non-interlaced (what Chromium writes) -> (width, height, rows of RGB)."""
    assert data[:8] == b"\x89PNG\r\n\x1a\n", "not a PNG"
    pos, idat, header = 8, b"", None
    while pos < len(data):
        (length,) = struct.unpack(">I", data[pos:pos + 4])
        kind, body = data[pos + 4:pos + 8], data[pos + 8:pos + 8 + length]
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat += body
        pos += 12 + length
    width, height, depth, colour, _, _, interlace = header
    assert depth == 8 and colour in (2, 6) and interlace == 0, f"unsupported PNG {header}"
    channels = 3 if colour == 2 else 4
    raw, stride, rows, previous = zlib.decompress(idat), width * channels, [], bytearray(width * channels)
    for y in range(height):
        kind, line = raw[y * (stride + 1)], bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for i in range(stride):
            a = line[i - channels] if i >= channels else 0
            b, c = previous[i], previous[i - channels] if i >= channels else 0
            if kind == 1:
                line[i] = (line[i] + a) & 0xFF
            elif kind == 2:
                line[i] = (line[i] + b) & 0xFF
            elif kind == 3:
                line[i] = (line[i] + (a + b) // 2) & 0xFF
            elif kind == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[i] = (line[i] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 0xFF
        rows.append([tuple(line[x * channels:x * channels + 3]) for x in range(width)])
        previous = line
    return width, height, rows


def open_mouth_pixels(png, colours, tolerance=14):
    """Pixels of the PNG within `tolerance` (per channel) of one of the open-mouth colours."""
    _, _, rows = decode_png(png)
    return sum(1 for row in rows for pixel in row
               if any(all(abs(p - c) <= tolerance for p, c in zip(pixel, colour)) for colour in colours))


class DevTools:
    """One page of a headless Chromium, over the DevTools protocol."""

    def __init__(self, workdir, extra_args=()):
        self.process = subprocess.Popen(
            ["chromium", "--headless=new", "--no-sandbox", "--disable-gpu-sandbox", "--use-angle=swiftshader",
             "--enable-unsafe-swiftshader", "--autoplay-policy=no-user-gesture-required", "--mute-audio",
             "--no-first-run", "--remote-debugging-port=0", "--window-size=1000,900",
             f"--user-data-dir={workdir}/chromium", *extra_args, "about:blank"],
            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        port = None
        for line in self.process.stderr:
            match = re.search(r"DevTools listening on ws://127\.0\.0\.1:(\d+)/", line)
            if match:
                port = match.group(1)
                break
        if port is None:
            raise RuntimeError("chromium did not start its DevTools endpoint")
        threading.Thread(target=self.process.stderr.read, daemon=True).start()  # drain
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list") as reply:
            page = next(t for t in json.load(reply) if t["type"] == "page")
        self.socket = websocket.create_connection(page["webSocketDebuggerUrl"], timeout=30)
        self.next_id = 0
        self.call("Page.enable")
        self.call("Runtime.enable")

    def call(self, method, **params):
        self.next_id += 1
        self.socket.send(json.dumps({"id": self.next_id, "method": method, "params": params}))
        while True:
            reply = json.loads(self.socket.recv())
            if reply.get("id") == self.next_id:
                if "error" in reply:
                    raise RuntimeError(f"{method}: {reply['error']}")
                return reply["result"]

    def evaluate(self, expression):
        result = self.call("Runtime.evaluate", expression=expression, returnByValue=True, awaitPromise=True)
        if "exceptionDetails" in result:
            raise RuntimeError(f"{expression}: {result['exceptionDetails']}")
        return result["result"].get("value")

    def set_files(self, selector, paths):
        """Chooses `paths` in the page's file input `selector`, as a user would (it fires 'change')."""
        root = self.call("DOM.getDocument")["root"]["nodeId"]
        node = self.call("DOM.querySelector", nodeId=root, selector=selector)["nodeId"]
        if not node:
            raise AssertionError(f"the page has no {selector}")
        self.call("DOM.setFileInputFiles", nodeId=node, files=list(paths))

    def screenshot(self, clip=None):
        params = {"format": "png"}
        if clip:
            params["clip"] = dict(clip, scale=1)
        return base64.b64decode(self.call("Page.captureScreenshot", **params)["data"])

    def close(self):
        self.socket.close()
        self.process.kill()
        self.process.wait()

    def hold_viewer_at(self, t_us, timeout_s=10):
        """Holds the viewer page (window.lipsyncViewer) at utterance time `t_us` and returns once that
        picture is on screen: a tick has drawn it, and two animation frames later it is shown."""
        self.evaluate(f"lipsyncViewer.hold({t_us})")
        deadline = time.time() + timeout_s
        while self.evaluate("lipsyncViewer.utteranceTime") != t_us:
            if time.time() > deadline:
                raise AssertionError(f"the page did not draw the held time {t_us} µs")
            time.sleep(0.02)
        self.evaluate("new Promise((done) => requestAnimationFrame(() => requestAnimationFrame(done)))")


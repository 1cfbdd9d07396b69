"""The viewer page's own voice in the page tests (docs/viewer.md, "Talk to the face"): Festival's
speech with its own phone timings, a lipsyncd with its viewer, and what the tests read off the page
(its live-voice state, the mouth on the canvas at a phone's middle, the latency it shows).

Used by tests/server/viewer_microphone_test.py (the voice from Chromium's fake microphone) and
tests/server/viewer_file_test.py (the voice from a file the page plays).
"""

import io
import json
import re
import subprocess
import time
import urllib.request
import wave

import numpy

from chromium_page import open_mouth_pixels
from listening_address import ServerProcess

BILABIALS = {"p", "b", "m"}
OPEN_VOWELS = {"aa", "ao", "ay", "ae"}
OPEN_PIXELS = 40  # an open mouth shows at least this many cavity, teeth or tongue pixels


def festival_segments(sentence):
    """Festival's own timings of `sentence` (utt.save.segs): (its text, [(label, start_us, end_us)])."""
    out = subprocess.run(["festival", "-b", "(voice_kal_diphone)", f'(set! u (SynthText "{sentence}"))',
                          '(utt.save.segs u "-")'], check=True, capture_output=True, text=True).stdout
    segments, start = [], 0
    for line in out.splitlines():
        fields = line.split()
        if len(fields) != 3 or line.startswith("#"):
            continue
        end = round(float(fields[0]) * 1e6)
        segments.append((fields[2], start, end))
        start = end
    return out, segments


def read_wav(path_or_bytes):
    """(mono float samples, rate) of a 16-bit WAV file or its bytes."""
    source = io.BytesIO(path_or_bytes) if isinstance(path_or_bytes, bytes) else path_or_bytes
    with wave.open(source) as w:
        assert w.getsampwidth() == 2, "not 16-bit"
        data = numpy.frombuffer(w.readframes(w.getnframes()), dtype="<i2").astype(numpy.float64)
        channels, rate = w.getnchannels(), w.getframerate()
    return data.reshape(-1, channels).mean(axis=1) / 32768.0, rate


def resample(samples, rate, to_rate):
    times = numpy.arange(0, len(samples) / rate, 1 / to_rate)
    return numpy.interp(times, numpy.arange(len(samples)) / rate, samples)


def offset_of(heard, heard_rate, speech, speech_rate):
    """µs into `heard` where `speech` starts (its first whole occurrence), by cross-correlation at 8 kHz."""
    rate = 8000
    a, b = resample(heard, heard_rate, rate), resample(speech, speech_rate, rate)
    size = 1 << int(numpy.ceil(numpy.log2(len(a) + len(b))))
    correlation = numpy.fft.irfft(numpy.fft.rfft(a, size) * numpy.conj(numpy.fft.rfft(b, size)), size)[:len(a) - len(b)]
    best = int(numpy.argmax(correlation))
    peak = correlation[best] / (numpy.linalg.norm(b) * numpy.linalg.norm(a[best:best + len(b)]) + 1e-12)
    return round(best / rate * 1e6), float(peak)


class FestivalSpeech:
    """Festival (kal diphone voice) speaking `sentence`: `segments`, its own timings, which must equal
    the fixture `lab_path` (tests/data/closures/festival_N.lab); `speech` and `rate`, its samples;
    `path`, a 16-bit mono WAV of the speech between two pauses of `pad_s`, `duration_s` long."""

    def __init__(self, sentence, lab_path, workdir, pad_s):
        lab, self.segments = festival_segments(sentence)
        with open(lab_path) as fixture:
            assert lab.split() == fixture.read().split(), f"Festival's timings differ from {lab_path}"
        spoken = f"{workdir}/spoken.wav"
        subprocess.run(["text2wave", "-eval", "(voice_kal_diphone)", "-o", spoken], input=sentence, text=True,
                       check=True, capture_output=True)
        self.speech, self.rate = read_wav(spoken)
        pad = numpy.zeros(round(pad_s * self.rate))
        padded = numpy.concatenate([pad, self.speech, pad])
        self.path = f"{workdir}/speech.wav"
        with wave.open(self.path, "wb") as w:
            w.setnchannels(1)
            w.setsampwidth(2)
            w.setframerate(self.rate)
            w.writeframes((numpy.clip(padded, -1, 1) * 32767).astype("<i2").tobytes())
        self.duration_s = len(padded) / self.rate


def start_viewer(lipsyncd):
    """lipsyncd on port 0 with its viewer (sessions kept a minute, for /audio): (the process, http://HOST:PORT)."""
    server = ServerProcess([lipsyncd, "--listen", "127.0.0.1:0", "--http-listen", "127.0.0.1:0",
                            "--log-level", "info", "--session-retention-ms", "60000"])
    line = server.next_line()
    assert line and line.startswith("lipsyncd viewer on http://"), line
    return server, line.split()[3].rsplit("/view", 1)[0]


class LiveVoicePage:
    """For a unittest.TestCase with `browser` (chromium_page.DevTools), `viewer_url` and `voice`
    (FestivalSpeech): the page opened, its live voice's state read, the mouth measured at Festival's
    phones, the latency the page shows judged."""

    BUDGET_MS = 200
    # The page's latency beyond the budget it asked of lipsyncd: the two WebSockets, the session's
    # fan-out to the follower and the page's own event loop on a loaded 2-core machine.
    PAGE_MARGIN_MS = 100

    def open_page(self, query="", script=None):
        self.browser.call("Page.navigate", url=f"{self.viewer_url}/view{query}")
        deadline = time.time() + 20
        while not self.browser.evaluate("!!(window.lipsyncViewer && lipsyncViewer.live && "
                                        "document.readyState === 'complete')"):
            self.assertLess(time.time(), deadline, "the page did not load")
            time.sleep(0.05)
        if script:
            self.browser.evaluate(script)

    def live(self):
        return json.loads(self.browser.evaluate(
            "JSON.stringify(Object.assign({}, lipsyncViewer.live, {socket: null, context: null, node: null,"
            " stream: null, queued: null, pieces: null}, {frames: lipsyncViewer.frames,"
            " status: document.getElementById('status').textContent,"
            " latencyText: document.getElementById('latency').textContent}))"))

    def wait_live(self, condition, what, timeout_s=20):
        deadline = time.time() + timeout_s
        while True:
            state = self.live()
            if condition(state):
                return state
            self.assertLess(time.time(), deadline, f"{what}: the page's voice is {state}")
            time.sleep(0.05)

    def wait_summary(self):
        """Waits for the session's summary on /ws (the page's follower) and returns the voice's state."""
        deadline = time.time() + 10
        while not self.browser.evaluate("lipsyncViewer.ended"):
            self.assertLess(time.time(), deadline, "the page did not receive the session's summary")
            time.sleep(0.05)
        return self.live()

    def check_summary(self, state, session, lead_s):
        """lipsyncd's summary of the voice, the sentence `lead_s` into it: the whole sentence was
        heard, a frame every 1/30 s of it, and the page has every frame."""
        print(f"{session}: sent {state['piecesSent']} pieces ({state['bytesSent']} bytes) at {state['sampleRate']} Hz; "
              f"summary {state['summary']}; the page has {state['frames']} frames", flush=True)
        self.assertEqual(state["summary"]["session"], session)
        sentence_end_us = (lead_s + len(self.voice.speech) / self.voice.rate) * 1e6
        self.assertGreater(state["summary"]["duration_us"], sentence_end_us)
        self.assertGreaterEqual(state["summary"]["frames"] * 1e6 / 30, sentence_end_us)
        self.assertEqual(state["frames"], state["summary"]["frames"])

    def mouth_pixels_at(self, t_us):
        self.browser.hold_viewer_at(t_us)
        state = json.loads(self.browser.evaluate(
            "JSON.stringify({rect: lipsyncViewer.mouthRect, colours: lipsyncViewer.openMouthColours})"))
        return open_mouth_pixels(self.browser.screenshot(state["rect"]), state["colours"])

    def heard_offset_us(self, session):
        """µs into the session's audio (what lipsyncd heard) where the sentence starts."""
        with urllib.request.urlopen(f"{self.viewer_url}/audio?session={session}") as reply:
            heard, heard_rate = read_wav(reply.read())
        offset, peak = offset_of(heard, heard_rate, self.voice.speech, self.voice.rate)
        print(f"{session}: lipsyncd heard {len(heard) / heard_rate:.2f} s at {heard_rate} Hz; the sentence starts "
              f"at {offset / 1000:.0f} ms (correlation {peak:.2f})", flush=True)
        self.assertGreater(peak, 0.8, "the sentence is not in what lipsyncd heard")
        return offset

    def measure_mouth(self, session, offset_us):
        """[(label, t µs, open-mouth pixels)] at the /p b m/ middles and at the open vowels' of
        Festival's timings, the sentence starting `offset_us` into the session."""
        closed, opened = [], []
        for label, start, end in self.voice.segments:
            middle = offset_us + (start + end) // 2
            if label in BILABIALS:
                closed.append((label, middle, self.mouth_pixels_at(middle)))
            elif label in OPEN_VOWELS:
                opened.append((label, middle, self.mouth_pixels_at(middle)))
        print(f"{session}: open-mouth pixels at /p b m/ middles {closed}", flush=True)
        print(f"{session}: open-mouth pixels at open vowels {opened}", flush=True)
        return closed, opened

    def check_mouth(self, closed, opened):
        """Every closure closed, every open vowel open."""
        for label, t_us, pixels in closed:
            self.assertEqual(pixels, 0, f"/{label}/ at {t_us} µs shows an open mouth")
        self.check_open(opened)

    def check_open(self, opened):
        for label, t_us, pixels in opened:
            self.assertGreaterEqual(pixels, OPEN_PIXELS, f"/{label}/ at {t_us} µs shows a closed mouth")

    def check_latency(self, state, beyond_budget_ms=0):
        """The page's own figure, and over the frames after the first second (the start of a voice
        waits for lipsyncd to set up its recogniser: printed, not judged). `beyond_budget_ms`: what
        the path is known to take beyond the budget at its 95th percentile (the audio alone)."""
        log = state["log"]
        steady = sorted(ms for t, ms in log if t >= 1_000_000)
        p95 = steady[min(len(steady) - 1, int(0.95 * len(steady)))]
        print(f"{state['session']}: the page shows {state['latencyText']!r}; over {len(log)} frames max "
              f"{max(ms for _, ms in log)} ms, the first second's frames {[ms for t, ms in log if t < 1_000_000]} ms, "
              f"after it p50 {steady[len(steady) // 2]} p95 {p95} max {steady[-1]} ms", flush=True)
        allowed = self.BUDGET_MS + beyond_budget_ms + self.PAGE_MARGIN_MS
        late = [(round(t / 1000), ms) for t, ms in log if t >= 1_000_000 and ms > allowed]
        if late:
            print(f"{state['session']}: frames later than {allowed} ms after the first second (frame ms, latency ms) "
                  f"{late}", flush=True)
        self.assertEqual(state["budgetMs"], self.BUDGET_MS)
        self.assertGreater(len(log), 60)
        shown = re.fullmatch(r"(\d+) ms \(p95 (\d+), budget (\d+)\)", state["latencyText"])
        self.assertIsNotNone(shown, state["latencyText"])
        self.assertAlmostEqual(int(shown[1]), state["latencyMs"], delta=0.5)
        self.assertAlmostEqual(int(shown[2]), state["latencyP95Ms"], delta=0.5)
        self.assertEqual(int(shown[3]), self.BUDGET_MS)
        self.assertLessEqual(p95, allowed)

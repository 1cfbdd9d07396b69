"""Mixed load for tools/soak.sh: worker threads that loop, until the deadline, over
the kinds of calls a real lipsyncd sees, good and bad:

  stream      Animate with a session name (60 phonemes), read to the end
  follower    Subscribe to a session being produced, read to the end
  staller     Subscribe, read the header, then stop reading (cut off, then cancelled)
  cancel      Animate that the client cancels half way
  bad         requests the server must refuse: unknown label, unknown model,
              a 1 MB label, a message over --max-message-bytes, Subscribe to nothing
  face        Animate with the mesh output (subdivision 0); on a busy machine it may
              end with DEADLINE_EXCEEDED (behind real time by --mesh-max-lag-ms)
  render      Render and GetModel

Every call's outcome is counted; a status the call should not get is an error.

Every --quiet-every seconds the load pauses: each worker finishes the call it is in and
waits; once the server's metrics say no call is in progress and no session is held, the
server's resident memory and open descriptors are read from /proc/PID and printed as a
`quiet` line, and the load resumes. After the run the quiet samples taken after the
warm-up are judged by soak_judge.judge.

  soak_load.py ADDRESS METRICS_ADDRESS PID SECONDS
      [--quiet-every S] [--warmup S] [--rss-slack-mb MB] [--fd-slack N]

Prints the quiet samples, one line of counts and the verdict; exit status 1 if any call
got a status it should not have, the load could not be made quiet, or memory or
descriptors grew. Run with Debian's /usr/bin/python3 (python3-grpcio) and
PYTHONPATH=<build>/clients/python/generated.
"""
import argparse
import os
import re
import statistics
import urllib.request
import random
import sys
import threading
import time
from collections import Counter

import grpc
from lipsync.v1 import lipsync_pb2 as pb
from lipsync.v1 import lipsync_pb2_grpc as rpc
from soak_judge import judge, lowest_of_thirds

LABELS = ["sil", "P", "AA", "M", "IY", "F", "AO", "R", "T", "UW", "B", "EH", "S", "sil"]
counts = Counter()
errors = Counter()
lock = threading.Lock()


class Pause:
    """Lets the sampler stop the workers between calls and know when all of them stopped."""

    def __init__(self, workers):
        self.workers = workers
        self.idle = 0
        self.paused = False
        self.changed = threading.Condition()

    def between_calls(self):
        """Called by a worker between two calls: waits here while the load is paused."""
        with self.changed:
            if not self.paused:
                return
            self.idle += 1
            self.changed.notify_all()
            self.changed.wait_for(lambda: not self.paused)
            self.idle -= 1

    def worker_done(self):
        with self.changed:
            self.workers -= 1
            self.changed.notify_all()

    def stop_all(self, timeout_s):
        """Pauses the load; True once every worker waits between calls."""
        with self.changed:
            self.paused = True
            return self.changed.wait_for(lambda: self.idle >= self.workers, timeout=timeout_s)

    def resume(self):
        with self.changed:
            self.paused = False
            self.changed.notify_all()


def note(kind, outcome, expected):
    with lock:
        counts[kind + ":" + outcome] += 1
        if outcome not in expected:
            errors[kind + ":" + outcome] += 1


def phonemes(n, seed):
    rng = random.Random(seed)
    t, out = 0, []
    for i in range(n):
        d = rng.randint(40, 160) * 1000
        out.append(pb.Phoneme(label=LABELS[i % len(LABELS)] if i else "sil", start_us=t, end_us=t + d))
        t += d
    return out


def animate(stub, settings, chunks, cancel_after=None, timeout=30):
    def requests():
        yield pb.AnimateRequest(settings=settings)
        for chunk in chunks:
            yield pb.AnimateRequest(phonemes=pb.PhonemeChunk(phonemes=chunk))
        yield pb.AnimateRequest(end=pb.EndOfUtterance())
    call = stub.Animate(requests(), timeout=timeout)
    try:
        for i, _ in enumerate(call):
            if cancel_after is not None and i >= cancel_after:
                call.cancel()
        return "OK"
    except grpc.RpcError as error:
        return error.code().name


def stream(stub, n, rng):
    name = "soak-%d-%d" % (threading.get_ident(), n)
    ps = phonemes(60, n)
    outcome = animate(stub, pb.AnimationSettings(session=name), [ps[i:i + 6] for i in range(0, 60, 6)])
    note("stream", outcome, {"OK"})
    return name


def follower(stub, session):
    try:
        for _ in stub.Subscribe(pb.SubscribeRequest(session=session), timeout=30):
            pass
        note("follower", "OK", {"OK"})
    except grpc.RpcError as error:
        note("follower", error.code().name, {"OK", "NOT_FOUND", "ABORTED"})


def staller(stub, n):
    name = "stall-%d-%d" % (threading.get_ident(), n)
    produced = threading.Thread(target=lambda: note(
        "stall-producer", animate(stub, pb.AnimationSettings(session=name), [phonemes(400, n)]), {"OK"}))
    produced.start()
    time.sleep(0.2)  # the producer has opened the session
    call = stub.Subscribe(pb.SubscribeRequest(session=name), timeout=30)
    try:
        next(call)
        time.sleep(2.0)  # not reading: the server cuts it off, then cancels it
        for _ in call:
            pass
        note("staller", "OK", {"OK", "RESOURCE_EXHAUSTED", "CANCELLED"})
    except StopIteration:
        note("staller", "OK", {"OK"})
    except grpc.RpcError as error:
        note("staller", error.code().name, {"OK", "RESOURCE_EXHAUSTED", "CANCELLED", "NOT_FOUND", "ABORTED"})
    produced.join()


def bad(stub, n):
    kind = n % 5
    if kind == 0:
        outcome = animate(stub, pb.AnimationSettings(), [[pb.Phoneme(label="XQ", start_us=0, end_us=1000)]])
        note("bad-label", outcome, {"INVALID_ARGUMENT"})
    elif kind == 1:
        outcome = animate(stub, pb.AnimationSettings(model="no-such-model"), [])
        note("bad-model", outcome, {"INVALID_ARGUMENT"})
    elif kind == 2:
        outcome = animate(stub, pb.AnimationSettings(), [[pb.Phoneme(label="x" * (1 << 20), start_us=0, end_us=1000)]])
        note("bad-huge-label", outcome, {"INVALID_ARGUMENT"})
    elif kind == 3:
        outcome = animate(stub, pb.AnimationSettings(), [[pb.Phoneme(label="x" * (5 << 20), start_us=0, end_us=1000)]])
        note("bad-oversize", outcome, {"RESOURCE_EXHAUSTED", "CANCELLED"})
    else:
        try:
            list(stub.Subscribe(pb.SubscribeRequest(session="nobody-%d" % n), timeout=10))
            note("bad-subscribe", "OK", {"NOT_FOUND"})
        except grpc.RpcError as error:
            note("bad-subscribe", error.code().name, {"NOT_FOUND"})


def face(stub, n):
    settings = pb.AnimationSettings()
    settings.outputs.mesh.enabled = True
    settings.outputs.mesh.subdivision = 0
    outcome = animate(stub, settings, [phonemes(12, n)], timeout=60)
    # DEADLINE_EXCEEDED: the face fell more than --mesh-max-lag-ms behind real time, as it
    # may on a machine busy with other work (docs/server.md); the soak runs beside other tests.
    note("face", outcome, {"OK", "DEADLINE_EXCEEDED"})


def render(stub, n):
    try:
        stub.Render(pb.RenderRequest(phonemes=phonemes(30, n)), timeout=30)
        stub.GetModel(pb.GetModelRequest(name=""), timeout=10)
        note("render", "OK", {"OK"})
    except grpc.RpcError as error:
        note("render", error.code().name, {"OK"})


def worker(address, role, deadline, seed, pause):
    channel = grpc.insecure_channel(address, options=[("grpc.max_send_message_length", -1),
                                                      ("grpc.max_receive_message_length", -1)])
    stub = rpc.LipSyncStub(channel)
    rng = random.Random(seed)
    n = 0
    while time.time() < deadline:
        pause.between_calls()
        if time.time() >= deadline:
            break
        n += 1
        if role == "stream":
            name = stream(stub, n, rng)
        elif role == "follow":
            follower(stub, "soak-followed")
        elif role == "staller":
            staller(stub, n)
        elif role == "cancel":
            note("cancel", animate(stub, pb.AnimationSettings(session="cancel-%d-%d" % (seed, n)),
                                   [phonemes(200, n)[i:i + 10] for i in range(0, 200, 10)], cancel_after=3),
                 {"CANCELLED", "OK"})
        elif role == "bad":
            bad(stub, n)
        elif role == "face":
            face(stub, n)
        elif role == "render":
            render(stub, n)
        elif role == "produce-followed":
            ps = phonemes(60, n)
            note("followed", animate(stub, pb.AnimationSettings(session="soak-followed"),
                                     [ps[i:i + 3] for i in range(0, 60, 3)]), {"OK", "ALREADY_EXISTS"})
        time.sleep(0.01)
    channel.close()
    pause.worker_done()


def scrape(metrics_address):
    with urllib.request.urlopen("http://%s/metrics" % metrics_address, timeout=10) as response:
        return response.read().decode()


def gauge_total(exposition, name):
    """The sum of every sample of the gauge `name` in a text exposition."""
    pattern = re.compile(r"^%s(\{[^}]*\})? (\S+)$" % re.escape(name), re.M)
    return sum(float(value) for _, value in pattern.findall(exposition))


def server_is_quiet(metrics_address):
    exposition = scrape(metrics_address)
    return gauge_total(exposition, "lipsyncd_calls_in_progress") == 0 and gauge_total(exposition, "lipsyncd_sessions") == 0


def rss_kb(pid):
    with open("/proc/%d/status" % pid) as status:
        return int(re.search(r"^VmRSS:\s+(\d+) kB", status.read(), re.M).group(1))


def quiet_sample(pause, metrics_address, pid, started):
    """Pauses the load, waits for a quiet server, reads (seconds since start, rss kB, fds)."""
    try:
        if not pause.stop_all(timeout_s=90):
            raise RuntimeError("the workers did not all finish their calls within 90 s")
        waited_until = time.time() + 30
        while not server_is_quiet(metrics_address):
            if time.time() > waited_until:
                raise RuntimeError("calls or sessions still held 30 s after the load paused")
            time.sleep(0.1)
        return time.time() - started, rss_kb(pid), len(os.listdir("/proc/%d/fd" % pid))
    finally:
        pause.resume()


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("address")
    parser.add_argument("metrics_address")
    parser.add_argument("pid", type=int)
    parser.add_argument("seconds", type=float)
    parser.add_argument("--quiet-every", type=float, default=10)
    parser.add_argument("--warmup", type=float, default=20)
    parser.add_argument("--rss-slack-mb", type=float, default=16)
    parser.add_argument("--fd-slack", type=int, default=8)
    args = parser.parse_args()

    started = time.time()
    deadline = started + args.seconds
    roles = ["stream", "stream", "produce-followed", "follow", "staller", "cancel", "bad", "face", "render"]
    pause = Pause(len(roles))
    threads = [threading.Thread(target=worker, args=(args.address, role, deadline, i, pause))
               for i, role in enumerate(roles)]
    for thread in threads:
        thread.start()
    samples, failures = [], []
    while time.time() + args.quiet_every < deadline:
        time.sleep(args.quiet_every)
        try:
            seconds, rss, fds = quiet_sample(pause, args.metrics_address, args.pid, started)
        except (RuntimeError, OSError) as error:
            failures.append("no quiet sample: %s" % error)
            break
        samples.append((seconds, rss, fds))
        print("quiet: t=%.0fs rss=%.1fMB fds=%d" % (seconds, rss / 1024, fds), flush=True)
    for thread in threads:
        thread.join()
    print("calls: " + " ".join("%s=%d" % item for item in sorted(counts.items())))
    if errors:
        failures.append("unexpected statuses: " + " ".join("%s=%d" % item for item in sorted(errors.items())))

    judged = [(rss, fds) for seconds, rss, fds in samples if seconds >= args.warmup]
    rss_series = [rss for rss, _ in judged]
    if rss_series:
        print("quiet samples after the warm-up (%.0f s): %d; rss min %.1f median %.1f max %.1f MB; fds %d..%d"
              % (args.warmup, len(judged), min(rss_series) / 1024, statistics.median(rss_series) / 1024,
                 max(rss_series) / 1024, min(f for _, f in judged), max(f for _, f in judged)))
    if len(judged) >= 3:
        first, last = lowest_of_thirds(rss_series)
        print("lowest rss of the first third %.1f MB, of the last third %.1f MB (slack %.0f MB)"
              % (first / 1024, last / 1024, args.rss_slack_mb))
    failures += judge(rss_series, [fds for _, fds in judged], args.rss_slack_mb * 1024, args.fd_slack)
    for failure in failures:
        print("soak: " + failure)
    sys.exit(1 if failures else 0)


if __name__ == "__main__":
    main()

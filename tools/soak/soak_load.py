"""Mixed load for tools/soak.sh: worker threads that loop, until the deadline, over
the kinds of calls a real lipsyncd sees, good and bad:

  stream      Animate with a session name (60 phonemes), read to the end
  follower    Subscribe to a session being produced, read to the end
  staller     Subscribe, read the header, then stop reading (cut off, then cancelled)
  cancel      Animate that the client cancels half way
  bad         requests the server must refuse: unknown label, unknown model,
              a 1 MB label, a message over --max-message-bytes, Subscribe to nothing
  face        Animate with the mesh output (subdivision 0)
  render      Render and GetModel

Every call's outcome is counted; a status the call should not get is an error.
Prints one line of counts at the end; exit status 1 if any call got a status it
should not have. Run with Debian's /usr/bin/python3 (python3-grpcio) and
PYTHONPATH=<build>/clients/python/generated.
"""
import random
import sys
import threading
import time
from collections import Counter

import grpc
from lipsync.v1 import lipsync_pb2 as pb
from lipsync.v1 import lipsync_pb2_grpc as rpc

LABELS = ["sil", "P", "AA", "M", "IY", "F", "AO", "R", "T", "UW", "B", "EH", "S", "sil"]
counts = Counter()
errors = Counter()
lock = threading.Lock()


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
    note("face", animate(stub, settings, [phonemes(12, n)], timeout=60), {"OK"})


def render(stub, n):
    try:
        stub.Render(pb.RenderRequest(phonemes=phonemes(30, n)), timeout=30)
        stub.GetModel(pb.GetModelRequest(name=""), timeout=10)
        note("render", "OK", {"OK"})
    except grpc.RpcError as error:
        note("render", error.code().name, {"OK"})


def worker(address, role, deadline, seed):
    channel = grpc.insecure_channel(address, options=[("grpc.max_send_message_length", -1),
                                                      ("grpc.max_receive_message_length", -1)])
    stub = rpc.LipSyncStub(channel)
    rng = random.Random(seed)
    n = 0
    while time.time() < deadline:
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


def main():
    address, seconds = sys.argv[1], float(sys.argv[2])
    deadline = time.time() + seconds
    roles = ["stream", "stream", "produce-followed", "follow", "staller", "cancel", "bad", "face", "render"]
    threads = [threading.Thread(target=worker, args=(address, role, deadline, i)) for i, role in enumerate(roles)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    print("calls: " + " ".join("%s=%d" % item for item in sorted(counts.items())))
    if errors:
        print("unexpected: " + " ".join("%s=%d" % item for item in sorted(errors.items())))
        sys.exit(1)


if __name__ == "__main__":
    main()

"""Exit time after SIGTERM as a user sees it (docs/server.md, "Shutdown"): from the
client's receipt of the last call's status to the end of the lipsyncd process, on a
machine made busy.

Each run starts lipsyncd, makes the face threads work (one mesh Render), starts BUSY
processes that spin (default 3: more than the 2 cores), opens an Animate stream, sends
SIGTERM, then ends the stream: the drain waits for it. The time from the stream's
final status to waitpid's return is the exit time. Prints each run and p50/p95/max.

  /usr/bin/python3 tools/perf/shutdown_timing.py BUILD_DIR [RUNS] [BUSY] [-- lipsyncd flags]

Needs PYTHONPATH=BUILD_DIR/clients/python/generated (the stubs the build makes).
"""
import os
import signal
import subprocess
import sys
import time

import grpc
from lipsync.v1 import lipsync_pb2 as pb
from lipsync.v1 import lipsync_pb2_grpc as rpc


def phonemes(count):
    labels = ["sil", "P", "AA", "M", "IY", "F", "AO", "R"]
    return [pb.Phoneme(label=labels[i % len(labels)], start_us=i * 80_000, end_us=(i + 1) * 80_000)
            for i in range(count)]


def one_run(binary, busy_count, flags):
    server = subprocess.Popen([binary, "--listen", "127.0.0.1:0", "--log-level", "warn"] + flags,
                              stdout=subprocess.PIPE, text=True)
    address = server.stdout.readline().strip().rsplit(" ", 1)[-1]
    channel = grpc.insecure_channel(address)
    stub = rpc.LipSyncStub(channel)
    mesh = pb.AnimationSettings()
    mesh.outputs.mesh.enabled = True
    mesh.outputs.mesh.subdivision = 0
    stub.Render(pb.RenderRequest(settings=mesh, phonemes=phonemes(6)), timeout=60)
    busy = [subprocess.Popen(["/bin/sh", "-c", "while :; do :; done"]) for _ in range(busy_count)]
    try:
        time.sleep(0.2)  # the busy processes are running
        ending = [False]

        def requests():
            yield pb.AnimateRequest(settings=pb.AnimationSettings())
            yield pb.AnimateRequest(phonemes=pb.PhonemeChunk(phonemes=phonemes(10)))
            while not ending[0]:
                time.sleep(0.005)
            yield pb.AnimateRequest(end=pb.EndOfUtterance())

        call = stub.Animate(requests(), timeout=60)
        next(call)  # the header: the call is running
        server.send_signal(signal.SIGTERM)
        time.sleep(0.1)  # the drain has begun and waits for the stream
        ending[0] = True
        for _ in call:
            pass
        assert call.code() == grpc.StatusCode.OK, call.code()
        last_status = time.monotonic()
        _, status = os.waitpid(server.pid, 0)
        exited = time.monotonic()
        server.returncode = os.waitstatus_to_exitcode(status)
        assert server.returncode == 0, server.returncode
        return (exited - last_status) * 1000
    finally:
        for process in busy:
            process.kill()
            process.wait()
        channel.close()
        if server.returncode is None:
            server.kill()
            server.wait()


def percentile(sorted_values, fraction):
    return sorted_values[min(len(sorted_values) - 1, int(round(fraction * (len(sorted_values) - 1))))]


def main():
    args = sys.argv[1:]
    flags = args[args.index("--") + 1:] if "--" in args else []
    args = args[:args.index("--")] if "--" in args else args
    build = args[0]
    runs = int(args[1]) if len(args) > 1 else 20
    busy = int(args[2]) if len(args) > 2 else 3
    times = []
    for run in range(runs):
        times.append(one_run(os.path.join(build, "server", "lipsyncd"), busy, flags))
        print("run %d: %.1f ms" % (run, times[-1]), flush=True)
    times.sort()
    print("exit after the last status, %d runs, %d busy processes: p50 %.1f ms, p95 %.1f ms, max %.1f ms"
          % (runs, busy, percentile(times, 0.5), percentile(times, 0.95), times[-1]))


if __name__ == "__main__":
    main()

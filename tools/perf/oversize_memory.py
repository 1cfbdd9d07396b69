#!/usr/bin/python3
"""Resident memory of lipsyncd while parallel clients send oversize messages.

Starts a fresh lipsyncd per run (so that its peak, VmHWM, is this run's), has
STREAMS Animate streams send one message of MESSAGE_MB megabytes each at the same
time (a settings message whose `model` is that long: any field does, gRPC refuses
the message by its size before lipsyncd decodes it), waits for every call to end,
and reports resident memory before, the peak, and 2 s after the calls ended, with
the status each client received. Extra lipsyncd flags follow `--`.

  PYTHONPATH=build/clients/python/generated /usr/bin/python3 tools/perf/oversize_memory.py \\
      --lipsyncd build/server/lipsyncd --runs 3 -- --transport-memory-bytes 67108864

lipsyncd's default quota follows the calls in progress (server/src/transport/transport_quota.hpp);
`-- --transport-memory-bytes 0` runs it without one.

Figures: docs/server.md, "Memory for oversize messages".
"""
import argparse
import collections
import os
import subprocess
import sys
import threading
import time

import grpc

from lipsync.v1 import lipsync_pb2, lipsync_pb2_grpc

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir, os.pardir, "tests", "support"))
from listening_address import listening_address  # noqa: E402


def status_kib(pid, field):
    with open(f"/proc/{pid}/status") as status:
        for line in status:
            if line.startswith(field + ":"):
                return int(line.split()[1])
    raise RuntimeError(f"no {field} in /proc/{pid}/status")


def start_server(binary, flags):
    server = subprocess.Popen([binary, "--listen", "127.0.0.1:0", "--log-level", "warn", *flags],
                              stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:
        line = server.stdout.readline()
        address = listening_address(line)
        if address:
            return server, address
        if not line and server.poll() is not None:
            break
    server.kill()
    raise RuntimeError(f"{binary} did not start (exit {server.poll()})")


def send_one(address, message_bytes, outcomes):
    # A connection of its own per stream (gRPC Python would otherwise share one subchannel).
    channel = grpc.insecure_channel(address, options=[("grpc.max_send_message_length", -1),
                                                       ("grpc.max_receive_message_length", -1),
                                                       ("grpc.use_local_subchannel_pool", 1)])
    stub = lipsync_pb2_grpc.LipSyncStub(channel)
    request = lipsync_pb2.AnimateRequest()
    request.settings.model = "x" * message_bytes
    try:
        for _ in stub.Animate(iter([request]), timeout=120):
            pass
        outcomes.append("OK")
    except grpc.RpcError as error:
        outcomes.append(f"{error.code().name}: {error.details()[:60]}")
    finally:
        channel.close()


def one_run(binary, flags, streams, message_bytes):
    server, address = start_server(binary, flags)
    try:
        time.sleep(0.5)
        before = status_kib(server.pid, "VmRSS")
        outcomes = []
        threads = [threading.Thread(target=send_one, args=(address, message_bytes, outcomes))
                   for _ in range(streams)]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
        time.sleep(2.0)
        peak = status_kib(server.pid, "VmHWM")
        after = status_kib(server.pid, "VmRSS")
        return before, peak, after, outcomes
    finally:
        server.terminate()
        server.wait(timeout=30)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--lipsyncd", default="build/server/lipsyncd")
    parser.add_argument("--streams", type=int, default=3)
    parser.add_argument("--message-mb", type=int, default=100)
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("flags", nargs="*", help="lipsyncd flags, after --")
    args = parser.parse_args()
    if not 1 <= args.streams <= 64 or not 1 <= args.message_mb <= 1024 or not 1 <= args.runs <= 20:
        sys.exit("oversize_memory: --streams 1..64, --message-mb 1..1024, --runs 1..20")
    print(f"lipsyncd {' '.join(args.flags) or '(defaults)'}: {args.streams} streams x {args.message_mb} MB")
    print("run  before MB  peak MB  after MB  statuses")
    for run in range(1, args.runs + 1):
        before, peak, after, outcomes = one_run(args.lipsyncd, args.flags, args.streams,
                                                args.message_mb * 1000 * 1000)
        counted = ", ".join(f"{n} x {text}" for text, n in collections.Counter(outcomes).items())
        print(f"{run:3d}  {before / 1024:9.0f}  {peak / 1024:7.0f}  {after / 1024:8.0f}  {counted}")


if __name__ == "__main__":
    main()

"""A real lipsyncd for the Python client's tests: started on 127.0.0.1:0 from the LIPSYNCD
environment variable, its address read from the line it prints, stopped after the test class.
A missing or unstartable server FAILS the tests (never skips); every wait has a timeout."""

import os
import queue
import subprocess
import sys
import tempfile
import threading
import time
import unittest

import grpc

from lipsync_client import Client

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir, os.pardir, os.pardir,
                                "tests", "support"))
from listening_address import listening_address  # noqa: E402

STARTUP_TIMEOUT_S = 30.0
RPC_TIMEOUT_S = 30.0


class LipsyncdTestCase(unittest.TestCase):
    """Starts the lipsyncd named by LIPSYNCD on 127.0.0.1:0 for the test class, connects `client`
    to it, and stops it after the class; `set_up_class` runs once the client is ready."""
    server = None
    address = ""

    @classmethod
    def setUpClass(cls):
        path = os.environ.get("LIPSYNCD", "")
        if not path:
            raise AssertionError(
                "LIPSYNCD is not set: it must name the lipsyncd binary (ctest sets it from the "
                "CMake target lipsyncd)"
            )
        if not (os.path.isfile(path) and os.access(path, os.X_OK)):
            raise AssertionError(
                f"lipsyncd binary not found or not executable at {path!r}: build the CMake target "
                "lipsyncd first (cmake --build <build> --target lipsyncd)"
            )
        cls.stderr_file = tempfile.TemporaryFile(mode="w+")
        cls.server = subprocess.Popen(
            [path, "--listen", "127.0.0.1:0"],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=cls.stderr_file,
            text=True,
        )
        lines = queue.Queue()

        def drain():  # keeps reading so that the server never blocks on a full pipe
            for line in cls.server.stdout:
                lines.put(line)
            lines.put(None)

        threading.Thread(target=drain, daemon=True).start()
        deadline = time.monotonic() + STARTUP_TIMEOUT_S
        seen = []
        while True:
            remaining = deadline - time.monotonic()
            try:
                line = lines.get(timeout=max(remaining, 0.01))
            except queue.Empty:
                line = ""
            if line is None or (line == "" and remaining <= 0):
                output = "".join(seen) + cls._server_stderr()
                cls._stop_server()
                raise AssertionError(
                    f"lipsyncd ({path}) did not print 'lipsyncd listening on HOST:PORT' within "
                    f"{STARTUP_TIMEOUT_S:g} s (exit status {cls.server.returncode}); its output:\n"
                    f"{output}"
                )
            seen.append(line)
            address = listening_address(line)
            if address:
                cls.address = address
                break
        cls.client = Client(cls.address, timeout=RPC_TIMEOUT_S)
        try:
            cls.client.wait_ready(timeout=RPC_TIMEOUT_S)
        except grpc.FutureTimeoutError:
            cls._stop_server()
            raise AssertionError(f"could not connect to lipsyncd at {cls.address}") from None
        cls.set_up_class()

    @classmethod
    def set_up_class(cls):
        """What a test class needs besides the server (nothing here)."""

    @classmethod
    def _server_stderr(cls):
        cls.stderr_file.seek(0)
        return cls.stderr_file.read()

    @classmethod
    def _stop_server(cls):
        if cls.server is None or cls.server.poll() is not None:
            return
        cls.server.terminate()
        try:
            cls.server.wait(timeout=10)
        except subprocess.TimeoutExpired:
            cls.server.kill()
            cls.server.wait(timeout=10)

    @classmethod
    def tearDownClass(cls):
        if getattr(cls, "client", None) is not None:
            cls.client.close()
        cls._stop_server()
        if cls.server is not None and cls.server.stdout is not None:
            cls.server.stdout.close()

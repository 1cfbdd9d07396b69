"""A real lipsyncd for the Python client's tests: started on 127.0.0.1:0 from the LIPSYNCD
environment variable, its address read from the line it prints, stopped after the test class.
A missing or unstartable server FAILS the tests (never skips); every wait has a timeout."""

import os
import sys
import unittest

import grpc

from lipsync_client import Client

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir, os.pardir, os.pardir,
                                "tests", "support"))
from listening_address import ServerProcess  # noqa: E402

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
        try:
            cls.server = ServerProcess([path, "--listen", "127.0.0.1:0"], timeout_s=STARTUP_TIMEOUT_S)
        except RuntimeError as error:
            raise AssertionError(f"lipsyncd did not start: {error}") from None
        cls.address = cls.server.address
        cls.client = Client(cls.address, timeout=RPC_TIMEOUT_S)
        try:
            cls.client.wait_ready(timeout=RPC_TIMEOUT_S)
        except grpc.FutureTimeoutError:
            cls.server.stop()
            raise AssertionError(f"could not connect to lipsyncd at {cls.address}") from None
        cls.set_up_class()

    @classmethod
    def set_up_class(cls):
        """What a test class needs besides the server (nothing here)."""

    @classmethod
    def tearDownClass(cls):
        if getattr(cls, "client", None) is not None:
            cls.client.close()
        if cls.server is not None:
            cls.server.stop()

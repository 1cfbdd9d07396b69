"""The Python client's TLS and API key options against the REAL lipsyncd, run with
mutual TLS and a key file (certificates made by openssl at test time with
tests/support/make_test_certs.sh; the key file holds SHA-256 hashes only).

Environment: LIPSYNCD (the lipsyncd binary) and PYTHONPATH, as for test_live_server.
A missing server FAILS these tests (never skips).
"""

import hashlib
import json
import os
import subprocess
import sys
import tempfile
import time
import unittest

import grpc

from lipsync_client import Client

HERE = os.path.dirname(os.path.abspath(__file__))
SUPPORT = os.path.join(HERE, os.pardir, os.pardir, os.pardir, "tests", "support")
sys.path.insert(0, SUPPORT)
from listening_address import ServerProcess  # noqa: E402

MAKE_CERTS = os.path.join(SUPPORT, "make_test_certs.sh")
KEY = "python-test-key-0001"
PHONEMES = [("pau", 0, 200_000), ("p", 200_000, 260_000), ("iy", 260_000, 400_000), ("pau", 400_000, 600_000)]


class MutualTlsWithKeysTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        path = os.environ.get("LIPSYNCD", "")
        if not (path and os.access(path, os.X_OK)):
            raise AssertionError(f"LIPSYNCD must name the lipsyncd binary, got {path!r}")
        cls.work = tempfile.TemporaryDirectory(prefix="lipsync-python-tls-")
        cls.certs = os.path.join(cls.work.name, "certs")
        subprocess.run(["bash", MAKE_CERTS, cls.certs], check=True, timeout=60)
        keys = os.path.join(cls.work.name, "keys.json")
        with open(keys, "w") as file:
            json.dump({"tenants": {"py": {"max_streams": 4}},
                       "keys": [{"tenant": "py", "sha256": hashlib.sha256(KEY.encode()).hexdigest()}]}, file)
        try:
            cls.server = ServerProcess(
                [path, "--listen", "127.0.0.1:0", "--tls-cert", cls.cert("server.pem"), "--tls-key",
                 cls.cert("server.key"), "--tls-client-ca", cls.cert("ca.pem"), "--api-keys", keys])
        except RuntimeError as error:
            raise AssertionError(f"lipsyncd did not start: {error}") from None
        cls.address = cls.server.address

    @classmethod
    def tearDownClass(cls):
        cls.server.stop()
        cls.work.cleanup()

    @classmethod
    def cert(cls, name):
        return os.path.join(cls.certs, name)

    def client(self, **options):
        return Client(self.address, timeout=5, **options)

    def test_a_client_with_the_ca_its_certificate_and_a_key_renders(self):
        with self.client(ca=self.cert("ca.pem"), cert=self.cert("client.pem"), key=self.cert("client.key"),
                         api_key=KEY) as client:
            track = client.render(PHONEMES, phone_set="radio")
        self.assertGreater(len(track.frames), 0)
        self.assertEqual(track.summary.frames, len(track.frames))

    def test_the_api_key_comes_from_lipsync_api_key_when_not_given(self):
        os.environ["LIPSYNC_API_KEY"] = KEY
        try:
            with self.client(ca=self.cert("ca.pem"), cert=self.cert("client.pem"),
                             key=self.cert("client.key")) as client:
                self.assertGreaterEqual(len(client.list_models()), 1)
        finally:
            del os.environ["LIPSYNC_API_KEY"]

    def test_without_a_key_the_call_is_unauthenticated(self):
        with self.client(ca=self.cert("ca.pem"), cert=self.cert("client.pem"), key=self.cert("client.key"),
                         api_key="") as client:
            with self.assertRaises(grpc.RpcError) as raised:
                client.render(PHONEMES, phone_set="radio")
        self.assertEqual(raised.exception.code(), grpc.StatusCode.UNAUTHENTICATED)

    def test_plaintext_a_foreign_ca_and_no_client_certificate_are_refused(self):
        refused = {
            "plaintext": {},
            "foreign CA": {"ca": self.cert("other-ca.pem"), "cert": self.cert("client.pem"),
                           "key": self.cert("client.key")},
            "no client certificate": {"ca": self.cert("ca.pem")},
            "foreign client certificate": {"ca": self.cert("ca.pem"), "cert": self.cert("other-client.pem"),
                                           "key": self.cert("other-client.key")},
        }
        for name, options in refused.items():
            with self.subTest(name), self.client(api_key=KEY, **options) as client:
                with self.assertRaises(grpc.RpcError) as raised:
                    client.list_models()
                self.assertEqual(raised.exception.code(), grpc.StatusCode.UNAVAILABLE)

    def test_an_unreadable_ca_file_is_named(self):
        with self.assertRaisesRegex(ValueError, "/nonexistent/ca.pem"):
            Client(self.address, ca="/nonexistent/ca.pem")


if __name__ == "__main__":
    unittest.main()

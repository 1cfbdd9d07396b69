"""Builds lipsync_client with the gRPC stubs of lipsync.v1 generated into the wheel.

protoc (Debian: protobuf-compiler) and grpc_python_plugin (protobuf-compiler-grpc) generate
lipsync/v1/lipsync_pb2.py and lipsync_pb2_grpc.py from proto/ at the top of the checkout
(or $LIPSYNC_PROTO_DIR). The metadata is in pyproject.toml.
"""

import os
import pathlib
import shutil
import subprocess

from setuptools import setup
from setuptools.command.build_py import build_py

HERE = pathlib.Path(__file__).resolve().parent
PROTO = "lipsync/v1/lipsync.proto"


class BuildPyWithStubs(build_py):
    def run(self):
        super().run()
        proto_dir = pathlib.Path(os.environ.get("LIPSYNC_PROTO_DIR", HERE.parent.parent / "proto"))
        if not (proto_dir / PROTO).is_file():
            raise SystemExit(f"lipsync-client: {proto_dir / PROTO} not found (set LIPSYNC_PROTO_DIR)")
        protoc = shutil.which("protoc")
        plugin = shutil.which("grpc_python_plugin") or "/usr/bin/grpc_python_plugin"
        if protoc is None or not os.path.exists(plugin):
            raise SystemExit(
                "lipsync-client: protoc and grpc_python_plugin are needed to generate the stubs "
                "(apt-get install protobuf-compiler protobuf-compiler-grpc)"
            )
        out = pathlib.Path(self.build_lib)
        subprocess.run(
            [protoc, f"-I{proto_dir}", f"--python_out={out}", f"--grpc_python_out={out}",
             f"--plugin=protoc-gen-grpc_python={plugin}", PROTO],
            check=True,
        )


setup(cmdclass={"build_py": BuildPyWithStubs})

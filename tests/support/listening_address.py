"""The address a server started on port 0 announces on its standard output: lipsyncd prints
"lipsyncd listening on HOST:PORT" (server/src/main.cpp), the bare gRPC server of the benchmarks
"listening on HOST:PORT" (tests/bench/grpc_baseline_server.cpp). The same line is read by
tests/support/listening_address.sh in shell scripts and by wait_for_listening_address in
tests/support/child_process.hpp in C++.

Python's standard library only, so that any script may import it: scripts outside this folder put
it on their path first,

    sys.path.insert(0, os.path.join(ROOT, "tests", "support"))
    from listening_address import listening_address
"""
import re

_LINE = re.compile(r"(?:lipsyncd )?listening on (\S+:\d+)")


def listening_address(line):
    """HOST:PORT when `line` is a server's "listening on" line, else None."""
    match = _LINE.match(line)
    return match.group(1) if match else None

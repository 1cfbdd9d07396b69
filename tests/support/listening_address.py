"""The address a server started on port 0 announces on its standard output: lipsyncd prints
"lipsyncd listening on HOST:PORT" (server/src/main.cpp), the bare gRPC server of the benchmarks
"listening on HOST:PORT" (tests/bench/grpc_baseline_server.cpp). The same line is read by
tests/support/listening_address.sh in shell scripts and by wait_for_listening_address in
tests/support/child_process.hpp in C++.

Python's standard library only, so that any script may import it: scripts outside this folder put
it on their path first,

    sys.path.insert(0, os.path.join(ROOT, "tests", "support"))
    from listening_address import listening_address, ServerProcess
"""
import queue
import re
import subprocess
import tempfile
import threading

_LINE = re.compile(r"(?:lipsyncd )?listening on (\S+:\d+)")


def listening_address(line):
    """HOST:PORT when `line` is a server's "listening on" line, else None."""
    match = _LINE.match(line)
    return match.group(1) if match else None


class ServerProcess:
    """A server started on port 0 (`argv`), for a test or a tool: `address` is HOST:PORT from its
    "listening on" line; next_line() reads what it prints after that (lipsyncd's viewer line);
    stop() (or leaving a `with` block) ends it. RuntimeError, with what it wrote on standard error,
    when it exits or says nothing within `timeout_s`."""

    def __init__(self, argv, timeout_s=30):
        self._errors = tempfile.TemporaryFile(mode="w+")
        self.process = subprocess.Popen(argv, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                        stderr=self._errors, text=True)
        self._lines = queue.Queue()
        threading.Thread(target=self._read, daemon=True).start()
        self.address = None
        while self.address is None:
            line = self.next_line(timeout_s)
            if line is None:
                try:
                    exited = self.process.wait(timeout=1)  # its standard output closed: it is ending
                except subprocess.TimeoutExpired:
                    exited = None
                self.stop()
                self._errors.seek(0)
                why = (f"exited with status {exited} before saying" if exited is not None
                       else f"did not say within {timeout_s} s")
                raise RuntimeError(f"{argv[0]} {why} where it listens: {self._errors.read()[-2000:]}")
            self.address = listening_address(line)

    def _read(self):
        for line in self.process.stdout:
            self._lines.put(line)
        self._lines.put(None)

    def next_line(self, timeout_s=30):
        """The next line the server prints; None when it has ended or said nothing for `timeout_s`."""
        try:
            return self._lines.get(timeout=timeout_s)
        except queue.Empty:
            return None

    def stop(self):
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait(timeout=10)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.stop()

"""Timed phonemes from a text-to-speech front-end: flite or Festival.

Both tools speak Festival's "radio" phone set (lowercase ARPAbet without stress
digits, plus ax axr dx el em en nx hv and the silences pau h# brth), so send
what they give with ``phone_set="radio"``.

Times are converted to integer microseconds from the decimal text the tools
print, digit by digit (``decimal.Decimal``), never through a binary float:
"0.171" is exactly 171000 µs. Beyond 6 decimals the value is rounded half away
from zero, as lipsyncd's own readers do.

    >>> parse_flite_psdur("pau:0.171 s:0.285 p:0.341")
    [TimedPhoneme(label='pau', start_us=0, end_us=171000), TimedPhoneme(label='s', start_us=171000, end_us=285000), TimedPhoneme(label='p', start_us=285000, end_us=341000)]
"""

from __future__ import annotations

import decimal
import os
import shutil
import subprocess
import tempfile
from typing import List, NamedTuple, Optional

__all__ = [
    "TimedPhoneme",
    "TTSError",
    "TTSUnavailableError",
    "seconds_to_us",
    "parse_flite_psdur",
    "parse_festival_segments",
    "flite_phonemes",
    "festival_phonemes",
    "timed_phonemes",
]

#: Longest time accepted (24 hours), as lipsyncd does.
MAX_TIME_US = 24 * 3600 * 1_000_000


class TimedPhoneme(NamedTuple):
    """One phoneme: a label and its interval in integer microseconds."""

    label: str
    start_us: int
    end_us: int


class TTSError(RuntimeError):
    """The front-end failed or printed something that is not timed phonemes."""


class TTSUnavailableError(TTSError, FileNotFoundError):
    """The front-end program is not installed (or not on PATH)."""


def seconds_to_us(text: str) -> int:
    """Converts a decimal number of seconds ("0.171", "1.5e-3") to integer µs, exactly.

    Rounds half away from zero beyond the 6th decimal. Raises ValueError for
    anything that is not a finite, non-negative decimal number up to 24 hours.
    """
    try:
        seconds = decimal.Decimal(text.strip())
    except decimal.InvalidOperation:
        raise ValueError(f"not a number of seconds: {text!r}") from None
    if not seconds.is_finite():
        raise ValueError(f"not a finite number of seconds: {text!r}")
    if seconds < 0:
        raise ValueError(f"negative time: {text!r}")
    if seconds > MAX_TIME_US // 1_000_000:
        raise ValueError(f"time beyond 24 hours: {text!r} (seconds expected)")
    micros = (seconds.scaleb(6)).quantize(decimal.Decimal(1), rounding=decimal.ROUND_HALF_UP)
    return int(micros)


def parse_flite_psdur(output: str) -> List[TimedPhoneme]:
    """Parses ``flite -psdur`` output: ``label:end_seconds`` tokens, start = previous end.

    The first phoneme starts at 0. Raises TTSError on a malformed token or on
    end times that go backwards.
    """
    phonemes: List[TimedPhoneme] = []
    previous_end = 0
    for token in output.split():
        label, colon, end_text = token.rpartition(":")
        if not colon:
            raise TTSError(f"flite: expected 'label:end_seconds', found {token!r}")
        if not label:
            raise TTSError(f"flite: missing label before ':' in {token!r}")
        try:
            end_us = seconds_to_us(end_text)
        except ValueError as error:
            raise TTSError(f"flite: end time of {label!r}: {error}") from None
        if end_us < previous_end:
            raise TTSError(
                f"flite: end time of {label!r} ({end_text} s) is before the previous end"
            )
        phonemes.append(TimedPhoneme(label, previous_end, end_us))
        previous_end = end_us
    return phonemes


def parse_festival_segments(output: str) -> List[TimedPhoneme]:
    """Parses ``label start_seconds end_seconds`` lines (what festival_phonemes' script prints)."""
    phonemes: List[TimedPhoneme] = []
    for number, line in enumerate(output.splitlines(), 1):
        fields = line.split()
        if not fields:
            continue
        if len(fields) != 3:
            raise TTSError(f"festival: line {number}: expected 'label start end', found {line!r}")
        label, start_text, end_text = fields
        try:
            start_us = seconds_to_us(start_text)
            end_us = seconds_to_us(end_text)
        except ValueError as error:
            raise TTSError(f"festival: line {number}: {error}") from None
        if end_us < start_us:
            raise TTSError(f"festival: line {number}: {label!r} ends before it starts")
        if phonemes and start_us < phonemes[-1].end_us:
            raise TTSError(f"festival: line {number}: {label!r} overlaps the previous segment")
        phonemes.append(TimedPhoneme(label, start_us, end_us))
    return phonemes


def _find_program(program: str, package: str) -> str:
    path = shutil.which(program)
    if path is None:
        raise TTSUnavailableError(
            f"{program!r} not found on PATH: install the Debian package '{package}' "
            f"(apt-get install {package})"
        )
    return path


def _run(command: List[str], timeout: float, name: str) -> "subprocess.CompletedProcess[str]":
    try:
        result = subprocess.run(
            command, capture_output=True, text=True, timeout=timeout, check=False
        )
    except subprocess.TimeoutExpired:
        raise TTSError(f"{name} did not finish within {timeout:g} s") from None
    if result.returncode != 0:
        raise TTSError(
            f"{name} failed (exit status {result.returncode}): {result.stderr.strip()[-500:]}"
        )
    return result


def flite_phonemes(
    text: str, voice: str = "slt", flite: str = "flite", timeout: float = 30.0
) -> List[TimedPhoneme]:
    """Timed phonemes of `text` from ``flite -voice VOICE -psdur -t TEXT -o none``.

    Raises TTSUnavailableError if flite is not installed, TTSError if it fails.
    """
    program = _find_program(flite, "flite")
    result = _run([program, "-voice", voice, "-psdur", "-t", text, "-o", "none"], timeout, "flite")
    phonemes = parse_flite_psdur(result.stdout)
    if not phonemes:
        raise TTSError(f"flite printed no phonemes for {text!r}")
    return phonemes


def _scheme_string(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


_FESTIVAL_SCRIPT = """\
(load (path-append datadir "init.scm"))
({voice})
(set! lipsync_u (eval (list 'Utterance 'Text {text})))
(Initialize lipsync_u) (Text lipsync_u) (Token_POS lipsync_u) (Token lipsync_u)
(POS lipsync_u) (Phrasify lipsync_u) (Word lipsync_u) (Pauses lipsync_u)
(Intonation lipsync_u) (PostLex lipsync_u) (Duration lipsync_u)
(mapcar
  (lambda (s)
    (format t "%s %s %s\\n" (item.name s) (item.feat s "segment_start") (item.feat s "end")))
  (utt.relation.items lipsync_u 'Segment))
"""


def festival_phonemes(
    text: str,
    voice: str = "kal_diphone",
    festival: str = "festival",
    timeout: float = 60.0,
) -> List[TimedPhoneme]:
    """Timed phonemes of `text` from Festival (segment start and end, no audio synthesised).

    `voice` names a Festival voice without the ``voice_`` prefix (Debian's
    festvox-kallpc16k gives ``kal_diphone``). Raises TTSUnavailableError if
    festival is not installed, TTSError if it fails.
    """
    program = _find_program(festival, "festival")
    script = _FESTIVAL_SCRIPT.format(voice="voice_" + voice, text=_scheme_string(text))
    fd, path = tempfile.mkstemp(prefix="lipsync-festival-", suffix=".scm")
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as handle:
            handle.write(script)
        result = _run([program, "--script", path], timeout, "festival")
    finally:
        os.unlink(path)
    # Festival reports Scheme errors ("SIOD ERROR: ...") and still exits 0.
    errors = result.stderr.strip()
    if "error" in errors.lower():
        raise TTSError(f"festival: {errors[-500:]}")
    phonemes = parse_festival_segments(result.stdout)
    if not phonemes:
        raise TTSError(f"festival printed no segments for {text!r}: {errors[-500:]}")
    return phonemes


def timed_phonemes(text: str, frontend: str = "auto", voice: Optional[str] = None) -> List[TimedPhoneme]:
    """Timed phonemes of `text` ("radio" phone set) from `frontend`: "flite", "festival"
    or "auto" (flite if installed, else Festival)."""
    if frontend == "flite" or (frontend == "auto" and shutil.which("flite")):
        return flite_phonemes(text, voice=voice or "slt")
    if frontend in ("festival", "auto"):
        try:
            return festival_phonemes(text, voice=voice or "kal_diphone")
        except TTSUnavailableError:
            if frontend == "auto":
                raise TTSUnavailableError(
                    "neither flite nor festival is installed: "
                    "apt-get install flite (or festival festvox-kallpc16k)"
                ) from None
            raise
    raise ValueError(f"unknown front-end {frontend!r} (flite, festival or auto)")

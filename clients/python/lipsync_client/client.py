"""A thin client for lipsyncd's gRPC API (lipsync.v1.LipSync).

    with Client("127.0.0.1:50051") as client:
        track = client.render([("pau", 0, 200000), ("p", 200000, 260000), ...], phone_set="radio")
        for frame in client.animate(chunks_from_my_tts(), phone_set="radio", session="demo"):
            ...
        for frame in client.subscribe("demo"):
            ...
        speech = client.speak("Papa parked the car.", session="demo")   # voice and face
        speech.write_wav("speech.wav"); speech.track.frames ...
        for frame in client.listen(pcm_pieces(), sample_rate_hz=16000, session="demo"):
            ...                                                         # audio in, face out

Phonemes may be given as ``(label, start_us, end_us)`` tuples, as objects with
``label``, ``start_us`` and ``end_us`` attributes (``lipsync_client.tts.TimedPhoneme``),
or as ``lipsync_pb2.Phoneme`` messages. Times are integer microseconds.

Settings (keyword arguments of render, animate, speak and listen; all optional, defaults are the server's):
    model (str), fps (int, 1..240), phone_set (str: arpabet, radio, timit, ipa, espeak,
    sampa), lookahead (int, 0..7; unset = 7, exact), fixed_rate (bool),
    closure_fraction (float in (0, 1)), channels (bool), arkit (bool) (which outputs the
    frames carry; neither set = both), session (str, animate only: publish under this
    name), media_clock ((clock_name, utterance_zero_us)), mesh (bool: also the simulated
    face's vertices, Frame.mesh), mesh_subdivision (int, 0..2; unset = 1), mesh_encoding
    ("float32" or "int16": int16 halves the bytes, error <= half the header's
    quantisation_scale_m, about 2.1 µm; Frame.mesh is decoded to metres either way),
    mesh_blinks (bool; unset = True: the face's upper lids blink on lipsyncd's seeded schedule;
    False keeps the eyes open, for clients that drive the eyes themselves), mesh_solve
    ("full" or "fast": about 0.45 of the server's CPU per face, closures still sealed; docs/face.md),
    visemes (str: "oculus", "azure", "polly" or "rhubarb": also the viseme weights,
    Frame.visemes, and events, Frame.viseme_event and Track.viseme_events()),
    rhubarb_extended_shapes (str, rhubarb only: Rhubarb's --extendedShapes letters; unset = "GHX").

Listen's own keyword arguments (the audio and how to hear it): sample_rate_hz,
audio_channels, encoding ("pcm_s16le" or "wav"), transcript, voice, latency_ms, recording;
see Client.listen. (`channels` stays the output selector above, as in every call.)

Security (docs/security.md): plaintext by default. ``Client(target, ca="ca.pem")``
(or ``tls=True`` for the system's roots) connects with TLS; ``cert=`` and ``key=``
add a client certificate for a server that requires one (mTLS). ``api_key=`` (default:
the environment variable LIPSYNC_API_KEY) is sent as ``authorization: Bearer <key>``
on every call.

Errors are the server's: every call raises ``grpc.RpcError`` (use ``.code()`` and
``.details()``), e.g. INVALID_ARGUMENT for a bad phoneme, DEADLINE_EXCEEDED when
the call outlasts its timeout. Every call has a deadline (`timeout`, seconds).
"""

from __future__ import annotations

import bisect
import collections
import dataclasses
import os
import struct
import threading
import time
import wave
from typing import Any, Dict, Iterable, Iterator, List, Optional, Sequence, Tuple

import grpc

try:
    from lipsync.v1 import lipsync_pb2, lipsync_pb2_grpc
except ImportError as _error:  # pragma: no cover - depends on the environment
    raise ImportError(
        "lipsync_client needs the generated gRPC stubs (package lipsync.v1): build the CMake "
        "target lipsync_python_stubs and put <build>/clients/python/generated on PYTHONPATH "
        f"(see docs/python-client.md); import failed with: {_error}"
    ) from _error

__all__ = [
    "Client", "make_channel", "Frame", "FrameStream", "ListenStream", "BatchArrival", "Speech", "Track",
    "make_settings", "KIND_NAMES", "VISEME_VOCABULARIES", "AUDIO_ENCODINGS",
]

#: FrameKind enum values to the short names used in Frame.kind.
KIND_NAMES: Dict[int, str] = {
    lipsync_pb2.FRAME_KIND_UNSPECIFIED: "unspecified",
    lipsync_pb2.FRAME_KIND_UNIFORM: "uniform",
    lipsync_pb2.FRAME_KIND_CLOSURE_START: "closure_start",
    lipsync_pb2.FRAME_KIND_CLOSURE_END: "closure_end",
    lipsync_pb2.FRAME_KIND_SHORT_SEGMENT: "short_segment",
}

#: The `visemes` setting's names to the VisemeVocabulary enum.
VISEME_VOCABULARIES: Dict[str, int] = {
    "oculus": lipsync_pb2.VISEME_VOCABULARY_OCULUS,
    "azure": lipsync_pb2.VISEME_VOCABULARY_AZURE,
    "polly": lipsync_pb2.VISEME_VOCABULARY_POLLY,
    "rhubarb": lipsync_pb2.VISEME_VOCABULARY_RHUBARB,
}

#: The `encoding` argument of Client.listen to the AudioEncoding enum.
AUDIO_ENCODINGS: Dict[str, int] = {
    "pcm_s16le": lipsync_pb2.AUDIO_ENCODING_PCM_S16LE,
    "wav": lipsync_pb2.AUDIO_ENCODING_WAV,
}

DEFAULT_TIMEOUT_S = 60.0
DEFAULT_CHUNK_SIZE = 16
# Pieces of an attached audio file (animate(audio=...)), and the largest piece listen() sends (it
# splits bigger ones): within lipsyncd's default message limit (4 MiB).
AUDIO_PIECE_BYTES = 1024 * 1024


@dataclasses.dataclass(frozen=True)
class Frame:
    """One animation frame.

    index: position in the track (0-based); t_us: utterance time in integer µs;
    kind: "uniform", "closure_start", "closure_end" or "short_segment";
    channels: model channel name -> value (empty if not selected);
    arkit: ARKit blendshape name (Apple's spelling, e.g. "jawOpen") -> weight;
    mesh: with the mesh output, the face's vertex positions in metres, flat
    [x0, y0, z0, x1, ...] (header.mesh.vertex_count × 3; topology in header.mesh), else None;
    visemes: with the viseme output, viseme name (header.viseme_names) -> weight, else None;
    viseme_event: the name of the viseme whose event starts at this frame, else None.
    """

    index: int
    t_us: int
    kind: str
    channels: Dict[str, float]
    arkit: Dict[str, float]
    mesh: Optional[List[float]] = None
    visemes: Optional[Dict[str, float]] = None
    viseme_event: Optional[str] = None


@dataclasses.dataclass
class Track:
    """A whole track: the header, the frames and the summary (protobuf messages for
    header and summary: lipsync_pb2.TrackHeader, lipsync_pb2.TrackSummary)."""

    header: Any
    frames: List[Frame]
    summary: Any

    def viseme_events(self) -> List[Tuple[str, int]]:
        """The viseme events as (viseme name, start_us), in time order (empty without visemes)."""
        return [(f.viseme_event, f.t_us) for f in self.frames if f.viseme_event is not None]


@dataclasses.dataclass
class Speech:
    """What a Speak call returned: the speech and its track on one utterance clock
    (audio sample n plays at n * 10**6 / sample_rate_hz µs, frame t_us at t_us).

    header: lipsync_pb2.SpeakHeader (audio format, the phonemes animated, header.track the
    frames' TrackHeader); pcm: the whole audio, mono signed 16-bit little-endian bytes;
    track: the frames as a Track; summary: lipsync_pb2.SpeakSummary.
    """

    header: Any
    pcm: bytes
    track: Track
    summary: Any

    @property
    def sample_rate_hz(self) -> int:
        return self.header.sample_rate_hz

    def samples(self) -> Tuple[int, ...]:
        """The audio as integers (-32768..32767)."""
        return struct.unpack(f"<{len(self.pcm) // 2}h", self.pcm)

    def write_wav(self, path: str) -> None:
        """Writes the audio as a 16-bit mono PCM WAV file."""
        with wave.open(path, "wb") as out:
            out.setnchannels(1)
            out.setsampwidth(2)
            out.setframerate(self.sample_rate_hz)
            out.writeframes(self.pcm)


SESSION_METADATA_KEY = "x-lipsync-session"


def session_metadata(session: str) -> Tuple[Tuple[str, str], ...]:
    """The metadata that lets a load balancer route a call to the replica holding
    `session` (docs/deploy.md); none for a private (unnamed) stream."""
    return ((SESSION_METADATA_KEY, session),) if session else ()


def _phoneme(item: Any) -> Any:
    if isinstance(item, lipsync_pb2.Phoneme):
        return item
    if hasattr(item, "label") and hasattr(item, "start_us") and hasattr(item, "end_us"):
        label, start_us, end_us = item.label, item.start_us, item.end_us
    else:
        try:
            label, start_us, end_us = item
        except (TypeError, ValueError):
            raise TypeError(
                f"a phoneme is (label, start_us, end_us) or has those attributes, not {item!r}"
            ) from None
    for name, value in (("start_us", start_us), ("end_us", end_us)):
        if isinstance(value, bool) or not isinstance(value, int):
            raise TypeError(f"phoneme {label!r}: {name} must be an integer count of µs, not {value!r}")
    return lipsync_pb2.Phoneme(label=str(label), start_us=start_us, end_us=end_us)


def _is_phoneme(item: Any) -> bool:
    if isinstance(item, lipsync_pb2.Phoneme) or hasattr(item, "label"):
        return True
    return (
        isinstance(item, (tuple, list)) and len(item) == 3 and isinstance(item[0], str)
    )


def make_settings(
    *,
    model: str = "",
    fps: int = 0,
    phone_set: str = "",
    lookahead: Optional[int] = None,
    fixed_rate: bool = False,
    closure_fraction: float = 0.0,
    channels: bool = False,
    arkit: bool = False,
    session: str = "",
    media_clock: Optional[Tuple[str, int]] = None,
    mesh: bool = False,
    mesh_subdivision: Optional[int] = None,
    mesh_encoding: str = "float32",
    mesh_blinks: bool = True,
    mesh_solve: str = "full",
    visemes: Optional[str] = None,
    rhubarb_extended_shapes: Optional[str] = None,
) -> Any:
    """Builds a lipsync_pb2.AnimationSettings from keyword arguments (see the module doc).
    Unknown keywords raise TypeError."""
    settings = lipsync_pb2.AnimationSettings(
        model=model,
        fps=fps,
        phone_set=phone_set,
        fixed_rate=fixed_rate,
        closure_fraction=closure_fraction,
        session=session,
    )
    if lookahead is not None:
        settings.lookahead = lookahead
    if channels or arkit:
        settings.outputs.channels = channels
        settings.outputs.arkit = arkit
    if mesh:
        settings.outputs.mesh.enabled = True
        if mesh_subdivision is not None:
            settings.outputs.mesh.subdivision = mesh_subdivision
        encodings = {"float32": lipsync_pb2.MESH_ENCODING_FLOAT32, "int16": lipsync_pb2.MESH_ENCODING_INT16}
        if mesh_encoding not in encodings:
            raise ValueError(f"mesh_encoding must be 'float32' or 'int16', not {mesh_encoding!r}")
        settings.outputs.mesh.encoding = encodings[mesh_encoding]
        settings.outputs.mesh.no_blinks = not mesh_blinks
        solves = {"full": lipsync_pb2.MESH_SOLVE_FULL, "fast": lipsync_pb2.MESH_SOLVE_FAST}
        if mesh_solve not in solves:
            raise ValueError(f"mesh_solve must be 'full' or 'fast', not {mesh_solve!r}")
        settings.outputs.mesh.solve = solves[mesh_solve]
    if visemes is not None:
        if visemes not in VISEME_VOCABULARIES:
            raise ValueError(f"visemes must be one of {', '.join(VISEME_VOCABULARIES)}, not {visemes!r}")
        settings.outputs.visemes.enabled = True
        settings.outputs.visemes.vocabulary = VISEME_VOCABULARIES[visemes]
    if rhubarb_extended_shapes is not None:
        settings.outputs.visemes.rhubarb_extended_shapes = rhubarb_extended_shapes
    if media_clock is not None:
        clock, zero_us = media_clock
        settings.media_clock.clock = clock
        settings.media_clock.utterance_zero_us = zero_us
    return settings


class _Decoder:
    """Turns FrameBatch messages into Frames, using the header's channel and ARKit names."""

    def __init__(self, header: Any) -> None:
        self.channel_names = list(header.channels)
        self.arkit_names = list(header.arkit_names)
        self.next_index = 0
        self.mesh_width = header.mesh.vertex_count * 3 if header.HasField("mesh") else 0
        self.mesh_int16 = self.mesh_width > 0 and header.mesh.encoding == lipsync_pb2.MESH_ENCODING_INT16
        self.mesh_scale = header.mesh.quantisation_scale_m
        self.mesh_offset = list(header.mesh.quantisation_offset_m)
        self.viseme_names = list(header.viseme_names)

    def _mesh(self, batch: Any, count: int) -> Optional[List[float]]:
        """All the batch's coordinates in metres (None without the mesh)."""
        if not self.mesh_width:
            return None
        if self.mesh_int16:
            data = batch.mesh_positions_int16
            if len(data) != count * self.mesh_width * 2 or len(self.mesh_offset) != 3:
                raise ValueError(f"malformed int16 mesh positions at frame {batch.first_frame}")
            q = struct.unpack(f"<{count * self.mesh_width}h", data)
            scale, offset = self.mesh_scale, self.mesh_offset
            return [offset[i % 3] + scale * value for i, value in enumerate(q)]
        if len(batch.mesh_positions) != count * self.mesh_width:
            raise ValueError(f"malformed mesh positions at frame {batch.first_frame}")
        return list(batch.mesh_positions)

    def frames(self, batch: Any) -> Iterator[Frame]:
        count = len(batch.t_us)
        width, arkit_width = len(self.channel_names), len(self.arkit_names)
        if len(batch.kinds) != count or len(batch.values) != count * width or len(
            batch.arkit
        ) != count * arkit_width:
            raise ValueError(
                f"malformed frame batch at frame {batch.first_frame}: {count} times, "
                f"{len(batch.kinds)} kinds, {len(batch.values)} values ({width} channels), "
                f"{len(batch.arkit)} ARKit weights ({arkit_width} names)"
            )
        values, arkit = batch.values, batch.arkit
        mesh, mesh_width = self._mesh(batch, count), self.mesh_width
        viseme_width, weights = len(self.viseme_names), batch.viseme_weights
        if len(weights) != count * viseme_width:
            raise ValueError(
                f"malformed frame batch at frame {batch.first_frame}: {len(weights)} viseme weights "
                f"for {count} frames of {viseme_width} visemes"
            )
        events = {}
        for event in batch.viseme_events:
            if event.viseme >= viseme_width:
                raise ValueError(f"viseme event at {event.start_us} µs names viseme {event.viseme} of {viseme_width}")
            events[event.start_us] = self.viseme_names[event.viseme]
        for i in range(count):
            yield Frame(
                index=batch.first_frame + i,
                t_us=batch.t_us[i],
                kind=KIND_NAMES.get(batch.kinds[i], str(batch.kinds[i])),
                channels=dict(zip(self.channel_names, values[i * width : (i + 1) * width])),
                arkit=dict(zip(self.arkit_names, arkit[i * arkit_width : (i + 1) * arkit_width])),
                mesh=None if mesh is None else mesh[i * mesh_width : (i + 1) * mesh_width],
                visemes=dict(zip(self.viseme_names, weights[i * viseme_width : (i + 1) * viseme_width]))
                if viseme_width
                else None,
                viseme_event=events.get(batch.t_us[i]),
            )
        self.next_index = batch.first_frame + count


class FrameStream:
    """The frames of an Animate or Subscribe call, as they arrive.

    Iterate over it to get Frames. `header` (lipsync_pb2.TrackHeader) is set once
    the header has arrived (before the first frame), `summary`
    (lipsync_pb2.TrackSummary) once the stream has ended. `cancel()` ends the call.
    Iteration raises grpc.RpcError if the call fails.
    """

    def __init__(self, call: Any) -> None:
        self._call = call
        self.header: Any = None
        self.summary: Any = None
        self._decoder: Optional[_Decoder] = None

    def __iter__(self) -> Iterator[Frame]:
        for message in self._call:
            kind = message.WhichOneof("kind")
            if kind == "header":
                self.header = message.header
                self._decoder = _Decoder(message.header)
            elif kind == "frames":
                if self._decoder is None:
                    raise ValueError("the server sent frames before the track header")
                self._on_batch(message.frames)
                yield from self._decoder.frames(message.frames)
            elif kind == "summary":
                self.summary = message.summary

    def _on_batch(self, batch: Any) -> None:
        """Called as each FrameBatch arrives, before its frames are yielded."""

    def cancel(self) -> None:
        self._call.cancel()

    def collect(self) -> Track:
        """Reads the whole stream into a Track."""
        frames = list(self)
        return Track(self.header, frames, self.summary)


@dataclasses.dataclass(frozen=True)
class BatchArrival:
    """One frame batch of a Listen stream, as it arrived.

    first_index, count: the batch's frames (Frame.index first_index .. first_index + count - 1);
    first_t_us, last_t_us: their times; received_s: time.monotonic() when the batch arrived;
    release_lag_us: the server's FrameBatch.release_lag_us (how far the audio it had decoded
    reached past first_t_us when it sent the batch).
    """

    first_index: int
    count: int
    first_t_us: int
    last_t_us: int
    received_s: float
    release_lag_us: int


@dataclasses.dataclass(frozen=True)
class Words:
    """More of a Listen stream's transcript, yielded among its audio pieces (a TTS that speaks an
    LLM's reply sentence by sentence): `text`, words as written, or `timed`, (word, start_us)
    pairs with the times the TTS gave them (µs from the stream's first sample, in order). The
    stream's `transcript` must be set ("" when every word comes this way)."""

    text: str = ""
    timed: Sequence[Tuple[str, int]] = ()

    def request(self) -> Any:
        if self.text and self.timed:
            raise ValueError("Words takes text or timed words, not both")
        return lipsync_pb2.ListenRequest(words=lipsync_pb2.ListenWords(
            text=self.text,
            timed=[lipsync_pb2.TimedWord(text=word, start_us=int(start_us)) for word, start_us in self.timed],
        ))


class ListenStream(FrameStream):
    """The frames of a Listen call, as they arrive: a FrameStream (iterate it for Frames;
    `header`, `summary`, `cancel()`, `collect()`) that also keeps the times for measuring
    latency on this machine's monotonic clock (time.monotonic()):

    `arrivals`: a BatchArrival per frame batch received, in order;
    `sent_at(t_us)`: when the audio piece holding utterance time t_us was handed to gRPC
    (raw PCM only; None for a WAV stream or before that piece was sent);
    `latency_s(frame)`: from sent_at(frame.t_us) to the arrival of the frame's batch.
    (About 100 bytes per piece and 250 per batch: some 7 MB for 10 minutes of 20 ms pieces.)

    An exception raised while reading `chunks` (a piece that is not bytes-like: TypeError; the
    audio source's own error) ends the call and is raised from iteration (gRPC itself would only
    say "Exception iterating requests!"). The server's errors raise grpc.RpcError.
    """

    def __init__(self, bytes_per_frame: int, sample_rate_hz: int) -> None:
        super().__init__(None)
        self.arrivals: List[BatchArrival] = []
        self._arrival_firsts: List[int] = []  # arrivals' first_index, for bisect
        self._bytes_per_frame = bytes_per_frame  # 0: the times of the audio are not known here
        self._sample_rate_hz = sample_rate_hz
        self._lock = threading.Lock()
        self._sent_end_us: List[int] = []  # end of the audio sent so far after each piece, µs
        self._sent_s: List[float] = []  # when each piece was handed over
        self._sent_bytes = 0
        self._request_error: Optional[BaseException] = None

    def _piece_sent(self, size: int) -> None:
        """On gRPC's request thread: a piece of `size` bytes is being handed over now."""
        now = time.monotonic()
        self._sent_bytes += size
        if not self._bytes_per_frame or not self._sample_rate_hz:
            return
        end_us = (self._sent_bytes // self._bytes_per_frame) * 1_000_000 // self._sample_rate_hz
        with self._lock:
            self._sent_end_us.append(end_us)
            self._sent_s.append(now)

    def sent_at(self, t_us: int) -> Optional[float]:
        """time.monotonic() when the piece holding utterance time t_us left (the last piece
        for a time past the audio sent); None if unknown."""
        with self._lock:
            if not self._sent_s:
                return None
            i = bisect.bisect_right(self._sent_end_us, t_us)
            return self._sent_s[min(i, len(self._sent_s) - 1)]

    def latency_s(self, frame: Frame) -> Optional[float]:
        """Seconds from sending the audio at frame.t_us to receiving the frame; None if unknown."""
        sent = self.sent_at(frame.t_us)
        i = bisect.bisect_right(self._arrival_firsts, frame.index) - 1
        if sent is None or i < 0 or frame.index >= self.arrivals[i].first_index + self.arrivals[i].count:
            return None
        return self.arrivals[i].received_s - sent

    def _on_batch(self, batch: Any) -> None:
        if len(batch.t_us) == 0:
            return
        self._arrival_firsts.append(batch.first_frame)
        self.arrivals.append(BatchArrival(
            first_index=batch.first_frame, count=len(batch.t_us), first_t_us=batch.t_us[0],
            last_t_us=batch.t_us[-1], received_s=time.monotonic(), release_lag_us=batch.release_lag_us,
        ))

    def __iter__(self) -> Iterator[Frame]:
        try:
            yield from super().__iter__()
        except grpc.RpcError as error:
            if self._request_error is not None:
                raise self._request_error from error
            raise


AUTHORIZATION_METADATA_KEY = "authorization"


class _CallDetails(
    collections.namedtuple(
        "_CallDetails", ("method", "timeout", "metadata", "credentials", "wait_for_ready", "compression")
    ),
    grpc.ClientCallDetails,
):
    pass


class _ApiKeyInterceptor(
    grpc.UnaryUnaryClientInterceptor,
    grpc.UnaryStreamClientInterceptor,
    grpc.StreamUnaryClientInterceptor,
    grpc.StreamStreamClientInterceptor,
):
    """Adds `authorization: Bearer <key>` to every call (call credentials would need TLS;
    a server behind a TLS-terminating proxy sees plaintext)."""

    def __init__(self, api_key: str) -> None:
        self._entry = (AUTHORIZATION_METADATA_KEY, "Bearer " + api_key)

    def _details(self, details: Any) -> Any:
        metadata = list(details.metadata or ()) + [self._entry]
        return _CallDetails(
            details.method, details.timeout, metadata, details.credentials,
            getattr(details, "wait_for_ready", None), getattr(details, "compression", None),
        )

    def intercept_unary_unary(self, continuation, details, request):  # type: ignore[no-untyped-def]
        return continuation(self._details(details), request)

    def intercept_unary_stream(self, continuation, details, request):  # type: ignore[no-untyped-def]
        return continuation(self._details(details), request)

    def intercept_stream_unary(self, continuation, details, requests):  # type: ignore[no-untyped-def]
        return continuation(self._details(details), requests)

    def intercept_stream_stream(self, continuation, details, requests):  # type: ignore[no-untyped-def]
        return continuation(self._details(details), requests)


def _read_pem(what: str, path: Optional[str]) -> Optional[bytes]:
    if path is None:
        return None
    try:
        with open(path, "rb") as file:
            return file.read()
    except OSError as error:
        raise ValueError(f"cannot read the {what} {path!r}: {error.strerror}") from error


def make_channel(
    target: str,
    *,
    tls: bool = False,
    ca: Optional[str] = None,
    cert: Optional[str] = None,
    key: Optional[str] = None,
) -> grpc.Channel:
    """A channel to lipsyncd: plaintext, or TLS when `tls` or any file is given (`ca`: PEM
    bundle that signed the server's certificate, default the system's roots; `cert` and
    `key`: a PEM client certificate and its key, for mTLS). Raises ValueError naming a file
    that cannot be read, or a certificate without its key."""
    if not (tls or ca or cert or key):
        return grpc.insecure_channel(target)
    if bool(cert) != bool(key):
        raise ValueError("a client certificate needs its key and a key its certificate (cert= and key=)")
    credentials = grpc.ssl_channel_credentials(
        root_certificates=_read_pem("CA file", ca),
        private_key=_read_pem("client key", key),
        certificate_chain=_read_pem("client certificate", cert),
    )
    return grpc.secure_channel(target, credentials)


class Client:
    """A connection to lipsyncd.

    target: "host:port", or pass a ready `channel`.
    timeout: default deadline of every call, in seconds (a whole stream for
    Animate and Subscribe).
    tls, ca, cert, key: TLS (see make_channel); plaintext by default.
    api_key: sent as `authorization: Bearer <key>` on every call; default: the
    environment variable LIPSYNC_API_KEY, else none.
    """

    def __init__(
        self,
        target: str = "127.0.0.1:50051",
        *,
        timeout: float = DEFAULT_TIMEOUT_S,
        channel: Optional[grpc.Channel] = None,
        tls: bool = False,
        ca: Optional[str] = None,
        cert: Optional[str] = None,
        key: Optional[str] = None,
        api_key: Optional[str] = None,
    ) -> None:
        self._channel = (
            channel if channel is not None else make_channel(target, tls=tls, ca=ca, cert=cert, key=key)
        )
        self._owns_channel = channel is None
        if api_key is None:
            api_key = os.environ.get("LIPSYNC_API_KEY") or None
        self._transport = self._channel
        if api_key:
            self._channel = grpc.intercept_channel(self._channel, _ApiKeyInterceptor(api_key))
        self.timeout = timeout
        self.stub = lipsync_pb2_grpc.LipSyncStub(self._channel)

    def close(self) -> None:
        if self._owns_channel:
            self._transport.close()

    def __enter__(self) -> "Client":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def wait_ready(self, timeout: Optional[float] = None) -> None:
        """Blocks until the channel is connected; raises grpc.FutureTimeoutError otherwise."""
        grpc.channel_ready_future(self._transport).result(
            timeout=self.timeout if timeout is None else timeout
        )

    def render(
        self, phonemes: Iterable[Any], *, timeout: Optional[float] = None, **settings: Any
    ) -> Track:
        """Renders a whole utterance at once (unary Render) and returns its Track."""
        settings.pop("session", None)  # ignored by Render
        request = lipsync_pb2.RenderRequest(
            settings=make_settings(**settings), phonemes=[_phoneme(p) for p in phonemes]
        )
        response = self.stub.Render(request, timeout=self.timeout if timeout is None else timeout)
        decoder = _Decoder(response.header)
        frames = list(decoder.frames(response.frames)) if response.HasField("frames") else []
        return Track(response.header, frames, response.summary)

    def animate(
        self,
        phonemes: Iterable[Any],
        *,
        timeout: Optional[float] = None,
        chunk_size: int = DEFAULT_CHUNK_SIZE,
        audio: Optional[bytes] = None,
        **settings: Any,
    ) -> FrameStream:
        """Streams one utterance (bidirectional Animate) and returns its FrameStream.

        `phonemes` is either an iterable of phonemes (sent in chunks of
        `chunk_size`) or an iterable of chunks (each a sequence of phonemes or a
        lipsync_pb2.PhonemeChunk), sent one message per chunk as the iterable
        yields them: a generator fed by a streaming TTS front-end is read lazily,
        on gRPC's thread, while the frames come back. The end marker follows the
        last chunk.

        `audio`, the bytes of the utterance's WAV file, is attached to the
        session (`session=` is needed) before the first phonemes, in pieces of
        AUDIO_PIECE_BYTES: the session's viewers play it from lipsyncd
        (/audio?session=NAME).
        """
        if chunk_size < 1:
            raise ValueError("chunk_size must be at least 1")
        first_request = lipsync_pb2.AnimateRequest(settings=make_settings(**settings))
        if audio is not None and not first_request.settings.session:
            raise ValueError("audio needs session=: only a session keeps its audio")
        call = self.stub.Animate(
            self._requests(first_request, phonemes, chunk_size, audio or b""),
            timeout=self.timeout if timeout is None else timeout,
            metadata=session_metadata(first_request.settings.session),
        )
        return FrameStream(call)

    @staticmethod
    def _requests(first: Any, source: Iterable[Any], chunk_size: int, audio: bytes = b"") -> Iterator[Any]:
        yield first
        for offset in range(0, len(audio), AUDIO_PIECE_BYTES):
            yield lipsync_pb2.AnimateRequest(
                audio=lipsync_pb2.AudioAttachment(wav=audio[offset:offset + AUDIO_PIECE_BYTES])
            )
        pending: List[Any] = []
        for item in source:
            if _is_phoneme(item):
                pending.append(_phoneme(item))
                if len(pending) >= chunk_size:
                    yield lipsync_pb2.AnimateRequest(
                        phonemes=lipsync_pb2.PhonemeChunk(phonemes=pending)
                    )
                    pending = []
                continue
            if pending:
                yield lipsync_pb2.AnimateRequest(phonemes=lipsync_pb2.PhonemeChunk(phonemes=pending))
                pending = []
            if isinstance(item, lipsync_pb2.PhonemeChunk):
                chunk = item
            else:
                chunk = lipsync_pb2.PhonemeChunk(phonemes=[_phoneme(p) for p in item])
            yield lipsync_pb2.AnimateRequest(phonemes=chunk)
        if pending:
            yield lipsync_pb2.AnimateRequest(phonemes=lipsync_pb2.PhonemeChunk(phonemes=pending))
        yield lipsync_pb2.AnimateRequest(end=lipsync_pb2.EndOfUtterance())

    def listen(
        self,
        chunks: Iterable[Any],
        *,
        sample_rate_hz: int = 0,
        audio_channels: int = 0,
        encoding: str = "pcm_s16le",
        transcript: Optional[str] = None,
        voice: str = "",
        latency_ms: Optional[int] = None,
        recording: bool = False,
        timeout: Optional[float] = None,
        **settings: Any,
    ) -> ListenStream:
        """Sends speech as it is spoken (bidirectional Listen) and returns its ListenStream:
        the frames of what the server hears, as they arrive, while the audio is still going out.

        `chunks`: an iterable of audio pieces (bytes-like: bytes, bytearray, memoryview,
        array.array...), read lazily on gRPC's thread and each sent as soon as it is yielded
        (a generator reading a microphone or a TTS's pipe); or one bytes-like object, sent
        whole. Pieces over AUDIO_PIECE_BYTES are split; empty ones are skipped; `end` follows
        the last piece. Raw PCM pieces need not hold whole samples (the server joins them).
        Among the pieces, Words items add to the transcript as the TTS produces it (send
        them ahead of their audio: docs/streaming.md, "Transcripts that grow").

        sample_rate_hz: raw PCM's rate, 8000..48000 (required); for a WAV 0 or its header's.
        audio_channels: raw PCM's channels, 1 or 2 (interleaved, mixed down by the server);
            0 = 1; for a WAV 0 or its header's.
        encoding: "pcm_s16le" (raw signed 16-bit little-endian samples) or "wav" (a WAV file
            in pieces; live: 16-bit PCM, a streaming writer's unknown data size is read to the end).
        transcript: the words spoken, for forced alignment; None = recognised from the audio;
            "" = the words come later, as Words among the chunks.
        voice: "" or an English espeak-ng voice name ("en", "en-us", "en-gb"...).
        latency_ms: live only, 100..2000 (None = the server's 200): how far a frame may trail
            the audio it shows.
        recording: the audio is a whole recording: frames come after `end`, equal to
            `lipsync render X.wav` (with latency_ms left None).
        settings: as for animate (model, fps, channels/arkit, visemes, session, media_clock,
            lookahead for a recording); phone_set must stay "" or "arpabet"; no mesh.

        The call's deadline (`timeout`, default the client's) covers the whole stream: give a
        live microphone a long one.
        """
        if isinstance(chunks, str):
            raise TypeError("listen() takes audio as bytes-like pieces, not a str")
        if isinstance(chunks, (bytes, bytearray, memoryview)):
            chunks = (chunks,)
        if encoding not in AUDIO_ENCODINGS:
            raise ValueError(f"encoding must be one of {', '.join(AUDIO_ENCODINGS)}, not {encoding!r}")
        listen_settings = lipsync_pb2.ListenSettings(
            animation=make_settings(**settings),
            encoding=AUDIO_ENCODINGS[encoding],
            sample_rate_hz=sample_rate_hz,
            channels=audio_channels,
            voice=voice,
            recording=recording,
        )
        if transcript is not None:
            listen_settings.transcript = transcript
        if latency_ms is not None:
            listen_settings.latency_ms = latency_ms
        raw = encoding == "pcm_s16le"
        stream = ListenStream(2 * max(audio_channels, 1) if raw else 0, sample_rate_hz if raw else 0)
        stream._call = self.stub.Listen(
            self._listen_requests(lipsync_pb2.ListenRequest(settings=listen_settings), chunks, stream),
            timeout=self.timeout if timeout is None else timeout,
            metadata=session_metadata(listen_settings.animation.session),
        )
        return stream

    @staticmethod
    def _listen_requests(first: Any, chunks: Iterable[Any], stream: ListenStream) -> Iterator[Any]:
        yield first
        try:
            for index, piece in enumerate(chunks):
                if isinstance(piece, Words):
                    yield piece.request()
                    continue
                if isinstance(piece, str):
                    raise TypeError(f"audio piece {index} is a str: listen() takes bytes-like pieces")
                try:
                    view = memoryview(piece)
                except TypeError:
                    raise TypeError(
                        f"audio piece {index} is a {type(piece).__name__}, not bytes-like "
                        "(bytes, bytearray, memoryview)"
                    ) from None
                data = view.cast("B") if view.contiguous else memoryview(view.tobytes())
                for offset in range(0, len(data), AUDIO_PIECE_BYTES):
                    part = bytes(data[offset:offset + AUDIO_PIECE_BYTES])
                    stream._piece_sent(len(part))
                    yield lipsync_pb2.ListenRequest(audio=lipsync_pb2.ListenAudio(data=part))
        except Exception as error:  # gRPC would only say "Exception iterating requests!"
            stream._request_error = error
            raise
        yield lipsync_pb2.ListenRequest(end=lipsync_pb2.EndOfUtterance())

    def subscribe(
        self, session: str, from_beginning: bool = True, *, timeout: Optional[float] = None
    ) -> FrameStream:
        """Follows the frames of `session` (published by an Animate call with that
        session name): from what the server still holds, or only new frames."""
        start = (
            lipsync_pb2.SubscribeRequest.START_FROM_BEGINNING
            if from_beginning
            else lipsync_pb2.SubscribeRequest.START_FROM_NOW
        )
        call = self.stub.Subscribe(
            lipsync_pb2.SubscribeRequest(session=session, start=start),
            timeout=self.timeout if timeout is None else timeout,
            metadata=session_metadata(session),
        )
        return FrameStream(call)

    def speak(
        self,
        text: str,
        *,
        voice: str = "",
        words_per_minute: int = 0,
        timeout: Optional[float] = None,
        **settings: Any,
    ) -> Speech:
        """Has the server speak `text` with espeak-ng (Speak) and returns the audio and the
        track of what it spoke. voice: an espeak-ng voice ("" = en-us); words_per_minute:
        80..450 (0 = 175); settings as for animate (phone_set must stay "" or the voice's:
        "espeak" for English voices, "ipa" for the others; no mesh), session publishes the frames for subscribers."""
        request = lipsync_pb2.SpeakRequest(
            text=text, voice=voice, words_per_minute=words_per_minute, settings=make_settings(**settings)
        )
        call = self.stub.Speak(
            request,
            timeout=self.timeout if timeout is None else timeout,
            metadata=session_metadata(request.settings.session),
        )
        header, summary, decoder = None, None, None
        chunks: List[bytes] = []
        samples = 0
        frames: List[Frame] = []
        for message in call:
            kind = message.WhichOneof("kind")
            if kind == "header":
                header, decoder = message.header, _Decoder(message.header.track)
            elif decoder is None:
                raise ValueError("the server sent Speak content before the SpeakHeader")
            elif kind == "audio":
                if message.audio.first_sample != samples or len(message.audio.pcm) % 2:
                    raise ValueError(f"an audio chunk at sample {message.audio.first_sample} does not continue the audio")
                chunks.append(message.audio.pcm)
                samples += len(message.audio.pcm) // 2
            elif kind == "frames":
                frames.extend(decoder.frames(message.frames))
            elif kind == "summary":
                summary = message.summary
        pcm = b"".join(chunks)
        if header is None or len(pcm) != header.sample_count * 2:
            raise ValueError("the Speak stream ended before the whole audio arrived")
        return Speech(header, pcm, Track(header.track, frames, summary.track if summary else None), summary)

    def list_models(self, *, timeout: Optional[float] = None) -> List[Any]:
        """The models this server can animate with (lipsync_pb2.ModelInfo messages)."""
        response = self.stub.ListModels(
            lipsync_pb2.ListModelsRequest(), timeout=self.timeout if timeout is None else timeout
        )
        return list(response.models)

    def get_model(self, name: str = "", *, timeout: Optional[float] = None) -> Any:
        """One model's layout (lipsync_pb2.ModelInfo); "" = the default model."""
        return self.stub.GetModel(
            lipsync_pb2.GetModelRequest(name=name),
            timeout=self.timeout if timeout is None else timeout,
        )

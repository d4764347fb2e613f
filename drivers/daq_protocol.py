"""The DAQ board's wire protocol (docs/daq_protocol.md): frame codec, CRC, command set.

Pure bytes in, bytes or arrays out: no I/O, so the serial driver and the board
emulator share one definition and the byte-level tests check exactly what goes
on the wire.  Device -> host traffic is all framed (data and replies alike), so a
reply can arrive in the middle of a stream; host -> device commands are ASCII lines.
"""

from __future__ import annotations

import struct
import zlib
from dataclasses import dataclass

import numpy as np

SYNC = b"\xa5\x5a\xc3\x3c"
HEADER_FORMAT = "<BBHI"  # type, channel mask, payload length, first sample index
HEADER_SIZE = len(SYNC) + struct.calcsize(HEADER_FORMAT)  # 12
CRC_SIZE = 4
FRAME_OVERHEAD = HEADER_SIZE + CRC_SIZE  # 16

FRAME_DATA = 0x01
FRAME_REPLY = 0x02

MAX_ANALOG_CHANNELS = 4
MAX_SAMPLES_PER_FRAME = 1024
MAX_REPLY_BYTES = 1024
MAX_PAYLOAD = MAX_SAMPLES_PER_FRAME * (MAX_ANALOG_CHANNELS + 1) * 2
INDEX_MODULUS = 1 << 32  # the wire's first-sample index is a u32 that wraps

SAMPLE_DTYPE = np.dtype("<i2")  # analog counts and the digital word are 16-bit little-endian


class ProtocolError(ValueError):
    """Bytes or a command that do not follow docs/daq_protocol.md."""


def channels_to_mask(channels: tuple[int, ...]) -> int:
    """Channel mask byte: bit k set when analog channel k is in the frame."""
    mask = 0
    for channel in channels:
        if not 0 <= channel < MAX_ANALOG_CHANNELS:
            raise ProtocolError(
                f"analog channel {channel} does not exist (0..{MAX_ANALOG_CHANNELS - 1})"
            )
        mask |= 1 << channel
    return mask


def mask_to_channels(mask: int) -> tuple[int, ...]:
    """Analog channels present in a frame, in the order their counts appear per sample."""
    return tuple(k for k in range(MAX_ANALOG_CHANNELS) if mask >> k & 1)


def _frame(frame_type: int, mask: int, index: int, payload: bytes) -> bytes:
    body = struct.pack(HEADER_FORMAT, frame_type, mask, len(payload), index % INDEX_MODULUS)
    body += payload
    return SYNC + body + struct.pack("<I", zlib.crc32(body))


def encode_data_frame(
    first_index: int, channels: tuple[int, ...], analog: np.ndarray, digital: np.ndarray
) -> bytes:
    """One data frame: ``analog`` is (samples, channels) int16 counts, ``digital`` one word each.

    ``first_index`` is the board's running index of the first sample; it is sent
    modulo 2**32.
    """
    analog = np.asarray(analog)
    digital = np.asarray(digital)
    n_samples = digital.shape[0]
    if analog.shape != (n_samples, len(channels)):
        raise ProtocolError(
            f"analog block has shape {analog.shape}, expected ({n_samples}, {len(channels)})"
        )
    if not 1 <= n_samples <= MAX_SAMPLES_PER_FRAME:
        raise ProtocolError(f"{n_samples} samples in a frame (1..{MAX_SAMPLES_PER_FRAME})")
    records = np.empty((n_samples, len(channels) + 1), dtype=SAMPLE_DTYPE)
    records[:, :-1] = analog
    records[:, -1] = digital.astype(np.uint16).view(np.int16)
    return _frame(FRAME_DATA, channels_to_mask(channels), first_index, records.tobytes())


def encode_reply_frame(text: str) -> bytes:
    """A reply frame carrying one ASCII line (``OK ...`` or ``ERR ...``)."""
    payload = text.encode("ascii")
    if len(payload) > MAX_REPLY_BYTES:
        raise ProtocolError(f"reply of {len(payload)} bytes (at most {MAX_REPLY_BYTES})")
    return _frame(FRAME_REPLY, 0, 0, payload)


@dataclass(frozen=True)
class DataRun:
    """Consecutive good data frames with contiguous sample indices, decoded together."""

    first_index_wire: int  # u32 index of the first sample, as sent
    channels: tuple[int, ...]
    analog: np.ndarray  # (samples, channels) int16 counts
    digital: np.ndarray  # (samples,) uint16 digital lines
    frames: int

    @property
    def n_samples(self) -> int:
        """Samples in the run."""
        return int(self.digital.shape[0])


@dataclass
class ParseResult:
    """What one call of :meth:`FrameParser.feed` found, in arrival order per kind."""

    runs: list[DataRun]
    replies: list[str]
    frames_rejected: int = 0  # a sync word whose frame failed the CRC
    bytes_discarded: int = 0  # bytes skipped while looking for a sync word


@dataclass(frozen=True)
class _Located:
    start: int
    frame_type: int
    mask: int
    length: int
    index: int


class FrameParser:
    """Incremental frame parser: feed it whatever bytes arrived, get frames back.

    Resynchronises after garbage by scanning for the sync word; a candidate frame
    whose header is implausible or whose CRC fails is rejected and the scan
    resumes one byte after its sync word, so a real frame hidden behind a damaged
    one is still found.  Runs of good frames are decoded with one numpy view.
    """

    def __init__(self) -> None:
        self._pending = b""

    def feed(self, data: bytes) -> ParseResult:
        """Parse ``data`` after what was held back; an incomplete frame is kept for next time."""
        buf = self._pending + data if self._pending else bytes(data)
        result = ParseResult(runs=[], replies=[])
        located: list[_Located] = []
        pos = 0
        size = len(buf)
        while True:
            start = buf.find(SYNC, pos)
            if start < 0:
                keep = max(pos, size - (len(SYNC) - 1))  # a sync word may straddle reads
                result.bytes_discarded += keep - pos
                pos = keep
                break
            result.bytes_discarded += start - pos
            if size - start < HEADER_SIZE:
                pos = start
                break
            frame_type, mask, length, index = struct.unpack_from(HEADER_FORMAT, buf, start + 4)
            if not _plausible_header(frame_type, mask, length):
                result.bytes_discarded += 1
                pos = start + 1
                continue
            end = start + HEADER_SIZE + length + CRC_SIZE
            if end > size:
                pos = start
                break
            (crc,) = struct.unpack_from("<I", buf, end - CRC_SIZE)
            if zlib.crc32(buf[start + 4 : end - CRC_SIZE]) != crc:
                result.frames_rejected += 1
                result.bytes_discarded += 1
                pos = start + 1
                continue
            located.append(_Located(start, frame_type, mask, length, index))
            pos = end
        self._decode(buf, located, result)
        self._pending = buf[pos:]
        return result

    def _decode(self, buf: bytes, located: list[_Located], result: ParseResult) -> None:
        group: list[_Located] = []
        for frame in located:
            if frame.frame_type == FRAME_REPLY:
                start = frame.start + HEADER_SIZE
                text = buf[start : start + frame.length].decode("ascii", errors="replace")
                result.replies.append(text)
                continue
            if group and not _continues(group[-1], frame):
                result.runs.append(_decode_group(buf, group))
                group = []
            group.append(frame)
        if group:
            result.runs.append(_decode_group(buf, group))


def _plausible_header(frame_type: int, mask: int, length: int) -> bool:
    if frame_type == FRAME_REPLY:
        return mask == 0 and 0 < length <= MAX_REPLY_BYTES
    if frame_type != FRAME_DATA or mask == 0 or mask >> MAX_ANALOG_CHANNELS:
        return False
    record = (mask.bit_count() + 1) * 2
    return 0 < length <= MAX_PAYLOAD and length % record == 0


def _samples_in(frame: _Located) -> int:
    return frame.length // ((frame.mask.bit_count() + 1) * 2)


def _continues(previous: _Located, frame: _Located) -> bool:
    """True when ``frame`` directly follows ``previous`` in the buffer and in sample index."""
    return (
        frame.mask == previous.mask
        and frame.length == previous.length
        and frame.start == previous.start + FRAME_OVERHEAD + previous.length
        and frame.index == (previous.index + _samples_in(previous)) % INDEX_MODULUS
    )


def _decode_group(buf: bytes, group: list[_Located]) -> DataRun:
    """Decode equal, adjacent frames at once through a strided view of the buffer."""
    first = group[0]
    n_channels = first.mask.bit_count()
    per_frame = _samples_in(first)
    frame_size = FRAME_OVERHEAD + first.length
    view = np.ndarray(
        shape=(len(group), per_frame, n_channels + 1),
        dtype=SAMPLE_DTYPE,
        buffer=buf,
        offset=first.start + HEADER_SIZE,
        strides=(frame_size, (n_channels + 1) * 2, 2),
    )
    records = view.reshape(len(group) * per_frame, n_channels + 1)  # copies: strided frames
    return DataRun(
        first_index_wire=first.index,
        channels=mask_to_channels(first.mask),
        analog=records[:, :n_channels],
        digital=records[:, n_channels].view(np.uint16),
        frames=len(group),
    )


class IndexUnwrapper:
    """Turns the wire's u32 first-sample indices into the running 64-bit index.

    The gap to the expected index is taken modulo 2**32 (so a wrap is seamless and a
    loss shorter than 2**31 samples is counted exactly); a frame that would step
    backwards is refused (``None``): a board never repeats samples.
    """

    def __init__(self) -> None:
        self.next_index = 0

    def reset(self) -> None:
        """A new stream: indices start again at 0."""
        self.next_index = 0

    def unwrap(self, wire_index: int, n_samples: int) -> int | None:
        """Running index of a run of ``n_samples`` sent as ``wire_index``; None if it goes back."""
        skipped = (wire_index - self.next_index) % INDEX_MODULUS
        if skipped >= INDEX_MODULUS // 2:
            return None
        first = self.next_index + skipped
        self.next_index = first + n_samples
        return first


# --- commands (host -> device): one ASCII line each, answered by one reply frame ---

COMMAND_IDENTIFY = "IDN?"
COMMAND_CONFIGURE = "CONF"
COMMAND_QUERY_CONFIGURATION = "CONF?"
COMMAND_START = "START"
COMMAND_STOP = "STOP"
MAX_COMMAND_BYTES = 128


def encode_command(name: str, *arguments: str) -> bytes:
    """An ASCII command line terminated by LF, e.g. ``b'CONF 20000 0,1\\n'``."""
    line = " ".join((name, *arguments))
    if "\n" in line or "\r" in line or len(line) >= MAX_COMMAND_BYTES:
        raise ProtocolError(f"command {line!r} is not one line of < {MAX_COMMAND_BYTES} bytes")
    return line.encode("ascii") + b"\n"


def encode_configure(sample_rate_hz: float, channels: tuple[int, ...]) -> bytes:
    """``CONF <rate_hz> <channel list>`` e.g. ``CONF 20000 0,1,3``."""
    channels_to_mask(channels)  # validates the channel numbers
    return encode_command(
        COMMAND_CONFIGURE, f"{sample_rate_hz:.6g}", ",".join(str(c) for c in channels)
    )


@dataclass(frozen=True)
class Reply:
    """A parsed reply line: ``ok`` and its ``key=value`` fields, or the error text."""

    ok: bool
    fields: dict[str, str]
    text: str


def parse_reply(text: str) -> Reply:
    """Split ``OK key=value ...`` or ``ERR message``; anything else is a ProtocolError."""
    if text == "OK" or text.startswith("OK "):
        fields: dict[str, str] = {}
        for token in text[3:].split():
            key, sep, value = token.partition("=")
            if not sep:
                raise ProtocolError(f"reply field {token!r} is not key=value in {text!r}")
            fields[key] = value
        return Reply(ok=True, fields=fields, text=text)
    if text.startswith("ERR "):
        return Reply(ok=False, fields={}, text=text[4:])
    raise ProtocolError(f"reply {text!r} is neither 'OK ...' nor 'ERR ...'")


def format_fields(**fields: object) -> str:
    """``OK key=value ...`` reply text, in the order given."""
    return " ".join(["OK", *(f"{key}={value}" for key, value in fields.items())])


def format_channels(channels: tuple[int, ...]) -> str:
    """(0, 1, 3) -> ``'0,1,3'``, the channel list of commands and replies."""
    return ",".join(str(c) for c in channels)


def parse_channels(text: str) -> tuple[int, ...]:
    """``'0,1,3'`` -> (0, 1, 3); a ProtocolError names what is not a channel number."""
    try:
        channels = tuple(int(part) for part in text.split(","))
    except ValueError:
        raise ProtocolError(f"channel list {text!r} is not comma-separated integers") from None
    if len(set(channels)) != len(channels):
        raise ProtocolError(f"channel list {text!r} names a channel twice")
    channels_to_mask(channels)
    return channels


@dataclass(frozen=True)
class BoardIdentity:
    """What ``IDN?`` returns: who the board is and the limits the host must respect."""

    model: str
    serial: str
    firmware: str
    channels: int  # analog inputs, numbered 0..channels-1
    min_rate_hz: float
    max_rate_hz: float
    adc_bits: int
    range_v: float  # bipolar input range: counts span -range_v .. +range_v

    def to_reply(self) -> str:
        """The ``IDN?`` reply text the board sends."""
        return format_fields(
            model=self.model,
            serial=self.serial,
            firmware=self.firmware,
            channels=self.channels,
            min_rate_hz=f"{self.min_rate_hz:g}",
            max_rate_hz=f"{self.max_rate_hz:g}",
            adc_bits=self.adc_bits,
            range_v=f"{self.range_v:g}",
        )

    @classmethod
    def from_reply(cls, reply: Reply) -> BoardIdentity:
        """Parse an ``IDN?`` reply; a ProtocolError names the missing or malformed field."""
        values: dict[str, object] = {}
        converters = {
            "model": str, "serial": str, "firmware": str, "channels": int,
            "min_rate_hz": float, "max_rate_hz": float, "adc_bits": int, "range_v": float,
        }  # fmt: skip
        for key, convert in converters.items():
            if key not in reply.fields:
                raise ProtocolError(f"identity reply {reply.text!r} has no field {key!r}")
            try:
                values[key] = convert(reply.fields[key])
            except ValueError:
                raise ProtocolError(
                    f"identity field {key}={reply.fields[key]!r} is not a {convert.__name__}"
                ) from None
        return cls(**values)  # type: ignore[arg-type]


@dataclass(frozen=True)
class BoardConfiguration:
    """What ``CONF`` and ``CONF?`` return: the rate the board really runs and its frames."""

    sample_rate_hz: float
    channels: tuple[int, ...]
    samples_per_frame: int

    def to_reply(self) -> str:
        """The ``CONF`` / ``CONF?`` reply text the board sends."""
        return format_fields(
            rate_hz=repr(self.sample_rate_hz),
            channels=format_channels(self.channels),
            samples_per_frame=self.samples_per_frame,
        )

    @classmethod
    def from_reply(cls, reply: Reply) -> BoardConfiguration:
        """Parse a ``CONF`` reply; a ProtocolError names what is missing or malformed."""
        try:
            return cls(
                sample_rate_hz=float(reply.fields["rate_hz"]),
                channels=parse_channels(reply.fields["channels"]),
                samples_per_frame=int(reply.fields["samples_per_frame"]),
            )
        except (KeyError, ValueError) as error:
            raise ProtocolError(
                f"configuration reply {reply.text!r} is malformed: {error}"
            ) from None

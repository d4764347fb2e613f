"""The program's input boundaries under generated input: what each must answer, and how to tell.

Each ``check_*`` function gives one generated input to one boundary and raises
:class:`BadAnswerError` when the answer is not one the boundary may give: either a correct
result, or one line (no newline) naming the file and what was wrong, raised as that
boundary's own error type.  Anything else (another exception, i.e. a traceback for the
user; a message of several lines or one that does not name the file; a result that is
wrong; an answer slower than ``SLOW_S``) is a bad answer.  The Hypothesis strategies
that feed them are here too, so that the suite (bounded, derandomized) and
``benchmarks/fuzz.py`` (as long as asked) try the same things.
"""

from __future__ import annotations

import json
import math
import struct
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from hypothesis import strategies as st

from analysis.exchange import ExchangeFormatError, read_exchange
from drivers.daq_protocol import FrameParser, encode_data_frame, encode_reply_frame
from recording.errors import RecordingFormatError
from recording.layout import ChannelSpec, RecordingStatus
from recording.metadata import RecordingMetadata
from recording.reader import open_recording
from recording.writer import RecordingWriter
from rig.config import ConfigError, default_config_path, parse_config

SLOW_S = 5.0  # the bound: every answer within 5 s


class BadAnswerError(AssertionError):
    """A boundary answered in a way it must not; the message says how."""


def one_line_naming(error: BaseException, *names: str) -> None:
    """The error's text is one line and names one of ``names`` (the file)."""
    text = str(error)
    if "\n" in text or not text.strip():
        raise BadAnswerError(f"{type(error).__name__} of several lines (or none): {text!r}")
    if names and not any(name in text for name in names):
        raise BadAnswerError(f"{type(error).__name__} names none of {names}: {text!r}")


def timed(call: Callable[[], object]) -> float:
    """Run ``call``; its duration, or BadAnswerError when it took longer than SLOW_S."""
    started = time.perf_counter()
    call()
    took = time.perf_counter() - started
    if took > SLOW_S:
        raise BadAnswerError(f"answered after {took:.1f} s (limit {SLOW_S:g} s)")
    return took


# -- the DAQ frame decoder -----------------------------------------------------------------

CHANNEL_SETS = [(0,), (0, 1), (1, 3), (0, 1, 2, 3)]


@st.composite
def frame_streams(draw: st.DrawFn) -> tuple[bytes, dict[int, np.ndarray], list[int]]:
    """Good data and reply frames in a row, then damaged: bits flipped, bytes cut out,
    garbage put in, frames repeated, truncated.  Returns the bytes, every sample that was
    really sent (wire index -> analog row, digital last), and where to cut the bytes."""
    channels = draw(st.sampled_from(CHANNEL_SETS))
    per_frame = draw(st.integers(1, 40))
    index = draw(st.integers(0, 2**32 - 1))
    sent: dict[int, np.ndarray] = {}
    pieces: list[bytes] = []
    for _ in range(draw(st.integers(1, 8))):
        if draw(st.booleans()) and draw(st.booleans()):
            pieces.append(encode_reply_frame(draw(st.text("OK ERR=abc123", max_size=30)) or "OK"))
            continue
        rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
        analog = rng.integers(-32768, 32767, (per_frame, len(channels)), dtype=np.int16)
        digital = rng.integers(0, 65535, per_frame, dtype=np.uint16)
        for k in range(per_frame):
            sent[(index + k) % 2**32] = np.append(analog[k].astype(np.int64), int(digital[k]))
        pieces.append(encode_data_frame(index, channels, analog, digital))
        index = (index + per_frame + draw(st.sampled_from([0, 0, 0, 1, 7]))) % 2**32
    data = bytearray(b"".join(pieces))
    for _ in range(draw(st.integers(0, 6))):
        if not data:
            break
        at = draw(st.integers(0, len(data) - 1))
        match draw(st.sampled_from(["flip", "cut", "garbage", "repeat", "truncate", "length"])):
            case "flip":
                data[at] ^= 1 << draw(st.integers(0, 7))
            case "cut":
                del data[at : at + draw(st.integers(1, 20))]
            case "garbage":
                data[at:at] = draw(st.binary(max_size=40))
            case "repeat":
                data[at:at] = data[max(0, at - 60) : at]
            case "truncate":
                del data[at:]
            case "length":  # a plausible header claiming another length (bad CRC then)
                data[at:at] = b"\xa5\x5a\xc3\x3c\x01\x01" + struct.pack("<H", at % 2048) + b"\0" * 4
    cuts = sorted(draw(st.lists(st.integers(0, max(0, len(data))), max_size=5)))
    return bytes(data), sent, cuts


def check_frames(data: bytes, sent: dict[int, np.ndarray], cuts: list[int]) -> None:
    """Fed at once or in pieces, the parser finds the same frames; never raises; every
    sample it returns was sent as it is (a damaged frame is dropped, never half-read)."""
    whole = FrameParser().feed(data)
    parser = FrameParser()
    runs, replies = [], []
    for start, stop in zip([0, *cuts], [*cuts, len(data)], strict=True):
        part = parser.feed(data[start:stop])
        runs += part.runs
        replies += part.replies

    def samples(found: list) -> list[tuple[int, tuple[int, ...]]]:
        out = []
        for run in found:
            rows = np.column_stack([run.analog.astype(np.int64), run.digital.astype(np.int64)])
            out += [((run.first_index_wire + k) % 2**32, tuple(r)) for k, r in enumerate(rows)]
        return out

    at_once, in_pieces = samples(whole.runs), samples(runs)
    if at_once != in_pieces or whole.replies != replies:
        raise BadAnswerError("the frames found depend on how the bytes were cut into reads")
    for index, row in at_once:
        if index not in sent or tuple(sent[index]) != row:
            raise BadAnswerError(f"sample {index} decoded as {row}, which was never sent")


# -- the exchange CSV and its sidecar ------------------------------------------------------

COLUMN_NAMES = ["time_s", "angle_rad", "table_m", "tach", "angle", "Time_s", " time_s", ""]
NUMBER_TEXT = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.floats(-4, 4).map(lambda v: f"{v:.6g}"),
    st.sampled_from(["", "nan", "-inf", "1e29", "1e400", "0x10", "1,5", "abc", "\u00e9", "--1"]),
)


@st.composite
def exchange_files(draw: st.DrawFn) -> tuple[bytes, bytes]:
    """A CSV and its JSON sidecar: mostly nearly right, sometimes anything at all."""
    if draw(st.integers(0, 9)) == 0:
        return draw(st.binary(max_size=300)), draw(st.binary(max_size=100))
    header = draw(
        st.one_of(
            st.just(["time_s", "angle_rad"]),
            st.just(["time_s", "angle_rad", "table_m", "tach"]),
            st.lists(st.sampled_from(COLUMN_NAMES), min_size=0, max_size=5),
        )
    )
    rows = []
    n = draw(st.integers(0, 60))
    step = draw(st.sampled_from([1e-3, 1e-3, 0.01, 0.0, -1e-3]))
    scale = draw(st.sampled_from([0.1, 0.5, 3.0, 57.3, 1e29]))
    for k in range(n):
        values = []
        for name in header:
            if draw(st.integers(0, 30)) == 0:
                values.append(draw(NUMBER_TEXT))
            elif name.strip().lower() == "time_s":
                values.append(repr(k * step))
            elif name == "tach":
                values.append(str(int(k % 10 == 0)))
            else:
                values.append(repr(scale * math.sin(0.3 * k) * math.exp(-0.01 * k)))
        if draw(st.integers(0, 40)) == 0:
            values = values[: draw(st.integers(0, len(values)))]
        rows.append(",".join(values))
    text = ",".join(header) + "\n" + "\n".join(rows) + ("\n" if rows else "")
    encoding = draw(st.sampled_from(["utf-8", "utf-8", "utf-8", "latin-1", "utf-16"]))
    if encoding == "latin-1" and draw(st.booleans()):
        text += "caf\u00e9,1\n"
    sidecar = draw(
        st.one_of(
            st.just({"experiment": "free_decay"}),
            st.fixed_dictionaries(
                {"experiment": st.sampled_from(["free_decay", "forced", "impact_decay", "x", 3])},
                optional={
                    "rig": st.dictionaries(
                        st.sampled_from(["m_kg", "l_m", "R_m", "g", "L_m", "z"]),
                        st.one_of(st.floats(), st.text(max_size=3), st.none()),
                        max_size=6,
                    ),
                    "drive": st.one_of(
                        st.none(),
                        st.dictionaries(
                            st.sampled_from(["frequency_hz", "amplitude_m"]),
                            st.one_of(st.floats(), st.none(), st.text(max_size=2)),
                        ),
                    ),
                    "notes": st.one_of(st.text(max_size=10), st.integers()),
                },
            ),
        )
    )
    sidecar_bytes = json.dumps(sidecar).encode() if draw(st.integers(0, 9)) else b"{not json"
    return text.encode(encoding, errors="replace"), sidecar_bytes


def check_exchange(csv_bytes: bytes, sidecar_bytes: bytes, folder: Path) -> None:
    """``read_exchange``: a record that holds together, or one line naming the file."""
    csv_path, json_path = folder / "record.csv", folder / "record.json"
    csv_path.write_bytes(csv_bytes)
    json_path.write_bytes(sidecar_bytes)
    outcome: list[object] = []

    def read() -> None:
        try:
            outcome.append(read_exchange(csv_path))
        except ExchangeFormatError as error:
            outcome.append(error)

    timed(read)
    (answer,) = outcome
    if isinstance(answer, ExchangeFormatError):
        one_line_naming(answer, str(csv_path), str(json_path))
        return
    t, angle = answer.time_s, answer.angle_rad
    steps = np.diff(t)
    if not (t.size >= 2 and angle.size == t.size and np.all(np.isfinite(t)) and steps.min() > 0):
        raise BadAnswerError(f"accepted a record whose time is not usable: {t[:5]}")
    if not (np.all(np.isfinite(angle)) and np.abs(angle).max() <= math.pi):
        raise BadAnswerError(f"accepted angles no pendulum here reaches: max {np.abs(angle).max()}")
    if not 0 < answer.sample_rate_hz < math.inf:
        raise BadAnswerError(f"sample rate {answer.sample_rate_hz}")


# -- the rig file --------------------------------------------------------------------------

TOML_VALUES = st.one_of(
    st.integers(-(2**63), 2**63 - 1).map(str),
    st.floats(allow_nan=True, allow_infinity=True).map(
        lambda v: "nan" if math.isnan(v) else ("inf" if v == math.inf else "-inf")
        if math.isinf(v) else repr(v)
    ),
    st.sampled_from(['""', '"sim"', "true", "[]", "[1, 2]", '"/dev/ttyACM0"', "{}", "1e400"]),
    st.text(max_size=8).map(json.dumps),
)


@st.composite
def rig_files(draw: st.DrawFn) -> str:
    """The shipped rig file with lines removed, values replaced, keys misnamed or garbage."""
    lines = default_config_path().read_text(encoding="utf-8").splitlines()
    for _ in range(draw(st.integers(1, 4))):
        at = draw(st.integers(0, len(lines) - 1))
        line = lines[at]
        match draw(st.sampled_from(["value", "value", "delete", "rename", "garbage", "dup"])):
            case "value" if "=" in line and not line.lstrip().startswith("#"):
                key = line.split("=", 1)[0]
                lines[at] = f"{key}= {draw(TOML_VALUES)}"
            case "delete":
                del lines[at]
            case "rename" if "=" in line:
                lines[at] = draw(st.sampled_from(["x", "tach_bits ", "Port "])) + line[
                    line.index("=") :
                ]
            case "garbage":
                lines.insert(at, draw(st.text(max_size=20)))
            case "dup":
                lines.insert(at, line)
            case _:
                pass
    return "\n".join(lines) + "\n"


def check_rig_file(text: str) -> None:
    """``parse_config``: a configuration, or one line naming the file."""
    try:
        timed(lambda: parse_config(text, "lab.toml"))
    except ConfigError as error:
        one_line_naming(error, "lab.toml")


# -- a recording with damaged bytes --------------------------------------------------------

RECORDING_RATE_HZ = 1000.0


def write_small_recording(path: Path) -> None:
    """A recording with two sampled channels, a tach, a gap, drive rows and an outage."""
    specs = [
        ChannelSpec("angle", "samples", "rad", RECORDING_RATE_HZ, "board", None, "int16"),
        ChannelSpec("table", "samples", "m", RECORDING_RATE_HZ, "board", None, "int16"),
        ChannelSpec("tach", "pulses", "", RECORDING_RATE_HZ, "board", None),
    ]
    writer = RecordingWriter(
        path, specs, RecordingMetadata("forced", notes="fuzz"), software_version="fuzz"
    )
    try:
        stored = 0
        for first in (0, 3000, 6500):
            n = 2500
            raw = (np.arange(first, first + n) % 3000 - 1500).astype(np.int16)
            flags = np.zeros(n, np.uint8)
            for name, gain in (("angle", 1e-4), ("table", 3e-6)):
                writer.append_channel(
                    name,
                    {"raw": [raw], "values": [(raw * gain).astype(np.float32)], "flags": [flags]},
                    [(first, n, stored, first / RECORDING_RATE_HZ, first / 1000.0, 0)],
                    [] if first == 0 else [(first - (500 if first == 3000 else 1000),
                                            500 if first == 3000 else 1000)],
                )
            edges = np.arange(first + 5, first + n, 100, dtype=np.int64)
            writer.append_channel(
                "tach",
                {"edge_indices": [edges], "edge_times_s": [edges / RECORDING_RATE_HZ]},
                [(first, first + n, first / 1000.0, 0, edges.size)],
                [],
            )
            stored += n
            writer.flush()
        writer.append_drive([(0.1, 10, 10.0, 0.002, 1, 0)])
        writer.append_outages([(b"angle", 5500, 1000, 1.0, 6.5)])
        writer.write_status(RecordingStatus(9.0, 2 * stored, 3000, 3, True, "completed"))
        writer.flush()
    finally:
        writer.close()


def read_everything(path: Path) -> dict[str, object]:
    """All a reader takes from a recording, as plain arrays."""
    with open_recording(path) as recording:
        recording.verify()
        out: dict[str, object] = {"info": recording.info, "status": recording.status()}
        for name in recording.channel_names:
            data = recording.channel(name)
            out[name] = (data.indices, data.raw, data.values, data.flags, data.gaps)
        for name in recording.pulse_names:
            pulses = recording.pulses(name)
            out[name] = (pulses.edge_indices, pulses.covered, pulses.gaps)
        out["drive"] = recording.drive_log()
        out["steps"] = recording.sweep_steps()
        out["outages"] = recording.outages()
    return out


def same(a: object, b: object) -> bool:
    if isinstance(a, tuple) and isinstance(b, tuple):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return np.array_equal(np.asarray(a), np.asarray(b))
    return a == b


@dataclass(frozen=True)
class Damage:
    """Bytes overwritten at offsets (as fractions of the file), and where to cut it."""

    writes: tuple[tuple[float, bytes], ...]
    truncate_at: float | None


DAMAGES = st.builds(
    Damage,
    st.lists(
        st.tuples(st.floats(0, 1, exclude_max=True), st.binary(min_size=1, max_size=16)),
        max_size=4,
    ).map(tuple),
    st.one_of(st.none(), st.none(), st.floats(0, 1, exclude_max=True)),
)


def check_damaged_recording(original: Path, damage: Damage, folder: Path) -> None:
    """Open and read a damaged copy: the very data of the original, or one line naming it."""
    good = read_everything(original)
    data = bytearray(original.read_bytes())
    for where, patch in damage.writes:
        at = int(where * len(data))
        data[at : at + len(patch)] = patch[: len(data) - at]
    if damage.truncate_at is not None:
        del data[int(damage.truncate_at * len(data)) :]
    path = folder / "damaged.h5"
    path.write_bytes(bytes(data))
    outcome: list[object] = []

    def read() -> None:
        try:
            outcome.append(read_everything(path))
        except RecordingFormatError as error:
            outcome.append(error)

    timed(read)
    (answer,) = outcome
    if isinstance(answer, RecordingFormatError):
        one_line_naming(answer, str(path))
        return
    assert isinstance(answer, dict)
    for key, value in good.items():
        if key == "info":
            continue  # attributes are compared below, field by field
        if not same(value, answer[key]):
            raise BadAnswerError(f"damaged file read without error, but its {key!r} differs")
    if answer["info"] != good["info"]:
        raise BadAnswerError("damaged file read without error, but its metadata differs")


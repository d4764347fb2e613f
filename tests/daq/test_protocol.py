"""Byte-level tests of the DAQ wire protocol against the reference frames of docs/daq_protocol.md.

The expected bytes are written out field by field, as the document gives them;
the CRC is checked against an independent bitwise CRC-32 written here.
"""

from __future__ import annotations

import numpy as np
import pytest

from drivers.daq_protocol import (
    BoardConfiguration,
    BoardIdentity,
    FrameParser,
    IndexUnwrapper,
    ProtocolError,
    encode_command,
    encode_configure,
    encode_data_frame,
    encode_reply_frame,
    parse_channels,
    parse_reply,
)

# docs/daq_protocol.md section 5: channels 0 and 1, 2 samples, first index 256.
REFERENCE_DATA_FRAME = bytes.fromhex(
    "a5 5a c3 3c"  # sync
    "01"  # type: data
    "03"  # mask: inputs 0 and 1
    "0c 00"  # payload length 12
    "00 01 00 00"  # first sample index 256
    "e8 03 fe ff 01 00"  # 1000, -2, digital 1
    "e9 03 fd ff 00 00"  # 1001, -3, digital 0
    "65 ed 82 8c"  # CRC-32
)
REFERENCE_REPLY_FRAME = bytes.fromhex(
    "a5 5a c3 3c 02 00 0e 00 00 00 00 00"
    "4f 4b 20 73 74 72 65 61 6d 69 6e 67 3d 31"  # "OK streaming=1"
    "94 8a 3b b4"
)


def bitwise_crc32(data: bytes) -> int:
    """CRC-32/IEEE computed bit by bit from its definition (reflected poly 0xEDB88320)."""
    crc = 0xFFFFFFFF
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = (crc >> 1) ^ (0xEDB88320 if crc & 1 else 0)
    return crc ^ 0xFFFFFFFF


def reference_samples():
    analog = np.array([[1000, -2], [1001, -3]], dtype=np.int16)
    digital = np.array([1, 0], dtype=np.uint16)
    return analog, digital


def test_crc_is_the_standard_crc32():
    assert bitwise_crc32(b"123456789") == 0xCBF43926  # the published check value
    body = REFERENCE_DATA_FRAME[4:-4]
    assert int.from_bytes(REFERENCE_DATA_FRAME[-4:], "little") == bitwise_crc32(body)
    body = REFERENCE_REPLY_FRAME[4:-4]
    assert int.from_bytes(REFERENCE_REPLY_FRAME[-4:], "little") == bitwise_crc32(body)


def test_data_frame_encodes_to_the_reference_bytes():
    analog, digital = reference_samples()
    assert encode_data_frame(256, (0, 1), analog, digital).hex(" ") == REFERENCE_DATA_FRAME.hex(" ")


def test_index_is_sent_modulo_2_to_the_32():
    analog, digital = reference_samples()
    frame = encode_data_frame(256 + (1 << 32), (0, 1), analog, digital)
    assert frame == REFERENCE_DATA_FRAME


def test_reply_frame_encodes_to_the_reference_bytes():
    assert encode_reply_frame("OK streaming=1").hex(" ") == REFERENCE_REPLY_FRAME.hex(" ")


def test_reference_frames_decode_to_their_fields():
    result = FrameParser().feed(REFERENCE_DATA_FRAME + REFERENCE_REPLY_FRAME)
    assert result.replies == ["OK streaming=1"]
    assert result.frames_rejected == 0 and result.bytes_discarded == 0
    (run,) = result.runs
    assert run.first_index_wire == 256 and run.channels == (0, 1) and run.frames == 1
    assert run.analog.tolist() == [[1000, -2], [1001, -3]]
    assert run.digital.tolist() == [1, 0]


def test_commands_are_the_documented_ascii_lines():
    assert encode_configure(20000, (0, 1)) == b"CONF 20000 0,1\n"
    assert encode_configure(30030.03003003003, (0, 1, 3)) == b"CONF 30030 0,1,3\n"
    assert encode_command("IDN?") == b"IDN?\n"
    with pytest.raises(ProtocolError, match="analog channel 4 does not exist"):
        encode_configure(1000, (0, 4))
    with pytest.raises(ProtocolError, match="one line"):
        encode_command("START\nSTOP")


def stream_bytes(n_frames: int, per_frame: int = 5, first: int = 0) -> tuple[list[bytes], list]:
    frames, samples = [], []
    for k in range(n_frames):
        index = first + k * per_frame
        analog = (np.arange(per_frame * 3).reshape(per_frame, 3) + 10 * index).astype(np.int16)
        digital = (np.arange(per_frame) % 2).astype(np.uint16)
        frames.append(encode_data_frame(index, (0, 2, 3), analog, digital))
        samples.append((index, analog, digital))
    return frames, samples


def collect(parser: FrameParser, chunks: list[bytes]):
    runs, replies, rejected, discarded = [], [], 0, 0
    for chunk in chunks:
        result = parser.feed(chunk)
        runs += result.runs
        replies += result.replies
        rejected += result.frames_rejected
        discarded += result.bytes_discarded
    return runs, replies, rejected, discarded


def test_frames_split_anywhere_decode_the_same_as_whole():
    frames, samples = stream_bytes(6)
    wire = b"".join(frames)
    expected = np.concatenate([a for _, a, _ in samples])
    for size in (1, 3, 7, len(frames[0]) - 1, len(wire)):
        pieces = [wire[i : i + size] for i in range(0, len(wire), size)]
        runs, _, rejected, discarded = collect(FrameParser(), pieces)
        assert rejected == 0 and discarded == 0
        indices = [r.first_index_wire for r in runs]
        assert indices[0] == 0
        assert np.array_equal(np.concatenate([r.analog for r in runs]), expected)


def test_adjacent_frames_decode_as_one_run():
    frames, samples = stream_bytes(4)
    (run,) = FrameParser().feed(b"".join(frames)).runs
    assert run.frames == 4 and run.n_samples == 20
    assert np.array_equal(run.digital, np.concatenate([d for _, _, d in samples]))


def test_garbage_between_frames_is_skipped_without_loss():
    frames, _ = stream_bytes(3)
    partial_sync = b"\xa5\x5a\x13"
    wire = b"\x00\xff junk" + frames[0] + partial_sync + frames[1] + bytes(range(200)) + frames[2]
    runs, _, rejected, discarded = collect(FrameParser(), [wire])
    assert rejected == 0
    assert discarded == 7 + 3 + 200
    assert [r.first_index_wire for r in runs] == [0, 5, 10]


def test_fake_sync_with_plausible_header_does_not_swallow_the_next_frame():
    frames, _ = stream_bytes(2)
    # A sync word and a header claiming a long data frame, just before a real frame.
    fake = bytes.fromhex("a5 5a c3 3c 01 01 00 02 00 00 00 00")
    runs, _, rejected, _ = collect(FrameParser(), [frames[0] + fake + frames[1] + bytes(600)])
    assert [r.first_index_wire for r in runs] == [0, 5]
    assert rejected == 1  # the fake frame, once its claimed length arrived and failed the CRC


def test_corrupted_crc_rejects_only_that_frame():
    frames, _ = stream_bytes(3)
    bad = bytearray(frames[1])
    bad[20] ^= 0x40
    runs, _, rejected, _ = collect(FrameParser(), [frames[0] + bytes(bad) + frames[2]])
    assert rejected == 1
    assert [(r.first_index_wire, r.n_samples) for r in runs] == [(0, 5), (10, 5)]


def test_bytes_dropped_mid_frame_lose_that_frame_and_recover_at_the_next():
    frames, samples = stream_bytes(3)
    short = frames[1][:20] + frames[1][27:]
    runs, _, rejected, _ = collect(FrameParser(), [frames[0], short, frames[2]])
    assert rejected == 1
    assert [r.first_index_wire for r in runs] == [0, 10]
    assert np.array_equal(runs[1].analog, samples[2][1])


def test_reply_in_the_middle_of_a_stream_is_found():
    frames, _ = stream_bytes(2)
    runs, replies, rejected, _ = collect(
        FrameParser(), [frames[0] + encode_reply_frame("OK streaming=0 samples=10") + frames[1]]
    )
    assert replies == ["OK streaming=0 samples=10"] and rejected == 0
    assert [r.first_index_wire for r in runs] == [0, 5]


def test_index_jump_splits_runs():
    frames, _ = stream_bytes(2)
    later, _ = stream_bytes(1, first=1000)
    runs = FrameParser().feed(frames[0] + frames[1] + later[0]).runs
    assert [(r.first_index_wire, r.frames) for r in runs] == [(0, 2), (1000, 1)]


def test_replies_parse_into_fields_or_errors():
    reply = parse_reply("OK rate_hz=20000.0 channels=0,1 samples_per_frame=200")
    assert reply.ok and reply.fields["channels"] == "0,1"
    assert BoardConfiguration.from_reply(reply) == BoardConfiguration(20000.0, (0, 1), 200)
    error = parse_reply("ERR rate 1e+06 Hz out of range 10..250000")
    assert not error.ok and "out of range" in error.text
    with pytest.raises(ProtocolError, match="neither"):
        parse_reply("HELLO")
    with pytest.raises(ProtocolError, match="not key=value"):
        parse_reply("OK streaming")


def test_identity_reply_names_a_missing_field():
    good = (
        "OK model=IRDAQ-4 serial=A1 firmware=1.0.0 channels=4 min_rate_hz=10 "
        "max_rate_hz=250000 adc_bits=16 range_v=10"
    )
    identity = BoardIdentity.from_reply(parse_reply(good))
    assert identity.max_rate_hz == 250000.0 and identity.channels == 4
    assert BoardIdentity.from_reply(parse_reply(identity.to_reply())) == identity
    with pytest.raises(ProtocolError, match="'adc_bits'"):
        BoardIdentity.from_reply(parse_reply(good.replace(" adc_bits=16", "")))
    with pytest.raises(ProtocolError, match="channels='four'"):
        BoardIdentity.from_reply(parse_reply(good.replace("channels=4", "channels=four")))


def test_channel_lists_are_validated():
    assert parse_channels("0,1,3") == (0, 1, 3)
    with pytest.raises(ProtocolError, match="twice"):
        parse_channels("1,1")
    with pytest.raises(ProtocolError, match="not comma-separated integers"):
        parse_channels("0;1")


def test_sample_index_unwraps_across_2_to_the_32():
    indices = IndexUnwrapper()
    indices.next_index = (1 << 32) - 512  # six hours into a 200 kHz stream
    assert indices.unwrap((1 << 32) - 512, 256) == (1 << 32) - 512
    assert indices.unwrap((1 << 32) - 256, 256) == (1 << 32) - 256
    assert indices.unwrap(0, 256) == 1 << 32  # the wire wrapped; the running index did not
    assert indices.unwrap(256 + 1000, 256) == (1 << 32) + 1256  # a gap of 1000 across it
    assert indices.unwrap(256, 256) is None  # behind: refused, never counted twice
    assert indices.next_index == (1 << 32) + 1512

"""The HDF5 superblock, read and written by hand: whether a file is whole, and whether a
writer still has it (or died with it) open."""

from __future__ import annotations

import os
import struct
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from recording.checksum import lookup3
from recording.errors import REPAIR_HINT, RecordingDamagedError, RecordingFormatError

HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
SUPERBLOCK_V2_BYTES = 48  # version 2/3 superblock with 8-byte addresses, checksum last
# bytes a superblock of each version needs up to its end-of-file address (with 8-byte
# addresses; 48 for versions 2 and 3, their whole superblock), and where that address is
SUPERBLOCK_BYTES = {0: 48, 1: 52, 2: SUPERBLOCK_V2_BYTES, 3: SUPERBLOCK_V2_BYTES}
EOF_AT = {0: 40, 1: 44, 2: 28, 3: 28}
WRITER_FLAGS = 0x01 | 0x04  # superblock consistency flags: open for writing / SWMR writing


@dataclass(frozen=True)
class Superblock:
    """The parts of the HDF5 superblock (version 2 or 3) that say whether a file is whole."""

    version: int
    flags: int  # non-zero while a writer has the file open (or died with it open)
    stored_eof: int  # the file's size as its writer last recorded it
    size: int  # the file's size on disk


def read_superblock(path: Path) -> Superblock:
    """The superblock of the HDF5 file ``path``; RecordingFormatError when it is none."""
    try:
        with path.open("rb") as handle:
            head = handle.read(max(SUPERBLOCK_BYTES.values()))
            size = os.fstat(handle.fileno()).st_size
    except FileNotFoundError:
        raise RecordingFormatError(f"{path}: file not found") from None
    except IsADirectoryError:
        raise RecordingFormatError(f"{path}: is a folder, not a recording") from None
    except OSError as error:
        raise RecordingFormatError(f"{path}: cannot be read ({error.strerror})") from None
    if not head.startswith(HDF5_SIGNATURE):
        raise RecordingFormatError(
            f"{path}: not an HDF5 file (it does not start with the HDF5 signature)"
        )
    if len(head) <= 8:
        raise RecordingDamagedError(
            f"{path}: truncated to {size} bytes, too short for an HDF5 superblock"
        )
    version = head[8]
    if version not in SUPERBLOCK_BYTES:
        raise RecordingFormatError(f"{path}: HDF5 superblock version {version} is not supported")
    if len(head) < SUPERBLOCK_BYTES[version]:
        raise RecordingDamagedError(
            f"{path}: truncated to {size} bytes, too short for an HDF5 superblock"
        )
    # files of other HDF5 writers (versions 0 and 1) keep no consistency flags
    flags = head[11] if version in (2, 3) else 0
    (eof,) = struct.unpack_from("<Q", head, EOF_AT[version])
    return Superblock(version, flags, eof, size)


def check_whole(path: Path, waits_s: Sequence[float] = (0.3, 0.6)) -> Superblock:
    """The superblock of a file that is as long as its writer said; RecordingDamagedError if not.

    A live SWMR writer may have reserved space it has not yet written, so a short file
    whose writer flags are set is looked at again after ``waits_s`` before it is refused.
    """
    block = read_superblock(path)
    for wait_s in waits_s:
        if block.size >= block.stored_eof or not block.flags & WRITER_FLAGS:
            break
        time.sleep(wait_s)
        block = read_superblock(path)
    if block.size < block.stored_eof:
        raise RecordingDamagedError(
            f"{path}: truncated: {block.size} of its {block.stored_eof} bytes are present; "
            + REPAIR_HINT.format(path=path)
        )
    return block


def clear_writer_flags(path: Path) -> None:
    """What ``h5clear -s`` does: mark the file as closed by its writer (superblock version 2
    or 3), so that tools without SWMR open a file whose writer was killed."""
    with path.open("r+b") as handle:
        head = bytearray(handle.read(SUPERBLOCK_V2_BYTES))
        if len(head) < SUPERBLOCK_V2_BYTES or head[8] not in (2, 3) or head[9] != 8:
            return  # other superblocks have no such flags
        head[11] = 0
        head[44:48] = lookup3(bytes(head[:44])).to_bytes(4, "little")
        handle.seek(0)
        handle.write(head)



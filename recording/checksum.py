"""Bob Jenkins' lookup3, the checksum HDF5 puts on its metadata (the superblock's among them)."""

from __future__ import annotations

_M32 = 0xFFFFFFFF


def _rot(x: int, k: int) -> int:
    return ((x << k) | (x >> (32 - k))) & _M32


def lookup3(data: bytes, initval: int = 0) -> int:
    """Bob Jenkins' lookup3 ``hashlittle``: the checksum HDF5 puts on its metadata."""
    length = len(data)
    a = b = c = (0xDEADBEEF + length + initval) & _M32
    k = 0
    while length > 12:
        a = (a + int.from_bytes(data[k : k + 4], "little")) & _M32
        b = (b + int.from_bytes(data[k + 4 : k + 8], "little")) & _M32
        c = (c + int.from_bytes(data[k + 8 : k + 12], "little")) & _M32
        a = ((a - c) & _M32) ^ _rot(c, 4); c = (c + b) & _M32  # noqa: E702
        b = ((b - a) & _M32) ^ _rot(a, 6); a = (a + c) & _M32  # noqa: E702
        c = ((c - b) & _M32) ^ _rot(b, 8); b = (b + a) & _M32  # noqa: E702
        a = ((a - c) & _M32) ^ _rot(c, 16); c = (c + b) & _M32  # noqa: E702
        b = ((b - a) & _M32) ^ _rot(a, 19); a = (a + c) & _M32  # noqa: E702
        c = ((c - b) & _M32) ^ _rot(b, 4); b = (b + a) & _M32  # noqa: E702
        length -= 12
        k += 12
    if length == 0:
        return c
    tail = data[k:] + bytes(12 - length)
    a = (a + int.from_bytes(tail[0:4], "little")) & _M32
    b = (b + int.from_bytes(tail[4:8], "little")) & _M32
    c = (c + int.from_bytes(tail[8:12], "little")) & _M32
    c ^= b; c = (c - _rot(b, 14)) & _M32  # noqa: E702
    a ^= c; a = (a - _rot(c, 11)) & _M32  # noqa: E702
    b ^= a; b = (b - _rot(a, 25)) & _M32  # noqa: E702
    c ^= b; c = (c - _rot(b, 16)) & _M32  # noqa: E702
    a ^= c; a = (a - _rot(c, 4)) & _M32  # noqa: E702
    b ^= a; b = (b - _rot(a, 14)) & _M32  # noqa: E702
    c ^= b; c = (c - _rot(b, 24)) & _M32  # noqa: E702
    return c


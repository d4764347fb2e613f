"""The HDF5 C library that h5py runs on, for the one file-access setting h5py does not wrap.

An HDF5 SWMR reader retries a metadata block whose checksum fails, in case a live writer
is mid-flush, up to 100 times with a sleep that doubles each time (from a nanosecond, to
an hour at most).  On a killed recording with damaged metadata that is days of silent
waiting in C, deaf to Ctrl-C and SIGTERM.  ``H5Pset_metadata_read_attempts`` bounds it;
h5py has no binding for it, so it is called through ctypes on the very library h5py loaded.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools
from pathlib import Path

import h5py


@functools.cache
def hdf5_library() -> ctypes.CDLL | None:
    """h5py's own HDF5 library (same version), or None when it cannot be found."""
    for candidate in _candidates():
        try:
            library = ctypes.CDLL(str(candidate))
            major, minor, release = (ctypes.c_uint(), ctypes.c_uint(), ctypes.c_uint())
            if library.H5get_libversion(
                ctypes.byref(major), ctypes.byref(minor), ctypes.byref(release)
            ) < 0:
                continue
        except (OSError, AttributeError):
            continue
        if (major.value, minor.value, release.value) == h5py.version.hdf5_version_tuple[:3]:
            return library
    return None


def _candidates() -> list[str | Path]:
    """Where h5py's HDF5 library may be: what this process has mapped (Linux), the folders
    h5py's wheels bundle it in, then the system's."""
    found: list[str | Path] = []
    maps = Path("/proc/self/maps")
    if maps.exists():
        for line in maps.read_text().splitlines():
            path = line.split()[-1] if len(line.split()) >= 6 else ""
            name = Path(path).name
            if name.startswith("libhdf5") and not name.startswith("libhdf5_hl"):
                found.append(path)
    package = Path(h5py.__file__).parent
    for folder in (package.parent / "h5py.libs", package / ".dylibs", package):
        for pattern in ("libhdf5-*.so*", "libhdf5.*.dylib", "libhdf5*.dylib", "hdf5.dll"):
            found += [p for p in sorted(folder.glob(pattern)) if "_hl" not in p.name]
    system = ctypes.util.find_library("hdf5")
    if system:
        found.append(system)
    return list(dict.fromkeys(found))


def set_metadata_read_attempts(fapl: h5py.h5p.PropFAID, attempts: int) -> bool:
    """Bound the metadata read attempts of files opened with ``fapl``; False when the HDF5
    library cannot be reached (the default of 100 attempts then stays)."""
    library = hdf5_library()
    if library is None:
        return False
    function = library.H5Pset_metadata_read_attempts
    function.argtypes = [ctypes.c_int64, ctypes.c_uint]
    function.restype = ctypes.c_int
    return function(fapl.id, attempts) >= 0


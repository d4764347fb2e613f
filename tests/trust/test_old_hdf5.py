"""Collaborators' tools can read our files: h5py 3.11 (HDF5 1.14), in an environment of its
own, opens a fresh recording, checks its checksums and reads every channel."""

from __future__ import annotations

import json
import subprocess
import sys
import venv

import pytest

from recording.reader import open_recording

OLD_H5PY = "h5py==3.11.0"  # the last h5py on HDF5 1.14 (wheels bundle it)
OLD_NUMPY = "numpy<2"  # what that h5py was built against

READER = """
import json, sys, h5py
f = h5py.File(sys.argv[1], "r", swmr=True)
out = {"hdf5": h5py.version.hdf5_version, "h5py": h5py.version.version,
       "format": f.attrs["format"].decode(), "version": int(f.attrs["format_version"]),
       "provenance": json.loads(f.attrs["provenance_json"])}
for name, group in f["channels"].items():
    values = group["values"]  # float32: summed in float64, as the test sums its own reading
    out[name] = [int(group["raw"].shape[0]), float(group["time_s"][-1]),
                 bool(values.fletcher32), float(values[()].astype("f8").sum())]
print(json.dumps(out))
"""


@pytest.fixture(scope="session")
def old_h5py(tmp_path_factory):
    """A Python environment with h5py 3.11 from the package index (as a collaborator has).
    This process's pip installs into it (``--python``): the environment needs no pip of its
    own, whose bootstrap (ensurepip) took as long as the install."""
    folder = tmp_path_factory.mktemp("old-h5py")
    venv.EnvBuilder(with_pip=False).create(folder)
    python = folder / "bin" / "python"
    done = subprocess.run(
        [sys.executable, "-m", "pip", "--python", str(python), "install", "--quiet",
         "--only-binary=:all:", OLD_H5PY, OLD_NUMPY],
        capture_output=True, text=True, timeout=600, check=False,
    )
    assert done.returncode == 0, f"cannot install {OLD_H5PY}: {done.stderr[-2000:]}"
    return python


@pytest.mark.slow
def test_h5py_3_11_on_hdf5_1_14_opens_a_fresh_recording(old_h5py, recording):
    done = subprocess.run(
        [str(old_h5py), "-c", READER, str(recording)], capture_output=True, text=True,
        timeout=120, check=False,
    )
    assert done.returncode == 0, done.stderr
    seen = json.loads(done.stdout)
    assert seen["hdf5"].startswith("1.14") and seen["h5py"] == "3.11.0"
    assert seen["format"] == "impact-rig recording" and seen["version"] == 3
    assert seen["provenance"]["operator"] == "A. Tester"
    with open_recording(recording) as rec:
        for name in rec.channel_names:
            data = rec.channel(name)
            count, last_time, checksummed, total = seen[name]
            assert count == len(data) and checksummed
            assert last_time == pytest.approx(float(data.times_s[-1]))
            assert total == pytest.approx(float(data.values.astype(float).sum()), rel=1e-6)

"""A recording process for the kill -9 test: records counter streams until it is killed.

Run as ``python -m tests.rig.record_forever FILE.h5``; prints 'recording' once started.
"""

from __future__ import annotations

import sys
import time

from rig.engine import AcquisitionEngine
from rig.recorder import ChannelSpec, Recorder, RecordingMetadata, attach_recorder
from tests.rig.streams import CounterStream, TachStream

RATE_HZ = 20_000.0


def main(path: str) -> None:
    streams = [
        CounterStream("angle", sample_rate_hz=RATE_HZ, block=200, realtime=True),
        CounterStream(
            "table", sample_rate_hz=RATE_HZ, block=200, gain=2e-3, realtime=True, unit="m"
        ),
        TachStream(sample_rate_hz=RATE_HZ, block=200, period=2000),
    ]
    specs = [
        ChannelSpec("angle", unit="rad", sample_rate_hz=RATE_HZ),
        ChannelSpec("table", unit="m", sample_rate_hz=RATE_HZ),
        ChannelSpec("tach", kind="pulses", sample_rate_hz=RATE_HZ),
    ]
    engine = AcquisitionEngine(streams)
    recorder = Recorder(
        path, specs, RecordingMetadata("free_decay", notes="kill me"), flush_interval_s=0.25
    )
    attach_recorder(engine, recorder)
    engine.start()
    print("recording", flush=True)
    while True:
        time.sleep(1.0)


if __name__ == "__main__":
    main(sys.argv[1])

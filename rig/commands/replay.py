"""``impact-rig replay``: play a recording through the replay drivers and the acquisition engine."""

from __future__ import annotations

import argparse
import contextlib
import math
import time
from pathlib import Path

from rig.cli import CommandError, add_command
from rig.logs import progress

DESCRIPTION = """\
Play an HDF5 recording through the replay drivers: each recorded channel becomes
an input stream delivering its blocks with the original sample indices, device
times and gaps, so the acquisition engine (and whatever subscribes to it) runs
exactly as on the rig. Shows live what the engine sees (sample rate, tach
frequency, drive settings, lost samples) and, with --record, writes what it
received to a new recording (the same layout, a copy made through the engine).
"""

EPILOG = """\
examples:
  impact-rig replay run.h5                   real time
  impact-rig replay run.h5 --speed 10        ten times faster
  impact-rig replay run.h5 --fast --record copy.h5
"""


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``replay`` sub-command."""
    parser = add_command(
        subparsers,
        "replay",
        "play a recording through the replay drivers and the engine",
        DESCRIPTION,
        EPILOG,
    )
    parser.add_argument("recording", metavar="FILE.h5", help="the recording to play")
    pace = parser.add_mutually_exclusive_group()
    pace.add_argument(
        "--speed", type=float, default=1.0, help="how many times faster than real time (default 1)"
    )
    pace.add_argument("--fast", action="store_true", help="as fast as possible")
    parser.add_argument(
        "--record", metavar="COPY.h5", help="record what the engine receives into a new file"
    )
    parser.add_argument("--overwrite", action="store_true", help="replace COPY.h5 if it exists")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Replay until every stream has played its last block; print what was seen."""
    from analysis.output_paths import check_outputs
    from analysis.provenance import provenance
    from recording.metadata import carried_over
    from rig.engine import AcquisitionEngine
    from rig.logs import log, log_file, log_path_for, log_provenance
    from rig.recorder import ChannelSpec, Recorder, RecordingError, attach_recorder
    from rig.replay import Replay

    speed = math.inf if args.fast else args.speed
    if not speed > 0:
        raise CommandError(f"--speed is {args.speed}; expected a positive number")
    if args.record:
        check_outputs(
            [args.record, log_path_for(args.record)],
            inputs=[args.recording],
            overwrite=args.overwrite,
        )
    replay = Replay(args.recording, speed=speed)  # a bad file: one line from the dispatcher
    with replay, contextlib.ExitStack() as stack:
        rec = replay.recording
        engine = AcquisitionEngine(replay.streams)
        recorder = thread = None
        if args.record:
            info = rec.info
            specs = [
                ChannelSpec(
                    name,
                    "samples",
                    rec.unit(name),
                    rec.sample_rate_hz(name),
                    raw_dtype=str(rec.channel_dtype(name)),
                )
                for name in rec.channel_names
            ] + [
                ChannelSpec(name, "pulses", "", rec.sample_rate_hz(name))
                for name in rec.pulse_names
            ]
            meta = carried_over(
                info,
                extra={
                    **info.extra,
                    "replayed_from": str(Path(args.recording).resolve()),
                    "source_provenance": info.provenance,
                },
                provenance=provenance(),
            )
            try:
                recorder = Recorder(args.record, specs, meta, overwrite=args.overwrite)
            except RecordingError as error:
                raise CommandError(str(error)) from None
            thread = attach_recorder(engine, recorder)
            logging_to = stack.enter_context(log_file(log_path_for(args.record)))
            log.info("replaying %s into %s (log %s)", args.recording, args.record, logging_to)
            log_provenance()
        engine.start()
        replay.publish_annotations(engine)
        started = time.monotonic()
        stop_reason = "completed"
        try:
            while not replay.finished and engine.error is None:
                time.sleep(0.5 if math.isinf(speed) else 1.0)
                progress(_live_line(engine))
        except KeyboardInterrupt:
            stop_reason = "interrupted (Ctrl-C)"
            raise
        finally:
            engine.stop()
            if thread is not None:
                thread.finish()  # never close the file under a writing thread
                if engine.error is not None:
                    stop_reason = f"error: {engine.error}"
                try:
                    recorder.close(stop_reason)
                except RecordingError as error:
                    raise CommandError(str(error)) from None
        if engine.error is not None:
            raise CommandError(f"replay stopped: {engine.error}")
        stats = engine.stats()
        for name, channel in stats.channels.items():
            print(
                f"{name}: {channel.samples_received} samples, {channel.samples_lost} lost in "
                f"{channel.gaps} gap(s)"
                + (f", {channel.edges} tach edges" if channel.edges else "")
            )
        print(
            f"replayed {args.recording} in {time.monotonic() - started:.1f} s"
            + (f"; copy written to {args.record}" if args.record else "")
        )
    return 0


def _live_line(engine) -> str:
    stats = engine.stats()
    parts = []
    for name, channel in stats.channels.items():
        if channel.edges:
            tach = channel.tach_frequency_hz
            parts.append(f"{name} {tach:.3g} Hz" if tach else f"{name} -")
        else:
            parts.append(f"{name} {channel.samples_received} ({channel.sample_rate_hz:.0f}/s)")
    drive = stats.drive
    if drive is not None:
        parts.append(f"drive {drive.frequency_hz:g} Hz {drive.amplitude_m * 1e3:g} mm")
    parts.append(f"lost {stats.samples_lost}")
    return "replay: " + ", ".join(parts)

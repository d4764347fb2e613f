"""``impact-rig gui``: the desktop application (live rig, real rig from a file, or a replay)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from rig.cli import CommandError, add_command

VIEWS = ("time", "spectrum", "poincare", "phase", "analysis")

DESCRIPTION = """\
The desktop application: live views of the angle and the table (time traces,
spectrum with peaks named as multiples of the drive frequency, Poincare section
from the tach pulses, phase portrait), shaker control within the rig file's limits
with an always-visible STOP, recording with notes, sweeps, replay of recordings
(play, pause, seek, speed) and identification with the model's response drawn
over the data. Settings persist between runs.

Acquisition and recording run in their own threads; the window only draws.
"""

EPILOG = """\
examples:
  impact-rig gui --sim
  impact-rig gui --config lab.toml
  impact-rig gui --replay run.h5
  impact-rig gui --identify decay.h5
  impact-rig gui --sim --drive-hz 10 --beta 0.06 --view spectrum \\
      --screenshot spectrum.png --after 12
  impact-rig gui --screenshots docs/screenshots --overwrite   # the README's pictures
"""


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add the ``gui`` sub-command."""
    parser = add_command(
        subparsers,
        "gui",
        "the desktop application (--sim, --config FILE, --replay FILE)",
        DESCRIPTION,
        EPILOG,
    )
    source = parser.add_mutually_exclusive_group()
    source.add_argument("--sim", action="store_true", help="connect to the virtual rig at start")
    source.add_argument("--config", metavar="FILE", help="connect to the rig this TOML file names")
    source.add_argument("--replay", metavar="FILE", help="replay this recording (.h5)")
    source.add_argument(
        "--screenshots",
        metavar="DIR",
        type=Path,
        help="take the README's screenshots into DIR and exit: the virtual rig live in every "
        "view, its recording replayed, a free decay explained (about a minute)",
    )
    parser.add_argument("--fs", type=float, metavar="HZ", help="DAQ sample rate for a live rig")
    parser.add_argument(
        "--drive-hz", type=float, metavar="HZ", help="start the drive at this frequency (live)"
    )
    parser.add_argument(
        "--beta", type=float, default=0.03, help="drive amplitude A/L with --drive-hz (0.03)"
    )
    parser.add_argument("--view", choices=VIEWS, help="the view to show first")
    parser.add_argument(
        "--identify",
        metavar="FILE",
        help="identify this recording at start and show it in the analysis view",
    )
    parser.add_argument(
        "--screenshot", metavar="PNG", type=Path, help="save the main window to PNG and exit"
    )
    parser.add_argument(
        "--after",
        type=float,
        default=5.0,
        metavar="SECONDS",
        help="with --screenshot: seconds to run after connecting, then save (default 5)",
    )
    parser.add_argument(
        "--overwrite", action="store_true", help="replace existing screenshot files"
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Start the Qt application and the main window; optionally save a screenshot and exit."""
    if args.screenshots is not None:
        return take_readme_screenshots(args)
    _check_arguments(args)
    from PySide6.QtCore import QTimer

    from gui.app import MainWindow, open_source
    from gui.screenshots import ScreenshotError, save_window

    app = _application()
    window = MainWindow(sample_rate_hz=args.fs)
    if args.view:
        window.show_view(args.view)
    window.show()
    open_source(window, args.sim, args.config, args.replay)
    if args.drive_hz is not None:
        _start_drive_when_connected(window, args.drive_hz, args.beta)
    if args.identify:
        window.show_view("analysis")
        window.analysis_panel.path.setText(args.identify)
        window.analysis_panel.run.click()
    status = {"code": 0}
    if args.screenshot is not None:

        def save() -> None:
            try:
                save_window(window, args.screenshot)
            except ScreenshotError as error:
                print(f"impact-rig gui: {error}", file=sys.stderr)
                status["code"] = 2
            else:
                print(f"saved {args.screenshot}")
            window.close()
            app.quit()

        asked = args.sim or args.config or args.replay

        def when_connected() -> None:
            # --after counts from the moment the source is open (or failed to open)
            if not asked or window.session is not None or window.last_error:
                QTimer.singleShot(round(args.after * 1000), save)
            else:
                QTimer.singleShot(100, when_connected)

        when_connected()
    app.exec()
    if window.last_error and window.session is None and args.screenshot is None:
        raise CommandError(window.last_error)
    return status["code"]


def _check_arguments(args: argparse.Namespace) -> None:
    """Refuse a bad --after, a screenshot in the way or a missing file, before Qt starts."""
    from analysis.output_paths import check_outputs

    if args.screenshot is not None:
        if not args.after >= 0:
            raise CommandError(f"--after {args.after}: expected a number of seconds >= 0")
        check_outputs([args.screenshot], overwrite=args.overwrite)
    for name in (args.config, args.replay, args.identify):
        if name and not Path(name).is_file():
            raise CommandError(f"{name}: file not found")


def _application():
    """The Qt application (made once), with the GUI thread kept responsive (see app.py)."""
    from PySide6.QtWidgets import QApplication

    from gui.app import GIL_SWITCH_INTERVAL_S

    sys.setswitchinterval(GIL_SWITCH_INTERVAL_S)
    app = QApplication.instance() or QApplication(sys.argv[:1])
    app.setApplicationName("impact-rig")
    return app


def take_readme_screenshots(args: argparse.Namespace) -> int:
    """--screenshots DIR: every README picture, taken in a window of 1280 x 800 whose
    settings live in a scratch file (the user's are neither used nor changed)."""
    from tempfile import TemporaryDirectory

    from analysis.output_paths import check_outputs
    from gui.app import MainWindow
    from gui.screenshots import ScreenshotError, screenshot_files, take_screenshots
    from gui.settings import AppSettings

    if any(option is not None for option in (args.screenshot, args.identify, args.view,
                                             args.drive_hz)):
        raise CommandError(
            "--screenshots runs every stage itself: give it alone (with --fs, --overwrite)"
        )
    check_outputs(screenshot_files(args.screenshots), overwrite=args.overwrite)
    app = _application()
    with TemporaryDirectory(prefix="impact-rig-gui-") as scratch:
        window = MainWindow(AppSettings(str(Path(scratch) / "gui.ini")),
                            sample_rate_hz=args.fs)
        window.resize(1280, 800)
        window.show()
        try:
            for _, path in take_screenshots(window, args.screenshots):
                print(f"saved {path}")
        except ScreenshotError as error:
            raise CommandError(str(error)) from None
        finally:
            window.shutdown()
            window.close()
            app.processEvents()
    return 0


def _start_drive_when_connected(window, frequency_hz: float, beta: float) -> None:
    """Set and enable the drive once the live rig is open."""
    from PySide6.QtCore import QTimer

    from gui.worker import LiveSession

    def attempt() -> None:
        if isinstance(window.session, LiveSession):
            panel = window.shaker_panel
            panel.frequency.setValue(frequency_hz)
            panel.beta.setValue(beta)
            panel.enable.setChecked(True)
            panel.apply.click()
        else:
            QTimer.singleShot(200, attempt)

    QTimer.singleShot(200, attempt)

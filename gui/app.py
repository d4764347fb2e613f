"""The main window: live views in tabs, control panels at the side, an always-visible STOP.

The window never acquires or records itself: a session (live rig or replay) runs the
engine in its own threads; a frame timer drains the GUI's bounded queue and redraws
the visible view at a steady rate; device commands run on a background task thread.
"""

from __future__ import annotations

import itertools
import time
from collections import deque

import pyqtgraph as pg
from PySide6.QtCore import Qt, QTimer
from PySide6.QtGui import QCloseEvent
from PySide6.QtWidgets import (
    QDockWidget,
    QHBoxLayout,
    QLabel,
    QMainWindow,
    QPushButton,
    QScrollArea,
    QTabWidget,
    QToolBar,
    QVBoxLayout,
    QWidget,
)

from analysis import quantities as q
from drivers.interfaces import LimitError
from gui.live_data import LiveData, drive_description
from gui.live_sweep import LiveStep, judge_dwell, step_dwell
from gui.panels.analysis import AnalysisPanel
from gui.panels.connection import RECORDING, RIG_FILE, VIRTUAL, ConnectionPanel
from gui.panels.recording import RecordingPanel
from gui.panels.replay import ReplayPanel
from gui.panels.shaker import ShakerPanel
from gui.panels.status import StatusPanel
from gui.settings import AppSettings
from gui.views.phase_view import PhasePortraitView
from gui.views.poincare_view import PoincareView
from gui.views.spectrum_view import SpectrumView
from gui.views.sweep_view import SweepDiagramView
from gui.views.time_view import TimeTraceView
from gui.worker import LiveSession, ReplaySession, Session, TaskRunner, speed_from_text
from rig.config import load_config
from rig.devices import virtual_config
from rig.procedures import ProcedureResult, SweepPlan

DEFAULT_FRAME_RATE_HZ = 33.0  # a 30 ms timer: at least 30 frames drawn per second
SPECTRUM_PERIOD_S = 0.5
STATUS_PERIOD_MS = 500
# The GUI thread makes hundreds of Qt calls per frame and each gives up the GIL; with the
# default 5 ms switch interval a busy acquisition thread can make every one of them wait.
GIL_SWITCH_INTERVAL_S = 0.001
VIEW_NAMES = ("time", "spectrum", "poincare", "phase", "analysis", "sweep")

pg.setConfigOptions(background="w", foreground="k", antialias=False)


class MainWindow(QMainWindow):
    """impact-rig: run, record, replay and analyse the impact pendulum."""

    def __init__(
        self,
        settings: AppSettings | None = None,
        *,
        frame_rate_hz: float = DEFAULT_FRAME_RATE_HZ,
        sample_rate_hz: float | None = None,
    ) -> None:
        super().__init__()
        self.setWindowTitle("impact-rig")
        self.settings = settings or AppSettings()
        self.sample_rate_override = sample_rate_hz
        self.tasks = TaskRunner("gui-device", self)  # commands, in order
        self.polls = TaskRunner("gui-poll", self)  # status reads
        self.stops = TaskRunner("gui-stop", self)  # STOP never waits behind another command
        self.analysis_tasks = TaskRunner("gui-analysis", self)
        self.view_tasks = TaskRunner("gui-views", self)  # heavy view computations (spectrum)
        self.sweeps = TaskRunner("gui-sweep", self)  # the sweep procedure, for its whole run
        self.step_judge = TaskRunner("gui-step-judge", self)  # a live sweep's completed steps
        self._spectrum_busy = False
        self.session: Session | None = None
        self.data: LiveData | None = None
        self.frame_times: deque[float] = deque(maxlen=2000)  # perf_counter of each frame
        self.frames = 0
        self.last_error = ""
        self._last_spectrum = 0.0
        self._last_status_poll_done = True
        self._sweep_total = 0
        self._sweep_first_mark = 0  # where the running sweep's step marks begin in data.steps
        self._sweep_parameter = ""  # the live sweep's swept parameter ('' when none runs)
        self._sweep_next_mark = 0  # the first of its step marks not yet sent to be judged

        # always visible: the stop button
        self.stop_button = QPushButton("STOP DRIVE")
        self.stop_button.setToolTip("ramp the shaker to zero and switch the drive off")
        self.stop_button.setStyleSheet(
            "QPushButton { background: #c00000; color: white; font-weight: bold; "
            "padding: 6px 18px; }"
        )
        self.stop_button.clicked.connect(self.stop_drive)
        self.source_label = QLabel("not connected")
        self.drive_label = QLabel("")
        self.drive_label.setToolTip("the drive in force at the newest sample, and the sweep step")
        toolbar = QToolBar("Drive")
        toolbar.setMovable(False)
        toolbar.addWidget(self.stop_button)
        toolbar.addSeparator()
        toolbar.addWidget(self.source_label)
        toolbar.addSeparator()
        toolbar.addWidget(self.drive_label)
        self.addToolBar(Qt.ToolBarArea.TopToolBarArea, toolbar)

        # views
        self.time_view = TimeTraceView()
        self.spectrum_view = SpectrumView()
        self.poincare_view = PoincareView()
        self.phase_view = PhasePortraitView()
        self.analysis_panel = AnalysisPanel()
        self.sweep_view = SweepDiagramView()
        self.tabs = QTabWidget()
        self.tabs.addTab(self.time_view, "Time traces")
        self.tabs.addTab(self.spectrum_view, "Spectrum")
        self.tabs.addTab(self.poincare_view, "Poincaré section")
        self.tabs.addTab(self.phase_view, "Phase portrait")
        self.tabs.addTab(self.analysis_panel, "Analysis")
        self.tabs.addTab(self.sweep_view, "Sweep diagram")
        self.setCentralWidget(self.tabs)

        # panels
        self.connection_panel = ConnectionPanel()
        self.shaker_panel = ShakerPanel()
        self.recording_panel = RecordingPanel()
        self.replay_panel = ReplayPanel()
        self.status_panel = StatusPanel()
        # two columns: at 1280 x 800 every panel shows without scrolling (a smaller
        # window scrolls)
        side = QWidget()
        columns = QHBoxLayout(side)
        for panels in (
            (self.connection_panel, self.shaker_panel, self.replay_panel),
            (self.recording_panel, self.status_panel),
        ):
            column = QVBoxLayout()
            for panel in panels:
                column.addWidget(panel)
            column.addStretch(1)
            columns.addLayout(column)
        scroll = QScrollArea()
        scroll.setWidget(side)
        scroll.setWidgetResizable(True)
        scroll.setMinimumWidth(side.minimumSizeHint().width() + 2 * scroll.frameWidth())
        dock = QDockWidget("Controls")
        dock.setFeatures(QDockWidget.DockWidgetFeature.NoDockWidgetFeatures)
        dock.setWidget(scroll)
        self.addDockWidget(Qt.DockWidgetArea.LeftDockWidgetArea, dock)

        self.connection_panel.connect_requested.connect(self._connect_requested)
        self.connection_panel.disconnect_requested.connect(self.disconnect_source)
        self.shaker_panel.apply_requested.connect(self.apply_drive)
        self.shaker_panel.clear_faults_requested.connect(self.clear_faults)
        self.recording_panel.start_requested.connect(self.start_recording)
        self.recording_panel.stop_requested.connect(self.stop_recording)
        self.recording_panel.sweep_requested.connect(self.start_sweep)
        self.recording_panel.sweep_cancel_requested.connect(self.cancel_sweep)
        self.replay_panel.play_requested.connect(self.replay_play)
        self.replay_panel.pause_requested.connect(self.replay_pause)
        self.replay_panel.seek_requested.connect(self.replay_seek)
        self.replay_panel.speed_changed.connect(self.replay_speed)
        self.analysis_panel.run_requested.connect(self.run_analysis)
        self.analysis_panel.explain_requested.connect(self.explain_recording)

        self.frame_timer = QTimer(self)
        self.frame_timer.setTimerType(Qt.TimerType.PreciseTimer)
        self.frame_timer.setInterval(max(1, round(1000.0 / frame_rate_hz)))
        self.frame_timer.timeout.connect(self._frame)
        self.frame_timer.start()
        self.status_timer = QTimer(self)
        self.status_timer.setInterval(STATUS_PERIOD_MS)
        self.status_timer.timeout.connect(self._update_status)
        self.status_timer.start()
        self._restore_settings()

    # -- sources --------------------------------------------------------------------------------

    def _connect_requested(self, kind: str, path: str) -> None:
        if kind == VIRTUAL:
            self.open_virtual_rig()
        elif kind == RIG_FILE:
            self.open_rig_file(path)
        else:
            self.open_replay(path)

    def open_virtual_rig(self, sample_rate_hz: float | None = None) -> None:
        """Start the virtual rig (in the background) and show it live."""
        self._open_live(virtual_config(load_config(None)), sample_rate_hz)

    def open_rig_file(self, path: str, sample_rate_hz: float | None = None) -> None:
        """Open the rig a TOML file describes (real devices, or virtual if it says so)."""
        try:
            config = load_config(path) if path else None
        except ValueError as error:
            self.connection_panel.show_state(f"cannot use {path}: {error}", False)
            return
        if config is None:
            self.connection_panel.show_state("choose a rig file first", False)
            return
        self.settings.set("connection/rig_file", path)
        self._open_live(config, sample_rate_hz)

    def _open_live(self, config, sample_rate_hz: float | None) -> None:
        self.disconnect_source()
        fs = sample_rate_hz or self.sample_rate_override
        where = "the virtual rig" if config.is_virtual else config.source
        self.connection_panel.show_state(f"opening {where} ...", True)
        self.tasks.submit(
            lambda: LiveSession.open(config, fs), self._attach_live, self._open_failed
        )

    def _open_failed(self, error: BaseException) -> None:
        self.last_error = str(error)
        self.connection_panel.show_state(f"cannot connect: {error}", False)

    def _attach_live(self, session: LiveSession) -> None:
        self.session = session
        self._sweep_parameter = ""  # a new source: the last live sweep is over
        self.data = LiveData(
            session.sample_rate_hz, equivalent_length_m=session.config.constants.L_m
        )
        self.connection_panel.show_state(f"connected: {session.title}", True)
        self.source_label.setText(session.title)
        self.status_panel.show_source(session.title)
        self.shaker_panel.configure(session.limits, session.config.constants.L_m)
        self.shaker_panel.setEnabled(True)
        self.recording_panel.setEnabled(True)
        self.replay_panel.setEnabled(False)
        self.stop_button.setEnabled(True)

    def open_replay(self, path: str) -> None:
        """Play a recording through the replay drivers into the same views."""
        self.disconnect_source()
        try:
            session = ReplaySession(path)
        except (OSError, ValueError) as error:
            self.last_error = str(error)
            self.connection_panel.show_state(f"cannot replay {path}: {error}", False)
            return
        self.settings.set("connection/recording", path)
        self.session = session
        self._sweep_parameter = ""  # a new source: the last live sweep is over
        self.data = LiveData(
            session.sample_rate_hz,
            origin_index=session.span.first_index,
            equivalent_length_m=session.info.rig.get(q.L_m),
            recorded_steps=session.steps,
        )
        self.connection_panel.show_state(f"replaying {path}", True)
        self.source_label.setText(session.title)
        self.status_panel.show_source(f"{session.title} ({session.info.experiment})")
        self.status_panel.show_shaker(None)
        self.shaker_panel.setEnabled(False)
        self.recording_panel.setEnabled(False)
        self.replay_panel.setEnabled(True)
        self.stop_button.setEnabled(False)
        self.analysis_panel.current_recording = str(path)
        self.replay_play()

    def disconnect_source(self) -> None:
        """Close the current source (the drive goes to zero, a recording is closed)."""
        session, self.session = self.session, None
        if session is not None:
            if isinstance(session, LiveSession):
                self.tasks.submit(session.close)
            else:
                session.close()
        self.connection_panel.show_state("not connected", False)
        self.source_label.setText("not connected")
        self.drive_label.setText("")
        self.shaker_panel.setEnabled(False)
        self.recording_panel.setEnabled(False)
        self.replay_panel.setEnabled(False)

    # -- drive ----------------------------------------------------------------------------------

    def apply_drive(
        self, frequency_hz: float, amplitude_m: float, enabled: bool, ramp_m_s: float
    ) -> None:
        """Send checked drive settings to the shaker (in the background)."""
        session = self.session
        if not isinstance(session, LiveSession):
            return
        self.tasks.submit(
            lambda: session.apply_drive(frequency_hz, amplitude_m, enabled, ramp_m_s),
            lambda _: self.shaker_panel.show_message(""),
            lambda error: self.shaker_panel.show_message(f"Refused: {error}"),
        )

    def clear_faults(self) -> None:
        """Clear the amplifier's latched faults (the drive stays off until enabled again)."""
        session = self.session
        if isinstance(session, LiveSession):
            self.tasks.submit(
                session.clear_faults,
                lambda _: self.shaker_panel.show_message(""),
                lambda error: self.shaker_panel.show_message(f"cannot clear faults: {error}"),
            )

    def stop_drive(self) -> None:
        """The STOP button: ramp the drive to zero and switch it off."""
        self.shaker_panel.enable.setChecked(False)
        session = self.session
        if isinstance(session, LiveSession):
            self.stops.submit(
                session.stop_drive,
                None,
                lambda error: self.shaker_panel.show_message(f"STOP failed: {error}"),
            )

    # -- recording ------------------------------------------------------------------------------

    def start_recording(self, path: str, notes: str) -> None:
        """Record everything from now on to ``path``."""
        session = self.session
        if not isinstance(session, LiveSession):
            return
        if not path:
            self.recording_panel.show_recording(False, "give a file name first")
            return
        self.settings.set("recording/path", path)

        def started(run) -> None:
            self.recording_panel.show_recording(True, f"recording to {run.path}")

        self.tasks.submit(
            lambda: session.start_recording(path, notes),
            started,
            lambda error: self.recording_panel.show_recording(False, f"cannot record: {error}"),
        )

    def stop_recording(self) -> None:
        """Close the recording (in the background) and offer it to the analysis panel."""
        session = self.session
        if not isinstance(session, LiveSession):
            return

        def stopped(path) -> None:
            self.recording_panel.show_recording(False, f"saved {path}")
            if path is not None:
                self.analysis_panel.current_recording = str(path)

        self.tasks.submit(
            session.stop_recording,
            stopped,
            lambda error: self.recording_panel.show_recording(False, f"closing failed: {error}"),
        )

    def start_sweep(self, plan: SweepPlan, path: str, notes: str) -> None:
        """Run ``impact-rig sweep``'s procedure on the live rig, recording to ``path``.

        The procedure runs on the sweep thread; the window only shows its progress (its
        messages, and the step marks it publishes) and its end.
        """
        session = self.session
        if not isinstance(session, LiveSession):
            return
        self._sweep_total = len(plan.steps())
        self._sweep_first_mark = self._sweep_next_mark = len(self.data.steps)
        self._sweep_parameter = plan.parameter
        self.sweep_view.start(plan.parameter)
        self.recording_panel.show_sweep(True, 0, self._sweep_total, "starting ...")
        self.recording_panel.show_recording(True, f"sweep recording to {path}")
        self.shaker_panel.setEnabled(False)  # the procedure alone drives until it ends
        self.sweeps.submit(
            lambda: session.run_sweep(plan, path, notes, progress=self._sweep_progress),
            lambda result: self._sweep_ended(session, result),
            lambda error: self._sweep_ended(session, error),
        )

    def _sweep_progress(self, text: str) -> None:
        # called from the sweep's thread: hand over to the GUI thread
        QTimer.singleShot(0, self, lambda: self._show_sweep_progress(text))

    def _show_sweep_progress(self, text: str) -> None:
        if self.recording_panel.sweeping and self.data is not None:
            marks = self.data.steps[self._sweep_first_mark :]
            done = sum(mark.complete for mark in marks)
            self.recording_panel.show_sweep(True, done, self._sweep_total, text)

    def _sweep_ended(self, session: LiveSession, outcome: ProcedureResult | BaseException) -> None:
        """Show how the sweep ended: its result, or why it was refused or failed."""
        if isinstance(outcome, ProcedureResult):
            done, text = outcome.steps, f"sweep {outcome.stop_reason}"
            self.recording_panel.show_recording(False, f"saved {outcome.path}")
            self.analysis_panel.current_recording = str(outcome.path)
        else:
            done = 0
            text = (
                f"Refused: {outcome}"
                if isinstance(outcome, LimitError)
                else f"sweep ended: {outcome}"
            )
            self.recording_panel.show_recording(False, text)
        self.recording_panel.show_sweep(False, done, self._sweep_total, text)
        self.shaker_panel.setEnabled(self.session is session)

    def _judge_completed_steps(self, data: LiveData) -> None:
        """Send each step of the live sweep that has ended, once its dwell's samples are all
        in, to be judged off the GUI thread; its regime and points join the diagram."""
        end = data.angle.end_index
        while self._sweep_next_mark < len(data.steps):
            mark = data.steps[self._sweep_next_mark]
            if end is None or end < mark.dwell_end_index:
                return  # the step's last samples are still on their way
            self._sweep_next_mark += 1
            if not mark.complete:
                self.sweep_view.note(f"step {mark.step} was interrupted: not judged")
                continue
            dwell = step_dwell(data, mark, self._sweep_parameter)
            if dwell is None:
                self.sweep_view.note(f"step {mark.step}: its dwell has a gap: not judged")
                continue
            self.step_judge.submit(
                lambda dwell=dwell: judge_dwell(dwell),
                self._step_judged,
                lambda error, step=mark.step: self.sweep_view.note(
                    f"step {step} cannot be judged: {error}"),
            )

    def _step_judged(self, step: LiveStep) -> None:
        self.sweep_view.add_step(step)

    def cancel_sweep(self) -> None:
        """Stop the running sweep (the drive ramps to zero, the file is closed)."""
        session = self.session
        if isinstance(session, LiveSession):
            session.cancel_sweep()

    # -- replay ---------------------------------------------------------------------------------

    def replay_play(self) -> None:
        session = self.session
        if not isinstance(session, ReplaySession):
            return
        if session.finished:
            self.data.clear()
            session.play(start_index=session.span.first_index)
        else:
            session.note_position(self.data.angle.end_index if self.data else None)
            session.play(speed=speed_from_text(self.replay_panel.speed.currentText()))
        self.replay_panel.show_playing(True)

    def replay_pause(self) -> None:
        session = self.session
        if isinstance(session, ReplaySession):
            session.pause()
            session.note_position(self.data.angle.end_index if self.data else None)
            self.replay_panel.show_playing(False)

    def replay_seek(self, fraction: float) -> None:
        session = self.session
        if not isinstance(session, ReplaySession):
            return
        span = session.span
        index = span.first_index + round(fraction * (span.end_index - span.first_index))
        self.data.clear()
        session.play(start_index=index)
        self.replay_panel.show_playing(True)

    def replay_speed(self, text: str) -> None:
        session = self.session
        if isinstance(session, ReplaySession) and session.playing:
            session.note_position(self.data.angle.end_index if self.data else None)
            session.play(speed=speed_from_text(text))

    # -- analysis -------------------------------------------------------------------------------

    def run_analysis(self, path: str, experiment: str) -> None:
        """Identify ``path`` on the analysis thread, then draw the overlay."""
        from gui.model_overlay import identify_recording  # scipy and numba: load when needed

        self.analysis_tasks.submit(
            lambda: identify_recording(path, experiment or None),
            self._analysis_done,
            self.analysis_panel.show_error,
        )

    def _analysis_done(self, overlay) -> None:
        self.analysis_panel.show_result(overlay)

    def explain_recording(self, path: str, experiment: str) -> None:
        """Run ``analyze`` on ``path`` on the analysis thread (acquisition runs on), showing
        its stages as it goes, then the explanation; a sweep recording is explained as a
        sweep (``analyze_sweep``)."""
        # scipy and numba: load when needed
        from gui.model_overlay import Explanation, explain_recording
        from gui.sweep_explanation import explain_sweep, is_sweep_recording

        panel = self.analysis_panel

        def progress(text: str) -> None:  # on the analysis thread: hand over to the GUI's
            QTimer.singleShot(0, self, lambda: panel.show_progress(text))

        def explain():  # a sweep (a file with sweep steps) is explained as one
            if is_sweep_recording(path):
                return explain_sweep(path, progress)
            return explain_recording(path, experiment or None, progress)

        def show(explanation) -> None:
            if isinstance(explanation, Explanation):
                panel.show_explanation(explanation)
            else:
                panel.show_sweep_explanation(explanation)

        self.analysis_tasks.submit(explain, show, panel.show_error)

    # -- the frame and status timers ------------------------------------------------------------

    def _frame(self) -> None:
        self.frame_times.append(time.perf_counter())
        session, data = self.session, self.data
        if session is None or data is None:
            return
        data.ingest(session.drain())
        self.drive_label.setText(drive_description(data))
        if self._sweep_parameter:
            self._judge_completed_steps(data)
        self.poincare_view.collect(data)
        current = self.tabs.currentWidget()
        if current is self.time_view:
            self.time_view.refresh(data)
        elif current is self.spectrum_view:
            now = time.monotonic()
            if now - self._last_spectrum >= SPECTRUM_PERIOD_S and not self._spectrum_busy:
                self._start_spectrum(data, now)
        elif current is self.poincare_view:
            self.poincare_view.refresh(data)
        elif current is self.phase_view:
            self.phase_view.refresh(data)
        self.frames += 1
        if isinstance(session, ReplaySession):
            end = data.angle.end_index or session.span.first_index
            finished = session.finished
            self.replay_panel.show_position(
                (end - session.span.first_index) / session.sample_rate_hz,
                session.span.duration_s,
                finished,
            )
            if finished and self.replay_panel.playing:
                self.replay_panel.show_playing(False)
        elif isinstance(session, LiveSession) and session.recording is not None:
            run = session.recording
            if not run.stopped:
                self.recording_panel.show_progress(run.elapsed_s, run.file_size_bytes)

    def _start_spectrum(self, data: LiveData, now: float) -> None:
        """Compute the spectrum on the view thread; draw it when it is ready."""
        snapshot = self.spectrum_view.snapshot(data)
        if snapshot is None:
            return
        self._last_spectrum = now
        self._spectrum_busy = True

        def done(spectrum) -> None:
            self._spectrum_busy = False
            self.spectrum_view.show(spectrum)

        def failed(error: BaseException) -> None:
            self._spectrum_busy = False

        self.view_tasks.submit(lambda: SpectrumView.compute(snapshot), done, failed)

    def _update_status(self) -> None:
        session = self.session
        if session is None:
            self.status_panel.show_engine(None, [], 0)
            return
        stats = session.stats()
        view_lost = 0
        if stats is not None:
            view_lost = sum(s.dropped_samples for s in stats.subscribers if s.name == "gui")
        self.status_panel.show_engine(stats, session.stream_statuses(), view_lost)
        if isinstance(session, LiveSession) and self._last_status_poll_done:
            self._last_status_poll_done = False

            def polled(status) -> None:
                self._last_status_poll_done = True
                if self.session is session:
                    self.status_panel.show_shaker(status)

            def poll_failed(error: BaseException) -> None:
                self._last_status_poll_done = True

            self.polls.submit(session.shaker_status, polled, poll_failed)

    # -- statistics for the benchmark and tests -------------------------------------------------

    def frame_intervals_s(self) -> list[float]:
        """Time between consecutive frames (the GUI thread's steadiness)."""
        times = list(self.frame_times)
        return [b - a for a, b in itertools.pairwise(times)]

    def show_view(self, name: str) -> None:
        """Bring a view to the front by name: time, spectrum, poincare, phase, analysis,
        sweep."""
        self.tabs.setCurrentIndex(VIEW_NAMES.index(name))

    # -- settings -------------------------------------------------------------------------------

    def _restore_settings(self) -> None:
        s = self.settings
        p = self.shaker_panel
        p.frequency.setValue(s.number("shaker/frequency_hz", 10.0))
        p.amplitude_mm.setValue(s.number("shaker/amplitude_mm", 1.0))
        p.ramp.setValue(s.number("shaker/ramp_mm_s", 5.0))
        self.recording_panel.path.setText(s.text("recording/path", "run.h5"))
        self.time_view.window_s.setValue(s.number("views/time_window_s", 5.0))
        self.spectrum_view.window.setCurrentText(s.text("views/spectrum_window", "hann"))
        self.spectrum_view.log_scale.setChecked(s.flag("views/spectrum_log", True))
        self.spectrum_view.max_frequency.setValue(s.number("views/spectrum_max_hz", 60.0))
        self.poincare_view.mode.setCurrentIndex(int(s.number("views/poincare_mode", 0)))
        self.replay_panel.speed.setCurrentText(s.text("replay/speed", "1x"))
        self.connection_panel.source.setCurrentText(s.text("connection/source", VIRTUAL))
        self.connection_panel.path.setText(s.text("connection/path", ""))
        self.tabs.setCurrentIndex(int(s.number("views/tab", 0)))
        self.resize(int(s.number("window/width", 1200)), int(s.number("window/height", 760)))

    def save_settings(self) -> None:
        """Remember the drive values, files and view choices for next time."""
        s = self.settings
        p = self.shaker_panel
        s.set("shaker/frequency_hz", p.frequency.value())
        s.set("shaker/amplitude_mm", p.amplitude_mm.value())
        s.set("shaker/ramp_mm_s", p.ramp.value())
        s.set("recording/path", self.recording_panel.path.text())
        s.set("views/time_window_s", self.time_view.window_s.value())
        s.set("views/spectrum_window", self.spectrum_view.window.currentText())
        s.set("views/spectrum_log", self.spectrum_view.log_scale.isChecked())
        s.set("views/spectrum_max_hz", self.spectrum_view.max_frequency.value())
        s.set("views/poincare_mode", self.poincare_view.mode.currentIndex())
        s.set("replay/speed", self.replay_panel.speed.currentText())
        s.set("connection/source", self.connection_panel.source.currentText())
        s.set("connection/path", self.connection_panel.path.text())
        s.set("views/tab", self.tabs.currentIndex())
        s.set("window/width", self.width())
        s.set("window/height", self.height())
        s.sync()

    def shutdown(self) -> None:
        """Save settings, drive to zero, close the source, stop the background threads."""
        self.frame_timer.stop()
        self.status_timer.stop()
        self.save_settings()
        session, self.session = self.session, None
        if session is not None:
            session.close()
        self.stops.shutdown()
        self.sweeps.shutdown()
        self.tasks.shutdown()
        self.polls.shutdown()
        self.analysis_tasks.shutdown(wait=False)
        self.view_tasks.shutdown(wait=False)
        self.step_judge.shutdown(wait=False)

    def closeEvent(self, event: QCloseEvent) -> None:
        self.shutdown()
        super().closeEvent(event)


def open_source(window: MainWindow, sim: bool, config: str | None, replay: str | None) -> None:
    """Connect the window to what the command line asked for."""
    if replay:
        window.connection_panel.source.setCurrentText(RECORDING)
        window.connection_panel.path.setText(replay)
        window.open_replay(replay)
    elif config and not sim:
        window.connection_panel.source.setCurrentText(RIG_FILE)
        window.connection_panel.path.setText(config)
        window.open_rig_file(config)
    elif config:
        window._open_live(virtual_config(load_config(config)), None)
    elif sim:
        window.connection_panel.source.setCurrentText(VIRTUAL)
        window.open_virtual_rig()


def frames_per_second(window: MainWindow, last_s: float) -> float:
    """Frames drawn per second over the last ``last_s`` seconds."""
    times = [t for t in window.frame_times if t >= time.perf_counter() - last_s]
    if len(times) < 2:
        return 0.0
    return (len(times) - 1) / (times[-1] - times[0])


__all__ = ["MainWindow", "frames_per_second", "open_source"]

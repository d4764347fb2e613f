"""Status: sample rate, lost samples, and every device's state and faults in plain words."""

from __future__ import annotations

from PySide6.QtWidgets import QFormLayout, QGroupBox, QLabel, QWidget

from analysis import quantities as q
from drivers.interfaces import ActuatorStatus, StreamStatus
from gui.units import DISPLAY
from rig.engine import EngineStats

ROWS = (
    ("source", "Source"),
    ("rate", "Sample rate"),
    ("received", "Samples"),
    ("lost", "Lost samples"),
    ("view", "Display"),
    ("daq", "DAQ board"),
    ("shaker", "Shaker"),
    ("drive", "Measured drive"),
    ("faults", "Faults"),
)


class StatusPanel(QGroupBox):
    """A form of live quantities; ``faults`` shows problems in words, red when there are any."""

    def __init__(self, parent: QWidget | None = None) -> None:
        super().__init__("Status", parent)
        form = QFormLayout(self)
        self.fields: dict[str, QLabel] = {}
        for key, title in ROWS:
            label = QLabel("-")
            label.setWordWrap(True)
            self.fields[key] = label
            form.addRow(title, label)

    def text(self, key: str) -> str:
        """The text shown in one row (for tests and screenshots)."""
        return self.fields[key].text()

    def show_source(self, text: str) -> None:
        self.fields["source"].setText(text)

    def show_engine(
        self, stats: EngineStats | None, streams: list[tuple[str, StreamStatus]], view_lost: int
    ) -> None:
        """Rates and losses from the engine, and the streams' own messages."""
        if stats is None:
            for key in ("rate", "received", "lost", "view", "daq"):
                self.fields[key].setText("-")
            return
        sampled = [c for c in stats.channels.values() if c.sample_rate_hz > 0]
        rate = max((c.sample_rate_hz for c in sampled), default=0.0)
        received = max((c.samples_received for c in stats.channels.values()), default=0)
        self.fields["rate"].setText(f"{rate:,.0f} Hz")
        self.fields["received"].setText(f"{received:,}")
        lost = stats.samples_lost
        self.fields["lost"].setText(f"{lost:,}" if lost == 0 else f"{lost:,} (gaps in the data)")
        self.fields["lost"].setStyleSheet("" if lost == 0 else "color: #b00000")
        self.fields["view"].setText(
            "all data drawn" if view_lost == 0 else f"skipped {view_lost:,} samples (display only)"
        )
        messages = sorted({s.message for _, s in streams if s.message})
        if stats.reconnecting:  # the board went away: say it first, and that the run goes on
            messages.insert(
                0,
                "reconnecting to the DAQ board (" + ", ".join(stats.reconnecting) + "): the "
                "run goes on, the outage will be a gap in the data",
            )
        if stats.error:
            messages.insert(0, f"acquisition stopped: {stats.error}")
        self.fields["daq"].setText("; ".join(messages) if messages else "streaming, healthy")
        self.fields["daq"].setStyleSheet("color: #b00000" if messages else "")

    def show_shaker(self, status: ActuatorStatus | None) -> None:
        """The amplifier's connection, drive and faults (None: no shaker, e.g. a replay)."""
        if status is None:
            for key in ("shaker", "drive", "faults"):
                self.fields[key].setText("-")
            return
        if not status.connected:
            again = any("reconnecting" in fault for fault in status.faults)
            state = "reconnecting (drive off until asked again)" if again else "not connected"
        else:
            state = "connected, drive on" if status.enabled else "connected, drive off"
        self.fields["shaker"].setText(state)
        measured = status.measured
        if measured:
            self.fields["drive"].setText(
                f"{measured.get(q.frequency_hz, 0.0):.3f} Hz, "
                f"{DISPLAY['displacement'].show(measured.get(q.amplitude_m, 0.0)):.3f} "
                f"{DISPLAY['displacement'].unit}"
            )
        faults = ", ".join(status.faults)
        self.fields["faults"].setText(faults or "none")
        self.fields["faults"].setStyleSheet("color: #b00000; font-weight: bold" if faults else "")

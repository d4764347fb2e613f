"""Settings that persist between runs (QSettings): last files, drive values, view choices.

The location is the user's QSettings store for organisation ``impact-rig``; setting
``IMPACT_RIG_GUI_SETTINGS`` to a file path keeps them in that INI file instead
(tests do this so they never touch the user's settings).
"""

from __future__ import annotations

import os

from PySide6.QtCore import QSettings

ORGANISATION = "impact-rig"
APPLICATION = "gui"
SETTINGS_FILE_VARIABLE = "IMPACT_RIG_GUI_SETTINGS"


class AppSettings:
    """Typed access to the application's QSettings."""

    def __init__(self, path: str | None = None) -> None:
        path = path or os.environ.get(SETTINGS_FILE_VARIABLE)
        if path:
            self._store = QSettings(path, QSettings.Format.IniFormat)
        else:
            self._store = QSettings(ORGANISATION, APPLICATION)

    @property
    def location(self) -> str:
        """Where the settings are kept (file name or registry path)."""
        return self._store.fileName()

    def _value(self, key: str) -> object:
        # never hand a default to QSettings.value: PySide6 returns it without a new
        # reference, and the interpreter later crashes freeing True or None
        return self._store.value(key) if self._store.contains(key) else None

    def number(self, key: str, default: float) -> float:
        """A float setting (the default when missing or unreadable)."""
        value = self._value(key)
        if value is None:
            return float(default)
        try:
            return float(value)
        except (TypeError, ValueError):
            return float(default)

    def text(self, key: str, default: str = "") -> str:
        """A text setting."""
        value = self._value(key)
        return str(value) if value is not None else default

    def flag(self, key: str, default: bool = False) -> bool:
        """A yes/no setting (QSettings stores booleans as text in INI files)."""
        value = self._value(key)
        if value is None:
            return default
        if isinstance(value, str):
            return value.lower() in ("true", "1", "yes")
        return bool(value)

    def set(self, key: str, value: float | str | bool) -> None:
        """Store a setting now."""
        self._store.setValue(key, value)

    def sync(self) -> None:
        """Write pending changes to disk."""
        self._store.sync()

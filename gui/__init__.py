"""The PySide6 + pyqtgraph desktop application."""

from gui.refcount_guard import protect_singletons

protect_singletons()  # before any Qt call anywhere in the process: see gui/refcount_guard.py

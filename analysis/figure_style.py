"""What every figure we write shares: legends beside the data, never over it, and a
resolution that prints (the HTML and Markdown reports embed these PNGs)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from analysis.provenance import png_metadata

PRINT_DPI = 200  # a 8-inch-wide figure is 1600 pixels: sharp on paper at full width


def legend_beside(axes: Any, **options: Any) -> Any:
    """The legend of ``axes`` to its right, outside the data; ``save_figure`` keeps it in."""
    return axes.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0,
                       **options)


def save_figure(figure: Any, path: str | Path, *, crop: bool = True) -> Path:
    """Write ``figure`` as a PNG at PRINT_DPI, cropped to what it draws (legends beside the
    axes included), with the software that made it in its metadata.  ``crop=False`` for a
    figure whose layout holds all it draws already (constrained layout, legends included):
    it is then drawn once instead of twice."""
    path = Path(path)
    figure.savefig(path, format="png", dpi=PRINT_DPI, bbox_inches="tight" if crop else None,
                   metadata=png_metadata())
    return path

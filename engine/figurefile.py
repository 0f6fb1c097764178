"""A figure's file: matplotlib imported when a figure is drawn (an optional extra), the bounds
of a figure's size (checked before anything is drawn), and its bytes: a PNG to embed, or a file
whose format its suffix names, written through ``NAME.tmp`` and a rename.

Shared by the maps (:mod:`engine.plot`), the report and the orbit pictures
(:mod:`engine.orbitplot`).
"""

from __future__ import annotations

import io
import math
import os
from pathlib import Path
from types import SimpleNamespace
from typing import Any

from .errortext import install_hint
from .io.atomic import fsync_path, replacing
from .mapspec import LookError

__all__ = [
    "FORMATS",
    "INSTALL_HINT",
    "MAX_DPI",
    "MAX_PIXELS",
    "MIN_DPI",
    "check_figure_size",
    "figure_png",
    "matplotlib_parts",
    "output_format",
    "save_figure",
]

INSTALL_HINT = install_hint("plot")
#: Largest resolution [dots per inch] a figure is drawn at, and the most pixels it may have
#: (width x height: 50 million, about 0.2 GB of RGBA while it is drawn; ``--dpi 3000`` on one
#: map took 1.5 GB and a minute, ``--dpi 100000`` ended in a MemoryError).
MIN_DPI, MAX_DPI = 10, 1200
MAX_PIXELS = 50_000_000


def matplotlib_parts() -> SimpleNamespace:
    """matplotlib's Figure, colors and patches (imported here, not at module import), or
    LookError telling how to install it."""
    try:
        import matplotlib
        from matplotlib import colors, patches
        from matplotlib.figure import Figure
    except ImportError:
        raise LookError(
            f"drawing figures needs matplotlib, which is not installed: {INSTALL_HINT}"
        ) from None
    return SimpleNamespace(mpl=matplotlib, Figure=Figure, colors=colors, patches=patches)


def check_figure_size(size: tuple[float, float], dpi: float, option: str = "--dpi") -> None:
    """LookError, before anything is drawn, for a resolution outside [MIN_DPI, MAX_DPI] or a
    figure of ``size`` [inch] at ``dpi`` with more than MAX_PIXELS pixels."""
    if not (isinstance(dpi, int | float) and math.isfinite(dpi)) or not MIN_DPI <= dpi <= MAX_DPI:
        raise LookError(f"{option} must be in {MIN_DPI}..{MAX_DPI}; got {dpi}")
    w, h = size[0] * dpi, size[1] * dpi
    if w * h > MAX_PIXELS:
        most = int(math.sqrt(MAX_PIXELS / (size[0] * size[1])))
        raise LookError(
            f"{option} {dpi:g}: a {size[0]:.3g} x {size[1]:.3g} inch figure would be "
            f"{w:,.0f} x {h:,.0f} pixels, more than {MAX_PIXELS:,}; at most {option} {most}"
        )


def figure_png(fig: Any, dpi: int = 80) -> bytes:
    """The figure as PNG bytes (for embedding)."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi)
    return buf.getvalue()


#: Output formats by file suffix.
FORMATS = {".png": "png", ".svg": "svg", ".pdf": "pdf"}


def output_format(path: Path) -> str:
    """The figure format of ``path``'s suffix; LookError for one matplotlib is not asked for."""
    fmt = FORMATS.get(path.suffix.lower())
    if fmt is None:
        raise LookError(f"output {path}: unknown format {path.suffix!r}; use {', '.join(FORMATS)}")
    return fmt


def save_figure(
    fig: Any, path: str | os.PathLike[str], *, overwrite: bool = False, dpi: int = 100
) -> Path:
    """Write ``fig`` to ``path`` (format from the suffix) through ``path.tmp`` and a rename;
    FileExistsError if ``path`` exists and not ``overwrite``."""
    path = Path(path)
    fmt = output_format(path)
    with replacing(path, overwrite=overwrite) as tmp:
        fig.savefig(tmp, format=fmt, dpi=dpi)
        fsync_path(tmp)
    return path

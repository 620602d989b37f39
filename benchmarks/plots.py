"""Figures: matplotlib on the Agg backend, saved atomically."""

from __future__ import annotations

import io
import os
from pathlib import Path

from hysbench.data.files import write_atomic


def save_figure(fig, path: str | os.PathLike, dpi: int = 110, tight: bool = True) -> Path:
    """Save a matplotlib figure atomically (PNG) and close it. ``tight``: crop to what is drawn (one more
    drawing pass); a figure made with ``layout="constrained"`` needs no crop."""
    plt = pyplot()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight" if tight else None)
    plt.close(fig)
    return write_atomic(path, buf.getvalue())


def pyplot():
    """matplotlib.pyplot on the non-interactive Agg backend (no screen needed)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt

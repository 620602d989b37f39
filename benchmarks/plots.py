"""Figures: matplotlib on the Agg backend, saved atomically."""

from __future__ import annotations

import io
import os
from pathlib import Path

from hysbench.data.files import write_atomic


def save_figure(fig, path: str | os.PathLike, dpi: int = 110) -> Path:
    """Save a matplotlib figure atomically (PNG) and close it: cropped to what is drawn (one more drawing
    pass), unless it was made with ``layout="constrained"``, which already fits it."""
    from matplotlib.layout_engine import ConstrainedLayoutEngine

    plt = pyplot()
    buf = io.BytesIO()
    laid_out = isinstance(fig.get_layout_engine(), ConstrainedLayoutEngine)
    fig.savefig(buf, format="png", dpi=dpi, bbox_inches=None if laid_out else "tight")
    plt.close(fig)
    return write_atomic(path, buf.getvalue())


def pyplot():
    """matplotlib.pyplot on the non-interactive Agg backend (no screen needed)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt

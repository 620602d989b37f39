"""Figures: matplotlib on the Agg backend, saved atomically, and the conventions every figure shares (a series'
style, axis labels with units, legends off the data)."""

from __future__ import annotations

import io
import os
from pathlib import Path

from hysbench.data.files import write_atomic

# Colour, line style and marker all change from one series to the next, with periods 10, 4 and 7: up to 140
# series stay apart, also when printed in grey, where colours alone do not.
LINESTYLES = ("-", "--", "-.", ":")
MARKERS = ("o", "s", "^", "D", "v", "P", "X")

# ASCII spellings of units in dataset files, as they are printed
UNIT_SYMBOLS = {"um": "µm", "uV": "µV", "uA": "µA", "uC/cm2": "µC/cm²", "mC/m2": "mC/m²", "C/m2": "C/m²",
                "cm2": "cm²", "m2": "m²", "degC": "°C"}


def save_figure(fig, path: str | os.PathLike, dpi: int = 110) -> Path:
    """Save a matplotlib figure atomically (PNG) and close it: cropped to what is drawn (one more drawing
    pass), unless it was made with ``layout="constrained"``, which already fits it."""
    from matplotlib.layout_engine import ConstrainedLayoutEngine

    plt = pyplot()
    buf = io.BytesIO()
    _title_beside_legends(fig)
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


def series_style(i: int, marker: bool = True) -> dict:
    """Keyword arguments of ``plot`` for the i-th series of a figure (colour, line style and, if ``marker``, a
    marker)."""
    style = {"color": f"C{i % 10}", "ls": LINESTYLES[i % len(LINESTYLES)]}
    if marker:
        style["marker"] = MARKERS[i % len(MARKERS)]
    return style


def unit_text(unit: str | None) -> str:
    return UNIT_SYMBOLS.get(unit or "", unit or "")


def axis_label(quantity: str, unit: str | None = None) -> str:
    """``"quantity (unit)"``; the quantity alone when the unit is not known."""
    unit = unit_text(unit)
    return f"{quantity} ({unit})" if unit else quantity


def legend_outside(ax, **kwargs):
    """The axes' legend to the right of it, where it cannot cover data (the saved figure is widened to hold it)."""
    kwargs.setdefault("fontsize", 7)
    return ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0, **kwargs)


def figure_legend(fig, ax, **kwargs):
    """One legend for a figure of panels, with the entries of ``ax``, to the right of the panels (the figure must
    be made with ``layout="constrained"``; below them it would collide with a ``supxlabel``)."""
    handles, labels = ax.get_legend_handles_labels()
    kwargs.setdefault("fontsize", 8)
    return fig.legend(handles, labels, loc="outside right upper", **kwargs)


def ticks_at(ax, values, axis: str = "x") -> None:
    """Ticks at exactly these values, labelled as plain numbers (a log axis otherwise labels only its decades)."""
    import numpy as np

    values = sorted(set(values))
    target = ax.xaxis if axis == "x" else ax.yaxis
    log = target.get_scale() == "log"
    close = len(values) > 1 and np.min(np.diff(np.log10(values) if log else values)) < 0.15 * (
        np.ptp(np.log10(values)) if log else np.ptp(values))
    # level, labels closer than 15 % of the span would run together
    target.set_ticks(values, [f"{v:g}" for v in values], rotation=45 if close and axis == "x" else 0)
    target.set_minor_locator(_null_locator())


def plain_log_labels(ax, axis: str = "y") -> None:
    """A log axis labelled 0.1, 1, 10 rather than as powers of ten (and its minor ticks, where matplotlib labels
    them, as 20, 30)."""
    from matplotlib.ticker import LogFormatter

    class Plain(LogFormatter):
        def __call__(self, x, pos=None):
            return f"{x:g}" if super().__call__(x, pos) else ""

    target = ax.xaxis if axis == "x" else ax.yaxis
    target.set_major_formatter(Plain())
    target.set_minor_formatter(Plain(labelOnlyBase=False))


def _null_locator():
    from matplotlib.ticker import NullLocator

    return NullLocator()


def _has_data(ax) -> bool:
    if getattr(ax, "_colorbar", None) is not None:  # a colour bar: its one label is the scale's
        return False
    return ax.get_visible() and ax.axison and bool(ax.lines or ax.collections or ax.patches or ax.images)


def _drawn(fig):
    """A renderer of the figure as laid out when drawn."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    canvas = fig.canvas if hasattr(fig.canvas, "get_renderer") else FigureCanvasAgg(fig)  # a Figure() has none
    canvas.draw()
    return canvas.get_renderer()


def _title_beside_legends(fig) -> None:
    """Wrap the figure's title to the width a legend beside the panels leaves it (the title is centred on the
    figure, the legend reaches its top): a title of any length, on a figure of any number of panels."""
    import textwrap

    title = fig._suptitle
    if title is None or not title.get_text() or not fig.legends:
        return
    renderer = _drawn(fig)
    right = max(fig.bbox.x1 - g.get_window_extent(renderer).x0 for g in fig.legends)
    room = fig.bbox.width - 2 * right - 10
    box = title.get_window_extent(renderer)
    if box.width <= room:
        return
    lines = title.get_text().split("\n")
    per_char = box.width / max(len(line) for line in lines)
    width = max(20, int(room / per_char))
    title.set_text("\n".join(w for line in lines for w in textwrap.wrap(line, width)))


def _titles_under_legends(fig) -> list[str]:
    """The figure's and the axes' titles that a legend covers, where the figure is laid out when drawn."""
    renderer = _drawn(fig)
    legends = list(fig.legends) + [ax.get_legend() for ax in fig.axes if ax.get_legend() is not None]
    titles = [t for t in [fig._suptitle] + [ax.title for ax in fig.axes] if t is not None and t.get_text()]
    return [f"the title {t.get_text()!r} runs under a legend" for t in titles
            if any(t.get_window_extent(renderer).overlaps(g.get_window_extent(renderer)) for g in legends)]


def unreadable(fig) -> list[str]:
    """What a reader could not tell from the figure alone: drawn axes without an x or y label (their own, one
    of the axes they share it with, or the figure's ``supxlabel``/``supylabel``), no title at all, and a
    title a legend covers."""
    problems = _titles_under_legends(fig)
    drawn = [ax for ax in fig.axes if _has_data(ax)]
    if not (fig._suptitle is not None and fig._suptitle.get_text()) and not any(ax.get_title() for ax in fig.axes):
        problems.append("the figure has no title")
    for which, sup in (("x", fig._supxlabel), ("y", fig._supylabel)):
        if sup is not None and sup.get_text():
            continue
        for ax in drawn:
            shared = getattr(ax, f"get_shared_{which}_axes")().get_siblings(ax)
            if not any(getattr(a, f"get_{which}label")() for a in shared):
                problems.append(f"axes {ax.get_title() or fig.axes.index(ax)!r} has no {which} label")
    return problems

"""``Window``: the samples of a record that are scored or fitted (one value type).

A window spans [start, stop) of a record and is either all of it (``rows`` is
None: a contiguous window) or a row subset (``rows``: increasing sample
indices within the span). Models still run from the record's first sample; a
window only says which outputs to keep. ``Window.of`` accepts a Window, a
slice with step 1, or an array of increasing indices, and checks it against
the record's length: the model interface converts whatever it is given at its
entry, so identifiers may pass any of the three.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import ModelError


@dataclass(frozen=True, eq=False)
class Window:
    start: int
    stop: int
    rows: np.ndarray | None = None  # increasing sample indices, or None for every sample of the span

    @classmethod
    def of(cls, window, n_samples: int, owner: str = "window") -> "Window":
        if isinstance(window, Window):
            if window.stop > n_samples:
                raise ModelError(f"{owner}: a window reaching sample {window.stop} on a record of {n_samples}")
            return window
        if isinstance(window, slice):
            start, stop, step = window.indices(n_samples)
            if step != 1 or stop <= start:
                raise ModelError(f"{owner}: a window must be a non-empty slice with step 1, got {window!r}")
            return cls(start, stop)
        rows = np.asarray(window)
        if (rows.ndim != 1 or rows.size == 0 or not np.issubdtype(rows.dtype, np.integer)
                or rows[0] < 0 or rows[-1] >= n_samples or np.any(np.diff(rows) <= 0)):
            raise ModelError(f"{owner}: a window must be a slice or increasing sample indices within the "
                             f"record's {n_samples} samples")
        rows = np.ascontiguousarray(rows, dtype=np.int64)
        return cls(int(rows[0]), int(rows[-1]) + 1, rows)

    @property
    def index(self):
        """What indexes a record's arrays: a slice, or the rows."""
        return slice(self.start, self.stop) if self.rows is None else self.rows

    @property
    def in_span(self):
        """What to take from an array computed over [start, stop)."""
        return slice(None) if self.rows is None else self.rows - self.start

    def __len__(self) -> int:
        return self.stop - self.start if self.rows is None else int(self.rows.size)

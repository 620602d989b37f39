"""The benchmark matrix: every model x identifier x dataset, scored on the protocol.

``cells`` defines and runs one cell, ``store`` keeps finished cells on disk,
``execute`` runs many (local processes or a Dask cluster), ``report`` writes
matrix.csv, report.md and the figures, ``cli`` is ``hysbench run``.
"""

from .cells import Cell, CellResult, plan_cells, run_cell
from .execute import run_matrix

__all__ = ["Cell", "CellResult", "plan_cells", "run_cell", "run_matrix"]

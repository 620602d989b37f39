"""The causes a diagnosis can name: one ``Cause`` subclass per module, registered by name (``CAUSES``).

Adding a cause is one module here with a ``Cause`` subclass decorated ``@register``, named on the import line below
(its place there is its place in the search), and its extension registered with ``hysbench.models.extended``.
"""

from ..cause import CAUSES, OUTPUT_UNIT, Cause, cause_of_parameter, get_cause, log_scale, refined, register
from . import relaxation, delay, resonance, creep, interference, saturation  # noqa: F401 (the search's order)

__all__ = ["CAUSES", "OUTPUT_UNIT", "Cause", "cause_of_parameter", "get_cause", "log_scale", "refined", "register",
           "relaxation", "delay", "resonance", "creep", "interference", "saturation"]

"""The causes a diagnosis can name: one class per cause behind one interface (``Cause``), registered by name.

``CAUSES["delay"]`` (or ``get_cause("delay")``) is the delay's ``Cause``; ``Candidate.kind`` is its candidate's.
Everything the diagnosis does differently for one cause is an attribute or a method of its class: how its
extension is fitted on the screen, its parameters in the report's vocabulary and their search bounds, what
keeps its meaning (``limit``), how it is scored on a held-out record, whether it composes with other causes,
how the validation records confirm it, which drive separates it from another cause. Adding a cause is one
module here with a ``Cause`` subclass decorated ``@register``, named on the import line below (its place there
is its place in the search), its extension registered with ``hysbench.models.extended``.
"""

from ..cause import CAUSES, OUTPUT_UNIT, Cause, cause_of_parameter, get_cause, log_scale, refined, register
from . import relaxation, delay, resonance, creep, interference, saturation  # noqa: F401 (the search's order)

__all__ = ["CAUSES", "OUTPUT_UNIT", "Cause", "cause_of_parameter", "get_cause", "log_scale", "refined", "register",
           "relaxation", "delay", "resonance", "creep", "interference", "saturation"]

"""Hysteresis models behind one interface (see ``base.HysteresisModel``)."""

from .base import DataScale, HysteresisModel, Parameter
from .classical_pi import ClassicalPI
from .errors import HysbenchError, ModelError
from .extended import CAUSES, ExtendedModel, register_extensions
from .mrpim import MRPIM, PAPER_TABLE2
from .registry import get_model, list_models, register
from .viscoelastic import Viscoelastic

register(ClassicalPI.name, ClassicalPI)
register(MRPIM.name, MRPIM)
register(Viscoelastic.name, Viscoelastic)
register_extensions(MRPIM.name)  # mrpim+relaxation, mrpim+delay, ... (see extended.py)

__all__ = [
    "CAUSES",
    "ClassicalPI",
    "ExtendedModel",
    "DataScale",
    "HysbenchError",
    "HysteresisModel",
    "MRPIM",
    "ModelError",
    "PAPER_TABLE2",
    "Parameter",
    "Viscoelastic",
    "get_model",
    "list_models",
    "register",
]

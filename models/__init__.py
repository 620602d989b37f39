"""Hysteresis models behind one interface (see ``base.HysteresisModel``)."""

from . import numba_cache  # noqa: F401  (first: numba's cache folder, before any kernel is defined)
from .base import DataScale, HysteresisModel, Parameter
from .black_box import NeuralNARX, SparseNARX
from .bouc_wen import BoucWen
from .bouc_wen_oscillator import BoucWenOscillator
from .classical_pi import ClassicalPI
from .dual_polynomial import DualPolynomial
from .elliptical import Elliptical
from .errors import HysbenchError, ModelError
from .extended import CAUSES, ExtendedModel, register_extensions
from .model_file import FittedModel, ModelFileError, load_model
from .mrpim import MRPIM, PAPER_TABLE2
from .preisach import Preisach
from .rate_dependent_pi import RateDependentPI
from .stepper import InverseStepper, Stepper
from .recurrent import RecurrentNetwork
from .registry import get_model, list_models, register
from .viscoelastic import Viscoelastic
from .window import Window

register(ClassicalPI.name, ClassicalPI)
register(MRPIM.name, MRPIM)
register(Viscoelastic.name, Viscoelastic)
# baselines
register(Elliptical.name, Elliptical)
register(DualPolynomial.name, DualPolynomial)
register(BoucWen.name, BoucWen)
register(Preisach.name, Preisach)
register(RateDependentPI.name, RateDependentPI)
# the Bouc-Wen benchmark's structure: force -> displacement, not a DEA model
register(BoucWenOscillator.name, BoucWenOscillator, in_matrix=False)
# black-box learners, trained by their own library (method "native")
register(SparseNARX.name, SparseNARX)
register(NeuralNARX.name, NeuralNARX)
# trains with the optional extra [neural] (PyTorch): named with --models, not in the default matrix
register(RecurrentNetwork.name, RecurrentNetwork, in_matrix=False)
# mrpim+relaxation, mrpim+delay, ... (see extended.py); the diagnosis names relaxation on the
# default dataset (results/diagnosis.md), so that extension joins the default matrix.
register_extensions(MRPIM.name, in_matrix=("relaxation",))

__all__ = [
    "BoucWen",
    "BoucWenOscillator",
    "CAUSES",
    "ClassicalPI",
    "ExtendedModel",
    "FittedModel",
    "DataScale",
    "DualPolynomial",
    "Elliptical",
    "HysbenchError",
    "HysteresisModel",
    "InverseStepper",
    "MRPIM",
    "ModelError",
    "ModelFileError",
    "NeuralNARX",
    "PAPER_TABLE2",
    "Parameter",
    "Preisach",
    "RateDependentPI",
    "Stepper",
    "RecurrentNetwork",
    "SparseNARX",
    "Viscoelastic",
    "Window",
    "get_model",
    "list_models",
    "load_model",
    "register",
]

"""Find what a model gets wrong: show it, name the cause, extend the model, measure the gain.

``diagnose(dataset, model="mrpim")`` -> ``Diagnosis`` (see ``diagnose``, ``result``);
``hysbench diagnose DATASET`` writes diagnosis.md, its figures and JSON
(``report``; the command is ``hysbench.benchmarks.cli.diagnose``). The causes it can name are plug-ins
(``causes``: one module per cause, registered in ``causes.CAUSES``); the thresholds of its decision are one
``policy.Policy``. How accurate it is on planted effects: ``hysbench.benchmarks.diagnosis_accuracy``.
"""

from .candidates import Candidate
from .screen import Screen
from .diagnose import DiagnosisError, diagnose
from .result import Diagnosis

__all__ = ["Candidate", "Diagnosis", "DiagnosisError", "Screen", "diagnose"]

"""Find what a model gets wrong: show it, name the cause, extend the model, measure the gain.

``diagnose(dataset, model="mrpim")`` -> ``Diagnosis``; ``hysbench diagnose DATASET`` writes diagnosis.md, its
figures and JSON (``report``). The causes are plug-ins (``causes.CAUSES``), the thresholds one ``policy.Policy``;
accuracy on planted effects: ``hysbench.benchmarks.diagnosis_accuracy``.
"""

from .candidates import Candidate
from .screen import Screen
from .diagnose import DiagnosisError, diagnose
from .result import Diagnosis

__all__ = ["Candidate", "Diagnosis", "DiagnosisError", "Screen", "diagnose"]

"""Find what a model gets wrong: show it, name the cause, extend the model, measure the gain.

``diagnose(dataset, model="mrpim")`` -> ``Diagnosis`` (see ``diagnose``);
``hysbench diagnose DATASET`` writes diagnosis.md, its figures and JSON
(``report``, ``cli``). ``planted`` makes test data with one known effect.
"""

from .candidates import Candidate
from .screen import Screen
from .diagnose import Diagnosis, DiagnosisError, diagnose

__all__ = ["Candidate", "Diagnosis", "DiagnosisError", "Screen", "diagnose"]

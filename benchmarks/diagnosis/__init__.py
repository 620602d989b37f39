"""Find what a model gets wrong: show it, name the cause, extend the model, measure the gain.

``diagnose(dataset, model="mrpim")`` -> ``Diagnosis`` (see ``diagnose``);
``hysbench diagnose DATASET`` writes diagnosis.md, its figures and JSON
(``report``; the command is ``hysbench.benchmarks.cli.diagnose``). ``planted`` plants effects with
functional forms independent of the extensions; ``accuracy`` measures the diagnosis on them and
``evidence_ceiling`` how much held-out evidence each planted effect gives by itself.
"""

from .candidates import Candidate
from .screen import Screen
from .diagnose import Diagnosis, DiagnosisError, diagnose

__all__ = ["Candidate", "Diagnosis", "DiagnosisError", "Screen", "diagnose"]

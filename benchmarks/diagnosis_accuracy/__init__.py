"""The diagnosis accuracy study: ``hysbench diagnose`` measured on planted effects.

``planted`` plants effects with functional forms independent of the diagnosis's extensions (also used by the
tests); ``accuracy`` runs a plan of planted cases and judges each verdict; ``rows`` stores every plan's rows in one
file; ``pooled`` pools plans; ``stated_limits`` states and reads the detection limits; ``evidence_ceiling`` and
``own_timing`` measure what a planted effect can show by itself. The command is ``hysbench accuracy``.
"""

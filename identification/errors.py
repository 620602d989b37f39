"""Errors of the identifiers: printed by the CLI as one line, exit status 2."""

from hysbench.models.errors import HysbenchError


class IdentificationError(HysbenchError):
    """A model, dataset, method or option that an identifier cannot handle."""

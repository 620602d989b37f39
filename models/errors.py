"""Errors that the command line reports as one line with exit status 2."""


class HysbenchError(Exception):
    """Base of every error that is the user's input, not a bug."""


class ModelError(HysbenchError):
    """An unknown model, a bad hyperparameter or a bad parameter set."""

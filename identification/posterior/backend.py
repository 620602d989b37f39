"""The chain file: emcee's HDF5 layout, written every few steps, resumed when the settings match.

Besides emcee's group "mcmc" the file holds three JSON attributes: ``hysbench_settings`` (the settings
fingerprint, its ``format`` the file's version, ``CHAIN_FORMAT``), ``hysbench_start`` (the start: modes and
their covariances) and ``hysbench_seconds`` (``wall`` and ``sampling`` over every run that built the chain).
An existing file is read strictly (``read_chain``): not HDF5 or truncated, another format, an attribute or
dataset missing or of the wrong type or shape is refused with ``ChainFileError``, one line naming the file and
what is wrong; the file is left as it is (``--restart`` discards it).
"""

from __future__ import annotations

import json
from pathlib import Path

import emcee
import h5py
import numpy as np

from hysbench.data.dataset import Dataset

from ..errors import IdentificationError
from .target import LogPosterior

# 2: discrepancy coefficients among the blobs; 3: walkers start in every separated mode, with mode
# jumps; 4: ensemble moves within modes, jumps mapped by the modes' Laplace shapes; 5: jumps mapped by each
# mode's mean and covariance from a pilot run
CHAIN_FORMAT = "hysbench-posterior-chain/5"


# --- the chain file ------------------------------------------------------------------
def settings_fingerprint(post: LogPosterior, dataset: Dataset, n_walkers: int, seed, moves: str) -> dict:
    return {
        "format": CHAIN_FORMAT,
        "dataset_hash": dataset.content_hash(),
        "fitted_records": [s.file for s in post.segments],
        "model": post.model.name,
        "hyperparameters": {k: (v if isinstance(v, (int, float, str, bool)) or v is None else repr(v))
                            for k, v in post.model.get_hyperparameters().items()},
        "noise": post.noise,
        "discrepancy": post.discrepancy,
        "walkers": int(n_walkers),
        "seed": None if seed is None else int(seed),
        "moves": moves,
        "priors": post.priors.describe(),
    }


class ChainFileError(IdentificationError):
    """A chain file that cannot be resumed: not HDF5 or truncated, of another format, or an attribute or dataset
    missing or of the wrong type or shape."""


DISCARD = "use --restart to discard it, or another --chain file"
RANDOM_STATE = 5  # numpy's RandomState.get_state(): name, keys, pos, has_gauss, cached_gaussian


def _is_int(v) -> bool:
    return isinstance(v, (int, np.integer)) and not isinstance(v, (bool, np.bool_))


def _is_number(v) -> bool:
    return _is_int(v) or isinstance(v, (float, np.floating))


def _json_attr(attrs, name: str, where: str, required: bool = True) -> dict | None:
    """A JSON-object attribute of the file (None if absent and not ``required``)."""
    if name not in attrs:
        if required:
            raise ChainFileError(f"{where}: no attribute {name!r}; {DISCARD}")
        return None
    value = attrs[name]
    if isinstance(value, bytes):
        value = value.decode("utf-8", "replace")
    if not isinstance(value, str):
        raise ChainFileError(f"{where}: attribute {name!r} must be JSON text, got {type(value).__name__}; {DISCARD}")
    try:
        out = json.loads(value)
    except ValueError:
        raise ChainFileError(f"{where}: attribute {name!r} is not JSON; {DISCARD}") from None
    if not isinstance(out, dict):
        raise ChainFileError(f"{where}: attribute {name!r} must be a JSON object; {DISCARD}")
    return out


def _check_start(start: dict, coord_names: list[str], where: str) -> None:
    """The stored start holds its modes as ``modes.mode_locations`` and the mode jumps read them."""
    d = len(coord_names)

    def bad(field: str, what: str):
        raise ChainFileError(f"{where}: attribute 'hysbench_start' field {field!r} must be {what}; {DISCARD}")

    def matrix(v, rows: int, cols: int) -> bool:
        return (isinstance(v, list) and len(v) == rows
                and all(isinstance(r, list) and len(r) == cols and all(_is_number(x) for x in r) for r in v))

    modes = start.get("modes")
    if not isinstance(modes, list) or not modes:
        bad("modes", "a non-empty list of modes")
    for i, m in enumerate(modes):
        if not isinstance(m, dict):
            bad(f"modes[{i}]", "an object")
        mode = m.get("mode")
        if not (isinstance(mode, dict) and all(_is_number(mode.get(n)) for n in coord_names)):
            bad(f"modes[{i}].mode", f"an object with a number for each of {', '.join(coord_names)}")
        if not matrix(m.get("covariance"), d, d):
            bad(f"modes[{i}].covariance", f"a {d} x {d} list of numbers")
        if "pilot_covariance" in m and not matrix(m["pilot_covariance"], d, d):
            bad(f"modes[{i}].pilot_covariance", f"a {d} x {d} list of numbers")
        if "pilot_mean" in m and not matrix([m["pilot_mean"]], 1, d):
            bad(f"modes[{i}].pilot_mean", f"a list of {d} numbers")


def seconds_of(attrs, where: str) -> dict:
    """``hysbench_seconds``: {"wall", "sampling"} spent on the chain so far (zeros if not written yet)."""
    out = _json_attr(attrs, "hysbench_seconds", where, required=False)
    if out is None:
        return {"wall": 0.0, "sampling": 0.0}
    for key in ("wall", "sampling"):
        if not _is_number(out.get(key)):
            raise ChainFileError(f"{where}: attribute 'hysbench_seconds' field {key!r} must be a number; {DISCARD}")
    return out


def _dataset(g, name: str, shape: tuple, where: str) -> np.ndarray:
    """A dataset of group "mcmc" whose shape is ``shape`` (its first axis: at least shape[0] steps), read."""
    if name not in g or not isinstance(g[name], h5py.Dataset):
        raise ChainFileError(f"{where}: no dataset 'mcmc/{name}'; {DISCARD}")
    data = g[name]
    if len(data.shape) != len(shape) or data.shape[0] < shape[0] or tuple(data.shape[1:]) != tuple(shape[1:]):
        raise ChainFileError(f"{where}: dataset 'mcmc/{name}' has shape {data.shape}, expected "
                             f"{('>= %d' % shape[0],) + tuple(shape[1:])}; {DISCARD}")
    return data[:shape[0]]


def _read_chain(f, path: Path, fingerprint: dict, coord_names: list[str] | None) -> dict:
    where = str(path)
    settings = _json_attr(f.attrs, "hysbench_settings", where)
    if "format" not in settings:
        raise ChainFileError(f"{where}: attribute 'hysbench_settings' has no field 'format'; {DISCARD}")
    if settings["format"] != CHAIN_FORMAT:
        raise ChainFileError(f"{where}: a chain of format {settings['format']!r}; this hysbench resumes "
                             f"{CHAIN_FORMAT!r} only; {DISCARD}")
    if json.dumps(settings, sort_keys=True) != json.dumps(fingerprint, sort_keys=True):
        diff = sorted(k for k in set(settings) | set(fingerprint) if settings.get(k) != fingerprint.get(k))
        raise ChainFileError(f"{where} holds a chain for other settings (differs in: {', '.join(diff)}); {DISCARD}")
    seconds_of(f.attrs, where)
    if "mcmc" not in f:
        return {"iteration": 0}
    g = f["mcmc"]
    if not isinstance(g, h5py.Group):
        raise ChainFileError(f"{where}: 'mcmc' is not a group; {DISCARD}")
    attrs = g.attrs
    for name in ("iteration", "nwalkers", "ndim"):
        if name not in attrs:
            raise ChainFileError(f"{where}: group 'mcmc' has no attribute {name!r}; {DISCARD}")
        if not _is_int(attrs[name]) or attrs[name] < 0:
            raise ChainFileError(f"{where}: attribute 'mcmc/{name}' must be an integer >= 0, got "
                                 f"{attrs[name]!r}; {DISCARD}")
    n, walkers, ndim = (int(attrs[k]) for k in ("iteration", "nwalkers", "ndim"))
    if walkers != fingerprint["walkers"]:
        raise ChainFileError(f"{where}: attribute 'mcmc/nwalkers' is {walkers}, its settings say "
                             f"{fingerprint['walkers']}; {DISCARD}")
    if coord_names is not None and ndim != len(coord_names):
        raise ChainFileError(f"{where}: attribute 'mcmc/ndim' is {ndim}, the posterior samples {len(coord_names)} "
                             f"coordinates; {DISCARD}")
    if n == 0:
        return {"iteration": 0}
    start = _json_attr(f.attrs, "hysbench_start", where)
    if coord_names is not None:
        _check_start(start, coord_names, where)
    has_blobs = attrs.get("has_blobs")
    if not isinstance(has_blobs, (bool, np.bool_)):
        raise ChainFileError(f"{where}: attribute 'mcmc/has_blobs' must be true or false; {DISCARD}")
    state = [attrs.get(f"random_state_{i}") for i in range(RANDOM_STATE)]
    if any(v is None for v in state) or any(k.startswith("random_state_") and k[13:] not in
                                            {str(i) for i in range(RANDOM_STATE)} for k in attrs):
        raise ChainFileError(f"{where}: group 'mcmc' lacks its random state (attributes random_state_0 to "
                             f"random_state_{RANDOM_STATE - 1}); {DISCARD}")
    try:
        np.random.RandomState().set_state(tuple(state))
    except (TypeError, ValueError):
        raise ChainFileError(f"{where}: attributes 'mcmc/random_state_*' are not a random state; {DISCARD}") from None
    out = {"iteration": n, "nwalkers": walkers, "ndim": ndim, "start": start, "random_state": state,
           "chain": _dataset(g, "chain", (n, walkers, ndim), where),
           "log_prob": _dataset(g, "log_prob", (n, walkers), where),
           "accepted": _dataset(g, "accepted", (walkers,), where)}
    if has_blobs:
        out["blobs"] = _dataset(g, "blobs", (n, walkers), where)
    for name in ("chain", "log_prob", "accepted"):
        if out[name].dtype.kind not in "fiu":
            raise ChainFileError(f"{where}: dataset 'mcmc/{name}' is not numeric; {DISCARD}")
    return out


def read_chain(path: Path, fingerprint: dict, coord_names: list[str] | None = None) -> dict:
    """The chain stored at ``path`` for the settings ``fingerprint`` ({"iteration": 0} when it holds no step):
    "iteration", "nwalkers", "ndim", "start", "random_state", "chain", "log_prob", "accepted" and "blobs" (if
    stored), every attribute and dataset checked (``coord_names``: the sampled coordinates the start's modes and
    the chain's width must match). ChainFileError, one line, for anything else."""
    try:
        with h5py.File(path, "r") as f:
            return _read_chain(f, path, fingerprint, coord_names)
    except ChainFileError:
        raise
    except (OSError, KeyError, ValueError, TypeError, RuntimeError) as e:  # h5py: not HDF5, truncated, damaged
        reason = " ".join(str(e).split())[:120]
        raise ChainFileError(f"{path} is not an HDF5 chain file, or is truncated or damaged ({reason}); "
                             f"{DISCARD}") from None


def _checkpointed_backend_class():
    class CheckpointedBackend(emcee.backends.Backend):
        """emcee's in-memory backend, written to an HDF5 file every ``every`` steps and on ``flush()``.

        The file has the layout of emcee's ``HDFBackend`` (group "mcmc"), so
        emcee can read it. emcee's own HDF5 backend opens the file at every
        step, which cost about ten times a sampler step here.
        """

        def __init__(self, path: Path, every: int = 50):
            super().__init__()
            self.path = Path(path)
            self.every = int(every)
            self.flushed = 0

        def load(self, stored: dict) -> None:
            """A chain read by ``read_chain``, into memory."""
            n = stored["iteration"]
            self.reset(stored["nwalkers"], stored["ndim"])
            blobs = stored.get("blobs")
            self.grow(n, None if blobs is None else blobs[0])
            self.chain[:n] = stored["chain"]
            self.log_prob[:n] = stored["log_prob"]
            if blobs is not None:
                self.blobs[:n] = blobs
            self.accepted = np.array(stored["accepted"], dtype=float)
            self.random_state = stored["random_state"]
            self.iteration = n
            self.flushed = n

        def save_step(self, state, accepted):
            super().save_step(state, accepted)
            if self.iteration - self.flushed >= self.every:
                self.flush()

        def flush(self) -> None:
            a, b = self.flushed, self.iteration
            if b <= a:
                return
            with h5py.File(self.path, "a") as f:
                if "mcmc" not in f:
                    g = f.create_group("mcmc")
                    g.attrs.update(version=emcee.__version__, nwalkers=self.nwalkers, ndim=self.ndim,
                                   has_blobs=self.blobs is not None, iteration=0)
                    g.create_dataset("accepted", data=np.zeros(self.nwalkers))
                    g.create_dataset("chain", (0, self.nwalkers, self.ndim),
                                     maxshape=(None, self.nwalkers, self.ndim), dtype=float)
                    g.create_dataset("log_prob", (0, self.nwalkers), maxshape=(None, self.nwalkers), dtype=float)
                    if self.blobs is not None:
                        dt = np.dtype((self.blobs.dtype, self.blobs.shape[2:]))
                        g.create_dataset("blobs", (0, self.nwalkers), maxshape=(None, self.nwalkers), dtype=dt)
                g = f["mcmc"]
                names = ["chain", "log_prob"] + (["blobs"] if self.blobs is not None else [])
                for name in names:
                    g[name].resize(b, axis=0)
                    g[name][a:b] = getattr(self, name)[a:b]
                g["accepted"][:] = self.accepted
                for i, v in enumerate(self.random_state):
                    g.attrs[f"random_state_{i}"] = v
                g.attrs["iteration"] = b
            self.flushed = b

    return CheckpointedBackend


def open_backend(path: Path, fingerprint: dict, restart: bool, every: int = 50,
                 coord_names: list[str] | None = None):
    """A checkpointed chain at ``path``: (backend, steps already stored, stored start info).

    A file that holds a chain for the same settings is loaded to be resumed (``read_chain``); one for other
    settings, of another format, or that cannot be read is refused (ChainFileError) and left as it is, unless
    ``restart``. A file of these settings without a stored step is started afresh.
    """
    backend = _checkpointed_backend_class()(path, every)
    if path.exists() and not restart:
        stored = read_chain(path, fingerprint, coord_names)
        if stored["iteration"]:
            backend.load(stored)
            return backend, backend.iteration, stored["start"]
    if path.exists():
        path.unlink()
    with h5py.File(path, "w") as f:
        f.attrs["hysbench_settings"] = json.dumps(fingerprint, sort_keys=True)
    return backend, 0, None


def store_start(path: Path | None, start: dict) -> None:
    if path is None:
        return
    with h5py.File(path, "a") as f:
        f.attrs["hysbench_start"] = json.dumps(start)



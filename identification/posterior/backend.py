"""The chain file: emcee's HDF5 layout, written every few steps, resumed when the settings match."""

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

        def load(self) -> None:
            """The chain stored in the file, into memory."""
            stored = emcee.backends.HDFBackend(str(self.path), read_only=True)
            n = int(stored.iteration)
            n_walkers, ndim = stored.shape
            self.reset(n_walkers, ndim)
            blobs = stored.get_blobs()
            self.grow(n, None if blobs is None else blobs[0])
            self.chain[:n] = stored.get_chain()
            self.log_prob[:n] = stored.get_log_prob()
            if blobs is not None:
                self.blobs[:n] = blobs
            self.accepted = np.array(stored.accepted, dtype=float)
            self.random_state = stored.random_state
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


def open_backend(path: Path, fingerprint: dict, restart: bool, every: int = 50):
    """A checkpointed chain at ``path``: (backend, steps already stored, stored start info).

    A file that holds a chain for the same settings is loaded to be resumed;
    one for other settings is refused unless ``restart``.
    """
    key = json.dumps(fingerprint, sort_keys=True)
    backend = _checkpointed_backend_class()(path, every)
    if path.exists() and not restart:
        try:
            with h5py.File(path, "r") as f:
                stored = f.attrs.get("hysbench_settings")
                start_info = f.attrs.get("hysbench_start")
                has_chain = "mcmc" in f and int(f["mcmc"].attrs.get("iteration", 0)) > 0
        except OSError:
            raise IdentificationError(f"{path} exists but is not an HDF5 chain file; use --restart to replace it")
        if stored is None:
            raise IdentificationError(f"{path} is not a hysbench posterior chain; use --restart to replace it")
        if stored != key:
            old = json.loads(stored)
            diff = sorted(k for k in set(old) | set(fingerprint) if old.get(k) != fingerprint.get(k))
            raise IdentificationError(
                f"{path} holds a chain for other settings (differs in: {', '.join(diff)}); use --restart to "
                "discard it, or another --chain file")
        if has_chain:
            backend.load()
            return backend, backend.iteration, (json.loads(start_info) if start_info is not None else None)
    if path.exists():
        path.unlink()
    with h5py.File(path, "w") as f:
        f.attrs["hysbench_settings"] = key
    return backend, 0, None


def store_start(path: Path | None, start: dict) -> None:
    if path is None:
        return
    with h5py.File(path, "a") as f:
        f.attrs["hysbench_start"] = json.dumps(start)



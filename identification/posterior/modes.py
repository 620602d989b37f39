"""Separated posterior modes: found at the start, sampled together, jumped between.

A posterior can have separated modes (MRPIM on the virtual DEA: gamma near +0.07 and near -0.1,
a valley about 45 log units deep between them, each holding a good part of the mass). Walkers
started in one mode never find the other, and the chain then looks converged: its autocorrelation
times are those of one mode. So the mode search starts from the best few screened candidates and
keeps every mode that a valley separates from the others (``find_modes``); the walkers start split
evenly between them (``walkers_in_modes``); and a mode-jump move (``ModeJump``) proposes, for
each walker, the shift from its nearest mode to another one. That proposal is symmetric, so the
chain sets the modes' weights itself, and the autocorrelation times (and ESS) include the
switching between modes.
"""

from __future__ import annotations

import emcee
import numpy as np

from ..errors import IdentificationError
from .start import find_mode, initial_walkers, noise_estimate
from .target import LogPosterior


MODE_SEARCHES = 6  # mode searches from the best screened candidates (fewer where they share a basin)
VALLEY_DEPTH = 10.0  # two points lie in separate modes if the log posterior between them dips this far below the lower
MODE_GAP = 10.0  # a mode this far (log posterior) below the best is not sampled


def separated(post: LogPosterior, a: np.ndarray, b: np.ndarray, depth: float = VALLEY_DEPTH, n: int = 9) -> bool:
    """True if the log posterior on the segment a-b (sampler coordinates, ``n`` interior points) falls
    more than ``depth`` below the lower of its ends: a valley between two modes."""
    t = np.linspace(0.0, 1.0, n + 2)[:, None]
    lp = post.log_prob(a[None] + t * (b - a)[None])
    lp = np.where(np.isfinite(lp), lp, -np.inf)
    return bool(np.min(lp[1:-1]) < min(lp[0], lp[-1]) - depth)


def find_modes(post: LogPosterior, starts: np.ndarray) -> list[dict]:
    """Posterior modes from start points (sampler coordinates, best first).

    A start in the basin of a mode already found (no valley between them, ``separated``) is
    skipped; a search that ends in a found mode's basin is dropped. Returns the modes best first,
    those within ``MODE_GAP`` of the best: dicts with ``x`` (sampler coordinates), ``cov``,
    ``info`` (``find_mode``'s) and ``log_posterior``.
    """
    modes: list[dict] = []
    for x0 in np.atleast_2d(starts):
        if any(not separated(post, x0, m["x"]) for m in modes):
            continue
        x, cov, info = find_mode(post, x0)
        if not np.isfinite(info["log_posterior"]) or any(not separated(post, x, m["x"]) for m in modes):
            continue
        modes.append({"x": x, "cov": cov, "info": info, "log_posterior": float(info["log_posterior"])})
    modes.sort(key=lambda m: -m["log_posterior"])
    if not modes:
        raise IdentificationError("posterior: no mode search started from a finite log posterior")
    return [m for m in modes if m["log_posterior"] >= modes[0]["log_posterior"] - MODE_GAP]


def mode_search_starts(post: LogPosterior, candidates: np.ndarray, searches: int = MODE_SEARCHES) -> np.ndarray:
    """The best ``searches`` screened theta_N candidates in sampler coordinates, each with the noise
    parameters estimated from its own residuals."""
    return np.array([post.coords(nl, *noise_estimate(post, nl)) for nl in candidates[:searches]])


def nearest_mode(post: LogPosterior, X: np.ndarray, modes: np.ndarray) -> np.ndarray:
    """Index of the nearest mode for each row of X (sampler coordinates), by distance in the
    nonlinear coordinates relative to their prior widths."""
    n_nl = len(post.nonlinear_names)
    if len(modes) < 2 or n_nl == 0:
        return np.zeros(len(X), dtype=int)
    w = post.priors.nonlinear_upper - post.priors.nonlinear_lower
    d = ((X[:, None, :n_nl] - np.asarray(modes)[None, :, :n_nl]) / w) ** 2
    return np.argmin(d.sum(axis=2), axis=1)


def mode_locations(post: LogPosterior, start: dict | None) -> np.ndarray:
    """The modes a run's walkers started in (sampler coordinates, best first), from its stored start:
    (k, d); a start from before the mode search has its one mode."""
    start = start or {}
    found = start.get("modes") or ([{"mode": start["mode"]}] if start.get("mode") else [])
    return np.array([[m["mode"][n] for n in post.coord_names] for m in found]).reshape(-1, post.ndim)


def walkers_in_modes(post: LogPosterior, modes: list[dict], n_walkers: int, rng: np.random.Generator) -> np.ndarray:
    """``n_walkers`` split evenly between the modes (the first ones get the remainder), each drawn from
    its mode's Laplace Gaussian; returns (n_walkers, d) and records each mode's count under "walkers"."""
    k = len(modes)
    counts = [n_walkers // k + (1 if i < n_walkers % k else 0) for i in range(k)]
    for m, c in zip(modes, counts):
        m["walkers"] = c
    return np.vstack([initial_walkers(post, m["x"], m["cov"], c, rng) for m, c in zip(modes, counts)])


class ModeJump(emcee.moves.MHMove):
    """Metropolis move x -> x + (m_j - m_i): i the mode nearest to x, j another mode drawn uniformly.

    The reverse proposal is drawn with the same probability when x + (m_j - m_i) is nearest to m_j;
    otherwise it could not be proposed back, and the move is rejected (log factor -inf).
    """

    def __init__(self, post: LogPosterior, modes: np.ndarray):
        self.post, self.modes = post, np.asarray(modes, dtype=float)
        super().__init__(self._propose)

    def _propose(self, coords: np.ndarray, random) -> tuple[np.ndarray, np.ndarray]:
        k = len(self.modes)
        i = nearest_mode(self.post, coords, self.modes)
        j = (i + 1 + random.randint(0, k - 1, size=len(coords))) % k
        q = coords + self.modes[j] - self.modes[i]
        back = nearest_mode(self.post, q, self.modes) == j
        return q, np.where(back, 0.0, -np.inf)


JUMP_SHARE = 0.1  # share of steps that are mode jumps when there are separated modes


def with_mode_jumps(moves, post: LogPosterior, modes: np.ndarray):
    """emcee moves (None: the stretch move) with ``ModeJump`` added at ``JUMP_SHARE`` when there are
    two or more modes; unchanged otherwise."""
    if len(modes) < 2:
        return moves
    base = [(emcee.moves.StretchMove(), 1.0)] if moves is None else list(moves)
    total = sum(w for _, w in base)
    return [(m, (1.0 - JUMP_SHARE) * w / total) for m, w in base] + [(ModeJump(post, modes), JUMP_SHARE)]

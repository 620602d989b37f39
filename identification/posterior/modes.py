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
        raise IdentificationError(
            f"posterior: no mode search started from a finite log posterior (of {post.n_evaluations} parameter sets "
            f"evaluated, {post.n_singular} had a linear part whose precision is not positive definite, e.g. a record "
            f"all but free of noise, and {post.n_nonfinite} a non-finite model output)")
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


def mode_covariances(post: LogPosterior, start: dict | None) -> list[np.ndarray] | None:
    """The covariances the mode jumps map by (sampler coordinates; the pilot's if it measured them, else the
    Laplace ones), from a run's stored start in ``mode_locations`` order; None if the start did not store them."""
    found = (start or {}).get("modes") or []
    key = "pilot_covariance" if found and all("pilot_covariance" in m for m in found) else "covariance"
    if not found or any(key not in m for m in found):
        return None
    return [np.array(m[key], dtype=float).reshape(post.ndim, post.ndim) for m in found]


def jump_centres(post: LogPosterior, start: dict | None) -> np.ndarray | None:
    """The pilot's mean of each mode (sampler coordinates), if it measured them; else None (the modes)."""
    found = (start or {}).get("modes") or []
    if not found or any("pilot_mean" not in m for m in found):
        return None
    return np.array([m["pilot_mean"] for m in found], dtype=float).reshape(-1, post.ndim)


PILOT_STEPS = 200  # steps of a pilot run that measures each mode's mean and covariance for the jumps


def ensemble_sampler(n_walkers: int, post: LogPosterior, **kwargs) -> emcee.EnsembleSampler:
    """emcee's sampler of ``post``, vectorised, calling ``post`` itself: emcee's wrapper prints the walkers
    and a traceback for any exception in the log posterior, Ctrl-C included, before re-raising it."""
    sampler = emcee.EnsembleSampler(n_walkers, post.ndim, post, vectorize=True, **kwargs)
    sampler.log_prob_fn = post
    return sampler


def pilot_shapes(post: LogPosterior, modes: list[dict], moves, p0: np.ndarray, seed: int | None,
                 steps: int = PILOT_STEPS) -> np.ndarray:
    """Run the sampler ``steps`` steps from ``p0`` (jumps mapped by the Laplace shapes) and store each mode's
    mean and covariance over the second half's states in it as "pilot_mean", "pilot_covariance" (a mode with
    fewer than 10 x d such states keeps its Laplace shape). Returns the last walker positions: the kept chain
    starts there, with the jumps fixed from then on."""
    M = np.array([m["x"] for m in modes])
    sampler = ensemble_sampler(len(p0), post, moves=with_mode_jumps(moves, post, M, [m["cov"] for m in modes]))
    sampler.random_state = np.random.RandomState([0 if seed is None else int(seed), 13]).get_state()
    state = sampler.run_mcmc(p0, steps, progress=False)
    X = sampler.get_chain(discard=steps // 2, flat=True)
    which = nearest_mode(post, X, M)
    for k, m in enumerate(modes):
        S = X[which == k]
        if len(S) >= 10 * post.ndim:
            m["pilot_mean"], m["pilot_cov"] = S.mean(axis=0), np.cov(S.T)
    return state.coords


def walkers_in_modes(post: LogPosterior, modes: list[dict], n_walkers: int, rng: np.random.Generator) -> np.ndarray:
    """``n_walkers`` split evenly between the modes (the first ones get the remainder), each drawn from
    its mode's Laplace Gaussian; returns (n_walkers, d) and records each mode's count under "walkers"."""
    k = len(modes)
    counts = [n_walkers // k + (1 if i < n_walkers % k else 0) for i in range(k)]
    for m, c in zip(modes, counts):
        m["walkers"] = c
    return np.vstack([initial_walkers(post, m["x"], m["cov"], c, rng) for m, c in zip(modes, counts)])


class ModeJump(emcee.moves.MHMove):
    """Metropolis move from the mode i nearest to x to another mode j drawn uniformly.

    Without shapes: x -> x + (c_j - c_i). With a covariance C = L L' per mode (the pilot's, or the
    Laplace one): x -> c_j + L_j L_i^-1 (x - c_i), which carries a point's place in its mode's shape
    over to the other mode's (log factor log |det L_j| - log |det L_i|, the map's Jacobian). The
    centres c are ``centres`` (the pilot's means) or the modes; the modes alone decide which mode a
    point is nearest to. Either way the reverse map is drawn with the same probability when the
    landing point is nearest to mode j; otherwise it could not be proposed back, and the move is
    rejected (log factor -inf).
    """

    def __init__(self, post: LogPosterior, modes: np.ndarray, covs: list[np.ndarray] | None = None,
                 centres: np.ndarray | None = None):
        self.post, self.modes = post, np.asarray(modes, dtype=float)
        self.centres = self.modes if centres is None else np.asarray(centres, dtype=float)
        self.chols = None if covs is None else [np.linalg.cholesky(np.asarray(c, dtype=float)) for c in covs]
        self.log_dets = None if covs is None else np.array([np.sum(np.log(np.diag(L))) for L in self.chols])
        super().__init__(self._propose)

    def _propose(self, coords: np.ndarray, random) -> tuple[np.ndarray, np.ndarray]:
        k = len(self.modes)
        i = nearest_mode(self.post, coords, self.modes)
        j = (i + 1 + random.randint(0, k - 1, size=len(coords))) % k
        if self.chols is None:
            q, log_det = coords + self.centres[j] - self.centres[i], np.zeros(len(coords))
        else:
            q = np.array([self.centres[b] + self.chols[b] @ np.linalg.solve(self.chols[a], x - self.centres[a])
                          for x, a, b in zip(coords, i, j)])
            log_det = self.log_dets[j] - self.log_dets[i]
        back = nearest_mode(self.post, q, self.modes) == j
        return q, np.where(back, log_det, -np.inf)


class WithinModes(emcee.moves.RedBlueMove):
    """An ensemble move (DE, snooker, stretch) whose helper walkers are those of the walker's own mode.

    Between walkers in different modes a difference vector spans the valley, and the proposal
    lands nowhere useful: with a 60/40 split that is half of all DE proposals. Here the
    complementary walkers are cut down to those nearest to the moving walker's mode (all of them
    when that leaves too few for the move), and a proposal that lands nearer another mode is
    rejected. The pool then depends only on the mode, which x and its proposal share, so the
    base move's proposal stays as symmetric (with the same factor) as it was.
    """

    def __init__(self, move: emcee.moves.RedBlueMove, post: LogPosterior, modes: np.ndarray):
        self.move, self.post, self.modes = move, post, np.asarray(modes, dtype=float)
        super().__init__(nsplits=move.nsplits, randomize_split=move.randomize_split,
                         live_dangerously=move.live_dangerously)

    def setup(self, coords):
        self.move.setup(coords)

    def get_proposal(self, s, c, random):
        mode_s = nearest_mode(self.post, s, self.modes)
        mode_c = [nearest_mode(self.post, cj, self.modes) for cj in c]
        q, factors = np.empty_like(s), np.empty(len(s))
        for k in np.unique(mode_s):
            rows = mode_s == k
            pool = [cj[mk == k] for cj, mk in zip(c, mode_c)]
            if not _enough(self.move, pool):
                pool = c
            q[rows], factors[rows] = self.move.get_proposal(s[rows], pool, random)
        same = nearest_mode(self.post, q, self.modes) == mode_s
        return q, np.where(same, factors, -np.inf)


def _enough(move, pool: list[np.ndarray]) -> bool:
    """Whether ``move`` can draw its helper walkers from ``pool``: the snooker one from each of three
    sets, DE two distinct ones, stretch one."""
    sizes = [len(p) for p in pool]
    if isinstance(move, emcee.moves.DESnookerMove):
        return len(sizes) >= 3 and min(sizes[:3]) >= 1
    return sum(sizes) >= (2 if isinstance(move, emcee.moves.DEMove) else 1)


JUMP_SHARE = 0.2  # share of steps that are mode jumps when there are separated modes


def with_mode_jumps(moves, post: LogPosterior, modes: np.ndarray, covs: list[np.ndarray] | None = None,
                    centres: np.ndarray | None = None):
    """emcee moves (None: the stretch move) for separated modes: each ensemble move drawing its helper
    walkers from the walker's own mode (``WithinModes``), and ``ModeJump`` at ``JUMP_SHARE``; unchanged
    with one mode."""
    if len(modes) < 2:
        return moves
    base = [(emcee.moves.StretchMove(), 1.0)] if moves is None else list(moves)
    total = sum(w for _, w in base)
    within = [(WithinModes(m, post, modes) if isinstance(m, emcee.moves.RedBlueMove) else m,
               (1.0 - JUMP_SHARE) * w / total) for m, w in base]
    return within + [(ModeJump(post, modes, covs, centres), JUMP_SHARE)]

"""Black-box models: lagged-input/output (NARX) learners trained by their own library.

No structure of hysteresis is assumed: the output at sample i is a learnt function of
past outputs and present and past inputs,

    y[i] = f(y[i-k], ..., y[i-n_output_lags*k], u[i], u[i-k], ..., u[i-(n_input_lags-1)*k])

where k = round(sample_time / dt) is the lag spacing in samples: the model is a
discrete-time system at ``sample_time`` seconds, run on a record of finer step dt as k
interleaved chains (every sample of the record is predicted from real input samples, so
the model is causal and a stepper reproduces ``simulate`` sample by sample). Before a
record's first sample the input is held at its first value and the output is 0 (at rest).

* ``SparseNARX`` ("narx-sparse"): f is a polynomial in the lagged variables; its terms are
  chosen by pysindy's sequentially thresholded least squares (``STLSQ``) over pysindy's
  ``PolynomialLibrary``, fitted on one-step prediction for each threshold of a grid and
  **selected on free-run simulation error** (eq. 9 on the fit records' scored windows).
* ``NeuralNARX`` ("narx-mlp"): f is a multilayer perceptron (scikit-learn's
  ``MLPRegressor``, tanh hidden layers), trained on one-step prediction, scored in free run.

Fitted weights are the model's parameters (a mapping name -> float, like every model's), so
a fitted model is simulated, saved to JSON and reloaded like any other: ``u_center``,
``u_scale``, ``y_center``, ``y_scale`` (the affine scaling of the data the learner saw),
``sample_time`` (seconds; fixed at fit when the hyperparameter is None, see
``resolve_sample_time``) and the learner's weights. Training is not a parameter search:
these models declare ``native_training`` and are identified by ``method="native"``
(identification/native.py), which calls ``train``.
"""

from __future__ import annotations

import math
import warnings
from typing import Callable, ClassVar, Mapping, Sequence

import numpy as np
from numba import njit

from .base import DataScale, HysteresisModel, Parameter
from .errors import ModelError
from .hyperparameters import check_choice, check_int, check_number
from .stepper import Stepper, check_state_keys, check_step_input

# With sample_time=None the lag spacing is set at fit: this many samples per shortest drive period.
POINTS_PER_PERIOD = 50
SCALING_NAMES = ("u_center", "u_scale", "y_center", "y_scale", "sample_time")
MAX_LAGS = 20
MAX_WIDTH = 1024
WEIGHT_BOUND = 1e6  # on the scaled data a learnt weight is O(1); bounds only keep parameter draws finite


# --- kernels -----------------------------------------------------------------
@njit(cache=True)
def _lagged(x, us, ys, i, k, n_out, n_in, y_rest):
    """The lag vector of sample i (scaled): past outputs, then present and past inputs."""
    for a in range(n_out):
        j = i - (a + 1) * k
        x[a] = ys[j] if j >= 0 else y_rest
    for b in range(n_in):
        j = i - b * k
        x[n_out + b] = us[j] if j >= 0 else us[0]


@njit(cache=True)
def poly_eval(x, exponents, coefs):
    """sum_t coefs[t] prod_v x[v]**exponents[t, v]."""
    total = 0.0
    for t in range(exponents.shape[0]):
        c = coefs[t]
        if c == 0.0:
            continue
        term = c
        for v in range(exponents.shape[1]):
            e = exponents[t, v]
            for _ in range(e):
                term *= x[v]
        total += term
    return total


@njit(cache=True)
def mlp_eval(x, weights, sizes):
    """A perceptron whose layer sizes are ``sizes`` (input ... 1), tanh on hidden layers;
    ``weights`` holds per layer the (n_in, n_out) matrix row by row, then the biases."""
    a = x.copy()
    pos = 0
    n_layers = sizes.size - 1
    for layer in range(n_layers):
        n_in, n_out = sizes[layer], sizes[layer + 1]
        z = np.empty(n_out)
        for o in range(n_out):
            z[o] = weights[pos + n_in * n_out + o]
        for i in range(n_in):
            ai = a[i]
            row = pos + i * n_out
            for o in range(n_out):
                z[o] += ai * weights[row + o]
        pos += n_in * n_out + n_out
        if layer < n_layers - 1:
            for o in range(n_out):
                z[o] = math.tanh(z[o])
        a = z
    return a[0]


@njit(cache=True)
def poly_simulate(us, k, n_out, n_in, y_rest, exponents, coefs):
    n = us.size
    ys = np.empty(n)
    x = np.empty(n_out + n_in)
    for i in range(n):
        _lagged(x, us, ys, i, k, n_out, n_in, y_rest)
        ys[i] = poly_eval(x, exponents, coefs)
    return ys


@njit(cache=True)
def mlp_simulate(us, k, n_out, n_in, y_rest, weights, sizes):
    n = us.size
    ys = np.empty(n)
    x = np.empty(n_out + n_in)
    for i in range(n):
        _lagged(x, us, ys, i, k, n_out, n_in, y_rest)
        ys[i] = mlp_eval(x, weights, sizes)
    return ys


# --- shared machinery --------------------------------------------------------
def lag_step(sample_time: float, dt: float) -> int:
    """Samples of step dt per model step: round(sample_time / dt), at least 1."""
    return max(1, int(round(sample_time / dt)))


def resolve_sample_time(records: Sequence[tuple], drive_period: float) -> float:
    """The model step chosen at fit when ``sample_time`` is None: the largest multiple of the fit
    records' smallest step not above drive_period / POINTS_PER_PERIOD (the record's own step for
    broadband records, whose shortest period is a few samples)."""
    dt = min(float(r[2]) for r in records)
    return dt * max(1, int(drive_period / POINTS_PER_PERIOD / dt + 1e-9))


def smoothed(x: np.ndarray, k: int) -> np.ndarray:
    """x averaged over a centred window of about one model step (2 (k // 2) + 1 samples; edges held),
    before it is sampled every k samples for training: at a model step of many record samples the
    step-to-step change of a slow drive is of the order of a sensor's quantisation, which the
    average removes without delay. The identity for k = 1."""
    if k <= 1:
        return np.asarray(x, dtype=float)
    half = k // 2
    padded = np.pad(np.asarray(x, dtype=float), half, mode="edge")
    c = np.concatenate(([0.0], np.cumsum(padded)))
    return (c[2 * half + 1:] - c[:-2 * half - 1]) / (2 * half + 1)


PREFILTERS = ("step-mean", "none")


def training_samples(x: np.ndarray, k: int, prefilter: str) -> np.ndarray:
    """A record's column as the learner sees it: every k-th sample, after ``smoothed`` when the
    prefilter is "step-mean" (for drives slow against the model step), as is when "none"."""
    return (smoothed(x, k) if prefilter == "step-mean" else np.asarray(x, dtype=float))[::k]


def lagged_rows(u: np.ndarray, y: np.ndarray, k: int, n_out: int, n_in: int,
                prefilter: str = "none") -> tuple[np.ndarray, np.ndarray]:
    """One-step regression rows of a record sampled every k samples (offset 0, ``training_samples``):
    (X, target), the rows whose lags all lie inside the record."""
    uc, yc = training_samples(u, k, prefilter), training_samples(y, k, prefilter)
    first = max(n_out, n_in - 1)
    n = uc.size - first
    if n <= 0:
        return np.empty((0, n_out + n_in)), np.empty(0)
    cols = [yc[first - a - 1:first - a - 1 + n] for a in range(n_out)]
    cols += [uc[first - b:first - b + n] for b in range(n_in)]
    return np.column_stack(cols), yc[first:first + n].copy()


class SteppingBase(Stepper):
    """What the black-box steppers share beyond the ``Stepper`` API: input and state checks."""

    _state_keys: tuple[str, ...] = ()

    def __init__(self, model, dt: float, params):
        if not (dt > 0 and math.isfinite(dt)):
            raise ModelError(f"model {model.name!r}: time step must be positive, got {dt!r}")
        self.model = model
        self.dt = float(dt)
        self._p = model.unpack(model.pack(params)) if isinstance(params, Mapping) else model.unpack(params)
        self.k = lag_step(self._p["sample_time"], dt)

    def _input(self, u) -> float:
        return check_step_input(f"model {self.model.name!r} stepper", u)

    def _checked_state(self, state) -> dict:
        return check_state_keys(f"model {self.model.name!r} stepper", state, self._state_keys)


class BlackBoxStepper(SteppingBase):
    """Sample-by-sample evaluation of a lagged black-box model: ``step(u) -> y``, ``reset()``,
    ``state`` (the scaled input and output history), ``set_state``. ``step`` repeated over a record
    gives exactly ``simulate``."""

    _state_keys = ("n", "u_first", "u_scaled", "y_scaled")

    def __init__(self, model: "LaggedBlackBox", dt: float, params: Mapping[str, float]):
        super().__init__(model, dt, params)
        self._evaluate = model.evaluator(self._p)
        self.reset()

    def reset(self) -> None:
        m = self.model
        self._span = max(m.n_output_lags, m.n_input_lags - 1) * self.k + 1  # the history a step reads
        self._us = np.zeros(self._span)
        self._ys = np.zeros(self._span)
        self._n = 0  # samples stepped since reset
        self._u_first = 0.0

    @property
    def state(self) -> dict:
        """Samples stepped, the first scaled input, and the scaled input and output history (the last
        ``span`` samples, oldest first)."""
        order = [(self._n - self._span + j) % self._span for j in range(self._span)]
        return {"n": self._n, "u_first": self._u_first, "u_scaled": self._us[order].tolist(),
                "y_scaled": self._ys[order].tolist()}

    def set_state(self, state: dict) -> None:
        state = self._checked_state(state)
        us, ys = np.asarray(state["u_scaled"], dtype=float), np.asarray(state["y_scaled"], dtype=float)
        if us.shape != (self._span,) or ys.shape != (self._span,):
            raise ModelError(f"model {self.model.name!r} stepper: a state holds {self._span} samples of history")
        self._n = int(state["n"])
        self._u_first = float(state["u_first"])
        order = [(self._n - self._span + j) % self._span for j in range(self._span)]
        self._us[order], self._ys[order] = us, ys

    def step(self, u: float) -> float:
        m, p, k, span = self.model, self._p, self.k, self._span
        i = self._n
        us = (self._input(u) - p["u_center"]) / p["u_scale"]
        if i == 0:
            self._u_first = us
        self._us[i % span] = us
        y_rest = (0.0 - p["y_center"]) / p["y_scale"]
        x = np.empty(m.n_output_lags + m.n_input_lags)
        for a in range(m.n_output_lags):
            j = i - (a + 1) * k
            x[a] = self._ys[j % span] if j >= 0 else y_rest
        for b in range(m.n_input_lags):
            j = i - b * k
            x[m.n_output_lags + b] = self._us[j % span] if j >= 0 else self._u_first
        ys = float(self._evaluate(x))
        self._ys[i % span] = ys
        self._n = i + 1
        return ys * p["y_scale"] + p["y_center"]


class LaggedBlackBox(HysteresisModel):
    """Base of the lagged black-box learners: lags, step, scaling; subclasses give the learner."""

    native_training: ClassVar[bool] = True  # identified by method "native": the model's own ``train``
    kind: ClassVar[str] = "black-box"
    inverse_unavailable = "a black-box model has no causal inverse"

    def _check_common(self, sample_time, n_output_lags, n_input_lags, prefilter):
        owner = f"model {self.name!r}"
        self.prefilter = check_choice(owner, "prefilter", prefilter, PREFILTERS)
        self.sample_time = None if sample_time is None else check_number(owner, "sample_time", sample_time,
                                                                          positive=True)
        self.n_output_lags = check_int(owner, "n_output_lags", n_output_lags, 1, MAX_LAGS)
        self.n_input_lags = check_int(owner, "n_input_lags", n_input_lags, 1, MAX_LAGS)

    @property
    def n_lags(self) -> int:
        return self.n_output_lags + self.n_input_lags

    # --- parameters ----------------------------------------------------------
    def weight_names(self) -> list[str]:
        raise NotImplementedError

    def declare_parameters(self, scale: DataScale) -> list[Parameter]:
        st = self.sample_time if self.sample_time is not None else 1e-3
        u, y = scale.u, scale.y
        fixed = [Parameter("u_center", 0.0, -u, u, description="input centre of the scaling", unit="u"),
                 Parameter("u_scale", u, u * 1e-9, 2 * u, description="input scale", unit="u"),
                 Parameter("y_center", 0.0, -y, y, description="output centre of the scaling", unit="y"),
                 Parameter("y_scale", y, y * 1e-9, 2 * y, description="output scale", unit="y"),
                 Parameter("sample_time", st, st, st, description="model step (s), fixed at fit", unit="s")]
        return fixed + [Parameter(n, 0.0, -WEIGHT_BOUND, WEIGHT_BOUND, description="learnt weight", unit="1")
                        for n in self.weight_names()]

    @property
    def n_weights(self) -> int:
        return self.n_params - len(SCALING_NAMES)

    def start_from_data(self, records: Sequence[tuple], scale: DataScale):
        st = self.sample_time if self.sample_time is not None else resolve_sample_time(records, scale.time)
        return {"sample_time": st}, {"sample_time": (st, st)}

    # --- evaluation ----------------------------------------------------------
    def evaluator(self, p: Mapping[str, float]) -> Callable[[np.ndarray], float]:
        """f of the module docstring on a scaled lag vector, for the parameters ``p``."""
        raise NotImplementedError

    def _run(self, us: np.ndarray, k: int, y_rest: float, p: Mapping[str, float]) -> np.ndarray:
        raise NotImplementedError

    def simulate_batch(self, u, dt: float, param_sets: np.ndarray, input_range=None) -> np.ndarray:
        u = self._check_input(u, dt)
        P = self._check_param_sets(param_sets)
        out = np.empty((P.shape[0], u.size))
        for s, row in enumerate(P):
            p = self.unpack(row)
            if not (p["u_scale"] > 0 and p["y_scale"] > 0 and p["sample_time"] > 0):
                raise ModelError(f"model {self.name!r}: u_scale, y_scale and sample_time must be positive")
            us = (u - p["u_center"]) / p["u_scale"]
            ys = self._run(us, lag_step(p["sample_time"], dt), (0.0 - p["y_center"]) / p["y_scale"], p)
            with np.errstate(over="ignore", invalid="ignore"):  # a diverged run is inf: the scoring names it
                out[s] = ys * p["y_scale"] + p["y_center"]
        return out

    def stepper(self, dt: float, params, input_range=None) -> BlackBoxStepper:
        return BlackBoxStepper(self, dt, params)

    # --- training ------------------------------------------------------------
    def training_rows(self, records: Sequence[tuple], sample_time: float) -> tuple[np.ndarray, np.ndarray, dict]:
        """Scaled one-step rows of every fit record (u, y, dt, window) and the scaling parameters."""
        us = np.concatenate([np.asarray(r[0], float) for r in records])
        ys = np.concatenate([np.asarray(r[1], float) for r in records])
        scaling = {"u_center": float(np.mean(us)), "u_scale": float(np.std(us)) or 1.0,
                   "y_center": float(np.mean(ys)), "y_scale": float(np.std(ys)) or 1.0,
                   "sample_time": float(sample_time)}
        X, T = [], []
        for u, y, dt, _ in records:
            k = lag_step(sample_time, dt)
            x, t = lagged_rows((np.asarray(u) - scaling["u_center"]) / scaling["u_scale"],
                               (np.asarray(y) - scaling["y_center"]) / scaling["y_scale"], k,
                               self.n_output_lags, self.n_input_lags, self.prefilter)
            X.append(x)
            T.append(t)
        X, T = np.concatenate(X), np.concatenate(T)
        if T.size < 2 * max(1, self.n_weights):
            raise ModelError(f"model {self.name!r}: {T.size} training rows at sample_time {sample_time:g} s "
                             f"cannot determine {self.n_weights} weights (shorter sample_time or fewer lags)")
        return X, T, scaling

    def train(self, records: Sequence[tuple], sample_time: float, seed: int | None,
              simulation_error: Callable[[dict], float]) -> tuple[dict, dict, list[str]]:
        """(parameters, diagnostics, notes) learnt from the fit records (u, y, dt, window);
        ``simulation_error(params)`` is eq. 9 of a candidate in free run on those records."""
        raise NotImplementedError


# --- sparse polynomial NARX (pysindy) ---------------------------------------
class SparseNARX(LaggedBlackBox):
    """Sparse polynomial NARX: pysindy's STLSQ over a PolynomialLibrary of the lag vector,
    threshold chosen on free-run simulation error; see the module docstring."""

    name = "narx-sparse"

    def __init__(self, sample_time: float | None = None, n_output_lags: int = 2, n_input_lags: int = 2,
                 prefilter: str = "step-mean", degree: int = 3, n_thresholds: int = 8, max_threshold: float = 1.0,
                 ridge: float = 1e-6, max_iter: int = 20):
        owner = f"model {self.name!r}"
        self._check_common(sample_time, n_output_lags, n_input_lags, prefilter)
        self.degree = check_int(owner, "degree", degree, 1, 5)
        self.n_thresholds = check_int(owner, "n_thresholds", n_thresholds, 1, 100)
        self.max_threshold = check_number(owner, "max_threshold", max_threshold, positive=True)
        self.ridge = check_number(owner, "ridge", ridge, lo=0.0)
        self.max_iter = check_int(owner, "max_iter", max_iter, 1, 10_000)
        if math.comb(self.n_lags + self.degree, self.degree) > 5000:
            raise ModelError(f"{owner}: {math.comb(self.n_lags + self.degree, self.degree)} polynomial terms "
                             f"(n_output_lags + n_input_lags = {self.n_lags}, degree {self.degree}); at most 5000")

    def _library(self):
        import pysindy as ps

        lib = ps.PolynomialLibrary(degree=self.degree, include_bias=True)
        lib.fit(np.zeros((2, self.n_lags)))
        return lib

    def lag_names(self) -> list[str]:
        return ([f"y{a + 1}" for a in range(self.n_output_lags)]
                + [f"u{b}" for b in range(self.n_input_lags)])

    def exponents(self) -> np.ndarray:
        cached = self.__dict__.get("_exponents")
        if cached is None:
            cached = self.__dict__["_exponents"] = np.ascontiguousarray(self._library().powers_, dtype=np.int64)
        return cached

    def term_names(self) -> list[str]:
        return self._library().get_feature_names(self.lag_names())

    def weight_names(self) -> list[str]:
        names = []
        for powers in self.exponents():
            parts = [f"{v}^{e}" if e > 1 else v for v, e in zip(self.lag_names(), powers) if e]
            names.append("c_" + ("*".join(parts) if parts else "1"))
        return names

    def coefficients(self, p: Mapping[str, float]) -> np.ndarray:
        return np.array([p[n] for n in self.weight_names()], dtype=float)

    def evaluator(self, p):
        exps, coefs = self.exponents(), self.coefficients(p)
        return lambda x: poly_eval(x, exps, coefs)

    def _run(self, us, k, y_rest, p):
        return poly_simulate(us, k, self.n_output_lags, self.n_input_lags, y_rest, self.exponents(),
                             self.coefficients(p))

    def train(self, records, sample_time, seed, simulation_error):
        import pysindy as ps

        X, T, scaling = self.training_rows(records, sample_time)
        theta = np.asarray(self._library().transform(X))
        names = self.weight_names()
        thresholds = np.geomspace(self.max_threshold, self.max_threshold * 1e-3, self.n_thresholds) \
            if self.n_thresholds > 1 else np.array([self.max_threshold])
        thresholds = np.append(thresholds, 0.0)  # the full least-squares polynomial as a candidate too
        candidates = []
        for threshold in thresholds:
            opt = ps.STLSQ(threshold=float(threshold), alpha=self.ridge, max_iter=self.max_iter)
            with warnings.catch_warnings():  # a threshold that removes every term is one candidate of the sweep
                warnings.filterwarnings("ignore", message="Sparsity parameter is too big", category=UserWarning)
                opt.fit(theta, T[:, None])
            coefs = np.asarray(opt.coef_, dtype=float).ravel()
            params = {**scaling, **dict(zip(names, (float(c) for c in coefs)))}
            error = simulation_error(params)
            candidates.append((error if math.isfinite(error) else math.inf, float(threshold), params,
                               int(np.count_nonzero(coefs))))
        best = min(candidates, key=lambda c: (c[0], -c[1]))
        notes = []
        if not math.isfinite(best[0]):
            notes.append("every threshold's polynomial diverged in free-run simulation of the fit records")
        diagnostics = {"threshold": best[1], "n_nonzero": best[3], "n_rows": int(T.size),
                       "candidates": [{"threshold": c[1], "simulation_fitness": c[0], "n_nonzero": c[3]}
                                      for c in candidates]}
        return best[2], diagnostics, notes


# --- neural NARX (scikit-learn) ---------------------------------------------
class NeuralNARX(LaggedBlackBox):
    """A multilayer perceptron on the lag vector (scikit-learn's MLPRegressor, tanh), trained on
    one-step prediction: full-batch L-BFGS (``solver="lbfgs"``, ``max_epochs`` its iterations)
    or minibatch Adam (``solver="adam"``, ``max_epochs`` passes, ``learning_rate``); see the
    module docstring."""

    name = "narx-mlp"

    def __init__(self, sample_time: float | None = None, n_output_lags: int = 2, n_input_lags: int = 2,
                 prefilter: str = "step-mean", width: int = 16, depth: int = 1, max_epochs: int = 200, max_rows: int = 50_000,
                 solver: str = "lbfgs", learning_rate: float = 1e-3, l2: float = 1e-5, seed: int = 0):
        owner = f"model {self.name!r}"
        self._check_common(sample_time, n_output_lags, n_input_lags, prefilter)
        self.width = check_int(owner, "width", width, 1, MAX_WIDTH)
        self.depth = check_int(owner, "depth", depth, 1, 8)
        self.max_epochs = check_int(owner, "max_epochs", max_epochs, 1, 100_000)
        self.max_rows = check_int(owner, "max_rows", max_rows, 10, 10_000_000)
        self.solver = check_choice(owner, "solver", solver, ("lbfgs", "adam"))
        self.learning_rate = check_number(owner, "learning_rate", learning_rate, positive=True)
        self.l2 = check_number(owner, "l2", l2, lo=0.0)
        self.seed = check_int(owner, "seed", seed, 0, 2**32 - 1)

    @property
    def layer_sizes(self) -> np.ndarray:
        return np.array([self.n_lags] + [self.width] * self.depth + [1], dtype=np.int64)

    def weight_names(self) -> list[str]:
        names, sizes = [], self.layer_sizes
        for layer in range(sizes.size - 1):
            n_in, n_out = int(sizes[layer]), int(sizes[layer + 1])
            names += [f"w{layer}_{i}_{o}" for i in range(n_in) for o in range(n_out)]
            names += [f"b{layer}_{o}" for o in range(n_out)]
        return names

    def weights(self, p: Mapping[str, float]) -> np.ndarray:
        return np.array([p[n] for n in self.weight_names()], dtype=float)

    def evaluator(self, p):
        w, sizes = self.weights(p), self.layer_sizes
        return lambda x: mlp_eval(x, w, sizes)

    def _run(self, us, k, y_rest, p):
        return mlp_simulate(us, k, self.n_output_lags, self.n_input_lags, y_rest, self.weights(p),
                            self.layer_sizes)

    def train(self, records, sample_time, seed, simulation_error):
        import warnings

        from sklearn.exceptions import ConvergenceWarning
        from sklearn.neural_network import MLPRegressor

        X, T, scaling = self.training_rows(records, sample_time)
        # the model's own seed and the identification's seed both select the draw
        state = int(np.random.SeedSequence([self.seed, 0 if seed is None else int(seed)]).generate_state(1)[0])
        rng = np.random.default_rng(state)
        if T.size > self.max_rows:  # the training budget: a seeded subset of rows
            keep = np.sort(rng.choice(T.size, self.max_rows, replace=False))
            X, T = X[keep], T[keep]
        net = MLPRegressor(hidden_layer_sizes=(self.width,) * self.depth, activation="tanh", solver=self.solver,
                           alpha=self.l2, learning_rate_init=self.learning_rate, max_iter=self.max_epochs,
                           random_state=state, tol=1e-9, n_iter_no_change=20, shuffle=True,
                           max_fun=10 * self.max_epochs + 1000)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", ConvergenceWarning)
            net.fit(X, T)
        flat = np.concatenate([np.concatenate([W.ravel(), b.ravel()]) for W, b in zip(net.coefs_, net.intercepts_)])
        params = {**scaling, **dict(zip(self.weight_names(), (float(v) for v in flat)))}
        notes = []
        if any(issubclass(w.category, ConvergenceWarning) for w in caught):
            notes.append(f"the perceptron's training stopped at max_epochs={self.max_epochs} before converging")
        diagnostics = {"epochs": int(net.n_iter_), "one_step_loss": float(net.loss_), "n_rows": int(T.size)}
        return params, diagnostics, notes

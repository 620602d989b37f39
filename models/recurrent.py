"""A recurrent black-box model: a gated recurrent unit (GRU) network, trained with PyTorch.

    h[i] = GRU(x[i], h[i-k]),   x[i] = (u[i] - u_center) / u_scale,
    y[i] = y_center + y_scale * (readout . h[i] + readout_bias)

with PyTorch's GRU cell (gates r, z, n) and k = round(sample_time / dt) as in
models/black_box.py (k interleaved state chains on a record of finer step; the state is 0
at a record's first sample). Training (``train``) needs the optional extra
``pip install -e ".[neural]"`` (PyTorch's CPU build): Adam on the simulation error of
overlapping windows of the fit records, each window started from a zero state whose first
``washout`` steps are not scored. Simulation and the stepper do not need PyTorch: the
weights are the model's parameters, run by a numba kernel, so a stored fit is simulated,
scored and reloaded without the extra.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .black_box import MAX_WIDTH, LaggedBlackBox, SteppingBase, lag_step, training_samples
from .errors import ModelError
from .hyperparameters import check_int, check_number

EXTRA_HINT = 'the recurrent model trains with PyTorch: pip install -e ".[neural]" (or torch==2.13.0, its CPU build)'


def torch_available() -> bool:
    try:
        import torch  # noqa: F401
    except ImportError:
        return False
    return True


@njit(cache=True)
def _sigmoid(v):
    return 1.0 / (1.0 + math.exp(-v))


@njit(cache=True)
def gru_update(h, x, w_ih, w_hh, b_ih, b_hh, out):
    """PyTorch's GRU cell for a scalar input x: the new state written to ``out``."""
    H = h.size
    for j in range(H):
        gr = w_ih[j] * x + b_ih[j] + b_hh[j]
        gz = w_ih[H + j] * x + b_ih[H + j] + b_hh[H + j]
        hn = b_hh[2 * H + j]
        for m in range(H):
            hm = h[m]
            gr += w_hh[j, m] * hm
            gz += w_hh[H + j, m] * hm
            hn += w_hh[2 * H + j, m] * hm
        r = _sigmoid(gr)
        z = _sigmoid(gz)
        n = math.tanh(w_ih[2 * H + j] * x + b_ih[2 * H + j] + r * hn)
        out[j] = (1.0 - z) * n + z * h[j]


@njit(cache=True)
def gru_simulate(us, k, w_ih, w_hh, b_ih, b_hh, readout, readout_bias):
    n = us.size
    H = readout.size
    chains = np.zeros((k, H))
    new = np.empty(H)
    ys = np.empty(n)
    for i in range(n):
        c = i % k
        gru_update(chains[c], us[i], w_ih, w_hh, b_ih, b_hh, new)
        y = readout_bias
        for j in range(H):
            chains[c, j] = new[j]
            y += readout[j] * new[j]
        ys[i] = y
    return ys


class GRUStepper(SteppingBase):
    """``step(u) -> y``, ``reset()``, ``state`` (the k state chains), ``set_state``; equals ``simulate``."""

    _state_keys = ("n", "chains")

    def __init__(self, model: "RecurrentNetwork", dt: float, params):
        super().__init__(model, dt, params)
        self._w = model.gru_weights(self._p)
        self.reset()

    def reset(self) -> None:
        self._chains = np.zeros((self.k, self.model.width))
        self._new = np.empty(self.model.width)
        self._n = 0

    @property
    def state(self) -> dict:
        return {"n": self._n, "chains": self._chains.tolist()}

    def set_state(self, state: dict) -> None:
        state = self._checked_state(state)
        chains = np.asarray(state["chains"], dtype=float)
        if chains.shape != self._chains.shape:
            raise ModelError(f"model {self.model.name!r} stepper: a state holds {self.k} chains of "
                             f"{self.model.width} units")
        self._n = int(state["n"])
        self._chains = chains.copy()

    def step(self, u: float) -> float:
        p = self._p
        w_ih, w_hh, b_ih, b_hh, readout, readout_bias = self._w
        c = self._n % self.k
        x = (self._input(u) - p["u_center"]) / p["u_scale"]
        gru_update(self._chains[c], x, w_ih, w_hh, b_ih, b_hh, self._new)
        self._chains[c] = self._new
        self._n += 1
        y = readout_bias
        for j in range(self.model.width):
            y += readout[j] * self._new[j]
        return y * p["y_scale"] + p["y_center"]


class RecurrentNetwork(LaggedBlackBox):
    """A GRU network from input to output (trained with PyTorch); see the module docstring."""

    name = "gru"

    def __init__(self, sample_time: float | None = None, prefilter: str = "step-mean", width: int = 16, window: int = 400, washout: int = 100,
                 max_epochs: int = 150, learning_rate: float = 1e-2, seed: int = 0):
        owner = f"model {self.name!r}"
        self._check_common(sample_time, 1, 1, prefilter)
        self.width = check_int(owner, "width", width, 1, MAX_WIDTH)
        self.window = check_int(owner, "window", window, 2, 1_000_000)
        self.washout = check_int(owner, "washout", washout, 0, 1_000_000)
        self.max_epochs = check_int(owner, "max_epochs", max_epochs, 1, 100_000)
        self.learning_rate = check_number(owner, "learning_rate", learning_rate, positive=True)
        self.seed = check_int(owner, "seed", seed, 0, 2**32 - 1)

    def weight_names(self) -> list[str]:
        H = self.width
        return ([f"w_ih_{g}" for g in range(3 * H)] + [f"w_hh_{g}_{m}" for g in range(3 * H) for m in range(H)]
                + [f"b_ih_{g}" for g in range(3 * H)] + [f"b_hh_{g}" for g in range(3 * H)]
                + [f"readout_{j}" for j in range(H)] + ["readout_bias"])

    def gru_weights(self, p) -> tuple:
        H = self.width
        v = np.array([p[n] for n in self.weight_names()], dtype=float)
        a = 0
        w_ih = v[a:a + 3 * H]
        a += 3 * H
        w_hh = v[a:a + 3 * H * H].reshape(3 * H, H).copy()
        a += 3 * H * H
        b_ih = v[a:a + 3 * H]
        a += 3 * H
        b_hh = v[a:a + 3 * H]
        a += 3 * H
        readout = v[a:a + H].copy()
        return w_ih.copy(), w_hh, b_ih.copy(), b_hh.copy(), readout, float(v[-1])

    def evaluator(self, p):
        raise ModelError(f"model {self.name!r} is recurrent: it has a state, not a lag vector")

    def _run(self, us, k, y_rest, p):
        return gru_simulate(us, k, *self.gru_weights(p))

    def stepper(self, dt: float, params, input_range=None) -> GRUStepper:
        return GRUStepper(self, dt, params)

    def train(self, records, sample_time, seed, simulation_error):
        if self.washout >= self.window:
            raise ModelError(f"model {self.name!r}: washout ({self.washout}) must be smaller than window "
                             f"({self.window})")
        try:
            import torch
        except ImportError:
            raise ModelError(f"model {self.name!r}: {EXTRA_HINT}") from None
        us = np.concatenate([np.asarray(r[0], float) for r in records])
        ys = np.concatenate([np.asarray(r[1], float) for r in records])
        scaling = {"u_center": float(np.mean(us)), "u_scale": float(np.std(us)) or 1.0,
                   "y_center": float(np.mean(ys)), "y_scale": float(np.std(ys)) or 1.0,
                   "sample_time": float(sample_time)}
        windows_u, windows_y, short = [], [], []
        stride = max(1, (self.window - self.washout) // 2)
        for u, y, dt, _ in records:
            k = lag_step(sample_time, dt)
            uc = (training_samples(u, k, self.prefilter) - scaling["u_center"]) / scaling["u_scale"]
            yc = (training_samples(y, k, self.prefilter) - scaling["y_center"]) / scaling["y_scale"]
            if uc.size < self.window:
                short.append(uc.size)
            starts = list(range(0, max(1, uc.size - self.window + 1), stride))
            if uc.size >= self.window and starts[-1] != uc.size - self.window:
                starts.append(uc.size - self.window)
            for s in starts:
                if s + self.window <= uc.size:
                    windows_u.append(uc[s:s + self.window])
                    windows_y.append(yc[s:s + self.window])
        if not windows_u:
            raise ModelError(f"model {self.name!r}: no fit record holds a window of {self.window} steps at "
                             f"sample_time {sample_time:g} s (shorter window or sample_time)")
        state = int(np.random.SeedSequence([self.seed, 0 if seed is None else int(seed)]).generate_state(1)[0])
        threads = torch.get_num_threads()
        torch.set_num_threads(1)  # small recurrent algebra: threads only contend on a shared machine
        try:
            torch.manual_seed(state)
            U = torch.tensor(np.array(windows_u)[:, :, None], dtype=torch.float64)
            Y = torch.tensor(np.array(windows_y), dtype=torch.float64)
            gru = torch.nn.GRU(1, self.width, batch_first=True, dtype=torch.float64)
            head = torch.nn.Linear(self.width, 1, dtype=torch.float64)
            params = list(gru.parameters()) + list(head.parameters())
            opt = torch.optim.Adam(params, lr=self.learning_rate)
            sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, self.max_epochs)
            losses = []
            for _ in range(self.max_epochs):  # full batch: one step per epoch
                opt.zero_grad()
                h, _ = gru(U)
                pred = head(h)[:, :, 0]
                loss = torch.mean((pred[:, self.washout:] - Y[:, self.washout:]) ** 2)
                loss.backward()
                opt.step()
                sched.step()
                losses.append(float(loss.detach()))
            flat = np.concatenate([gru.weight_ih_l0.detach().numpy().ravel(), gru.weight_hh_l0.detach().numpy().ravel(),
                                   gru.bias_ih_l0.detach().numpy(), gru.bias_hh_l0.detach().numpy(),
                                   head.weight.detach().numpy().ravel(), head.bias.detach().numpy()])
        finally:
            torch.set_num_threads(threads)
        out = {**scaling, **dict(zip(self.weight_names(), (float(v) for v in flat)))}
        notes = [] if math.isfinite(losses[-1]) else ["the network's training loss is not finite"]
        if short:  # said, so a score is not read as learnt from every fit record
            notes.append(f"{len(short)} of {len(records)} fit records ({', '.join(str(n) for n in short)} model steps) "
                         f"are shorter than one training window ({self.window} steps) and took no part in training")
        diagnostics = {"epochs": self.max_epochs, "final_loss": losses[-1], "n_windows": len(windows_u),
                       "torch": torch.__version__}
        return out, diagnostics, notes

"""The black-box learners (models/black_box.py, models/recurrent.py) and method "native".

Each learner recovers a known discrete-time system from its data; the stepper gives
``simulate`` sample by sample; the same seed gives the same weights; bad hyperparameters
and wrong methods are refused in one line. The recurrent network's training needs the
optional extra [neural] (PyTorch); those tests skip, naming it, when it is not installed.
"""

import json
import math
import warnings

import numpy as np
import pytest

from hysbench.data.dataset import Dataset, Record
from hysbench.identification import Fit, IdentificationError, identify
from hysbench.identification.api import applicable_methods
from hysbench.models import ModelError, get_model
from hysbench.models.black_box import lag_step, resolve_sample_time, training_samples
from hysbench.models.recurrent import torch_available

DT = 0.01
N = 1500


def _input(seed: int, n: int = N) -> np.ndarray:
    """A broadband drive: a few random sines and a little noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * DT
    u = sum(rng.uniform(0.2, 0.6) * np.sin(2 * np.pi * rng.uniform(0.2, 8.0) * t + rng.uniform(0, 6))
            for _ in range(4))
    return 1.0 + u + 0.05 * rng.normal(size=n)


def reference_narx(u: np.ndarray, k: int = 1) -> np.ndarray:
    """A known polynomial NARX, written as the slow obvious loop (rest before the record: y = 0, u = u[0])."""
    y = np.zeros(u.size)
    for i in range(u.size):
        y1 = y[i - k] if i >= k else 0.0
        y2 = y[i - 2 * k] if i >= 2 * k else 0.0
        u0 = u[i]
        u1 = u[i - k] if i >= k else u[0]
        y[i] = 0.5 * y1 - 0.2 * y2 + 0.8 * u0 - 0.3 * u1 + 0.1 * u0 * u1 - 0.05 * y1 * u0
    return y


def reference_linear(u: np.ndarray) -> np.ndarray:
    """A first-order linear system, y[i] = 0.7 y[i-1] + 0.3 u[i] (at rest before the record)."""
    y = np.zeros(u.size)
    prev = 0.0
    for i in range(u.size):
        prev = 0.7 * prev + 0.3 * u[i]
        y[i] = prev
    return y


def _dataset(system, noise_sd: float = 0.0, n: int = N) -> Dataset:
    rng = np.random.default_rng(99)
    records = []
    for j, role in enumerate(("identification", "identification", "validation")):
        u = _input(j, n)
        y = system(u) + (noise_sd * rng.normal(size=n) if noise_sd else 0.0)
        records.append(Record(file=f"r{j}.npz", t=np.arange(n) * DT, u=u, y=y, role=role))
    return Dataset(name="known-system", records=records)


@pytest.fixture(scope="module")
def narx_data() -> Dataset:
    return _dataset(reference_narx)


@pytest.fixture(scope="module")
def sparse_fit(narx_data) -> Fit:
    return identify(get_model("narx-sparse", sample_time=DT, degree=2), narx_data, "native", seed=0)


def _validation_erms(fit: Fit) -> float:
    return max(s.e_rms for s in fit.scores("validation"))


# --- recovery ------------------------------------------------------------------
def test_sparse_narx_recovers_a_known_polynomial_narx_exactly(sparse_fit, narx_data):
    assert sparse_fit.method == "native" and sparse_fit.success
    assert _validation_erms(sparse_fit) < 1e-6  # % of peak-to-peak: exact up to rounding
    u = _input(7)
    np.testing.assert_allclose(sparse_fit.simulate(u, DT), reference_narx(u), rtol=1e-7, atol=1e-7)
    # selected on free-run simulation error: every candidate threshold was simulated
    diag = sparse_fit.diagnostics["native"]
    assert len(diag["candidates"]) == get_model("narx-sparse").n_thresholds + 1
    assert sparse_fit.n_evaluations == len(diag["candidates"])


def test_a_threshold_that_removes_every_term_is_a_candidate_without_a_library_warning(narx_data, recwarn):
    """The sweep's largest thresholds may remove every term (pysindy warns): that candidate is listed with
    no nonzero weight, and the user sees no library warning for it."""
    fit = identify(get_model("narx-sparse", sample_time=DT, degree=1, n_thresholds=2, max_threshold=1e6),
                   narx_data, "native", seed=0)
    assert any(c["n_nonzero"] == 0 for c in fit.diagnostics["native"]["candidates"])
    assert not [w for w in recwarn if "Sparsity parameter" in str(w.message)]


def test_sparse_narx_on_a_coarser_step_runs_interleaved_chains():
    """sample_time = 3 dt: the known system at lag spacing 3 is recovered exactly."""
    ds = _dataset(lambda u: reference_narx(u, k=3))
    fit = identify(get_model("narx-sparse", sample_time=3 * DT, degree=2, prefilter="none"), ds, "native")
    assert _validation_erms(fit) < 1e-6


def test_the_step_mean_prefilter_is_a_centred_average_over_one_step():
    x = np.arange(10.0) ** 2
    got = training_samples(x, 4, "step-mean")
    padded = np.concatenate(([x[0]] * 2, x, [x[-1]] * 2))
    want = np.array([padded[i:i + 5].mean() for i in range(10)])[::4]
    np.testing.assert_allclose(got, want)
    np.testing.assert_array_equal(training_samples(x, 4, "none"), x[::4])
    np.testing.assert_array_equal(training_samples(x, 1, "step-mean"), x)


def test_neural_narx_recovers_a_linear_system_to_noise_level():
    noise = 0.002
    ds = _dataset(reference_linear, noise_sd=noise)
    fit = identify(get_model("narx-mlp", sample_time=DT, n_output_lags=1, n_input_lags=1, width=8,
                             max_epochs=300), ds, "native", seed=0)
    u = _input(11)
    err = fit.simulate(u, DT) - reference_linear(u)
    rms = float(np.sqrt(np.mean(err ** 2)))
    assert rms < 5 * noise, rms  # free run, against the noise-free system
    assert fit.n_params == get_model("narx-mlp", n_output_lags=1, n_input_lags=1, width=8).n_params


# --- stepper ---------------------------------------------------------------------
def _random_params(model, seed: int, sample_time: float, scale: float = 0.3) -> dict:
    rng = np.random.default_rng(seed)
    p = {n: float(scale * rng.normal()) for n in model.param_names}
    p.update(u_center=1.0, u_scale=0.5, y_center=0.2, y_scale=2.0, sample_time=sample_time)
    return p


def test_a_diverging_run_is_non_finite_without_a_numpy_warning():
    """A polynomial NARX that diverges in free run gives inf (the scoring names the record); numpy's
    overflow warning would only repeat that on the user's terminal, once per worker."""
    model = get_model("narx-sparse", sample_time=DT, degree=2)
    params = {**_random_params(model, 5, DT, 1.0), "y_scale": 1e10}  # large terms: the run overflows
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        y = model.simulate(_input(3, 400), DT, params)
    assert not np.all(np.isfinite(y))


@pytest.mark.parametrize("name,hyper", [("narx-sparse", {"degree": 2}), ("narx-mlp", {"depth": 2, "width": 5}),
                                        ("gru", {"width": 4})])
@pytest.mark.parametrize("k", [1, 3])
def test_stepper_equals_simulate(name, hyper, k):
    model = get_model(name, sample_time=k * DT, **hyper)
    scale = 0.05 if name == "narx-sparse" else 0.4  # a random polynomial stays bounded only with small terms
    params = _random_params(model, 5, k * DT, scale)
    u = _input(3, 400)
    whole = model.simulate(u, DT, params)
    assert np.all(np.isfinite(whole))
    stepper = model.stepper(DT, params)
    stepped = np.array([stepper.step(v) for v in u])
    np.testing.assert_allclose(stepped, whole, rtol=1e-12, atol=1e-12)
    stepper.reset()
    again = stepper.run(u[:50])
    np.testing.assert_allclose(again, whole[:50], rtol=1e-12, atol=1e-12)
    assert stepper.state["n"] == 50 and stepper.dt == DT
    # a snapshot (through JSON) continues identically, in a fresh stepper too
    snapshot = json.loads(json.dumps(stepper.state))
    other = model.stepper(DT, params)
    other.set_state(snapshot)
    np.testing.assert_allclose(other.run(u[50:120]), whole[50:120], rtol=1e-12, atol=1e-12)
    with pytest.raises(ModelError, match="finite"):
        other.step(float("nan"))
    with pytest.raises(ModelError, match="state keys do not match"):
        other.set_state({"n": 0})


# --- reproducibility, JSON ---------------------------------------------------------
def test_same_seed_same_weights_and_another_seed_other_weights():
    ds = _dataset(reference_linear, n=600)
    model = get_model("narx-mlp", sample_time=DT, n_output_lags=1, n_input_lags=1, width=4, max_epochs=30)
    a, b = (identify(model, ds, "native", seed=3) for _ in range(2))
    assert a.params == b.params
    c = identify(model.clone(seed=4), ds, "native", seed=3)
    assert c.params != a.params


def test_sparse_narx_is_deterministic(narx_data, sparse_fit):
    again = identify(get_model("narx-sparse", sample_time=DT, degree=2), narx_data, "native", seed=5)
    assert again.params == sparse_fit.params


def test_a_fit_round_trips_through_json(sparse_fit):
    back = Fit.from_dict(sparse_fit.to_dict())
    u = _input(8)
    np.testing.assert_array_equal(back.simulate(u, DT), sparse_fit.simulate(u, DT))
    assert back.hyperparameters == sparse_fit.hyperparameters


def test_sample_time_none_is_fixed_at_fit_from_the_drive_period():
    """With sample_time=None the model step is the drive period / 50, a multiple of the records' step."""
    t = np.arange(4000) * 1e-3
    u = np.sin(2 * np.pi * 1.0 * t)
    records = [(u, u, 1e-3, slice(None))]
    assert resolve_sample_time(records, 1.0) == pytest.approx(0.02)
    assert lag_step(0.02, 1e-3) == 20 and lag_step(1e-4, 1e-3) == 1
    rec = Record(file="s.npz", t=t, u=u, y=np.tanh(u), role="identification", frequency_hz=1.0)
    fit = identify(get_model("narx-sparse", degree=1, n_thresholds=1), Dataset("s", [rec]), "native")
    assert fit.params["sample_time"] == pytest.approx(0.02)
    assert fit.diagnostics["native"]["sample_time"] == pytest.approx(0.02)


# --- refusals ------------------------------------------------------------------------
@pytest.mark.parametrize("name,hyper,text", [
    ("narx-sparse", {"degree": 0}, "degree must be an integer in 1..5"),
    ("narx-sparse", {"n_output_lags": 2.0}, "n_output_lags must be an integer"),
    ("narx-sparse", {"sample_time": -1.0}, "sample_time must be a positive number"),
    ("narx-mlp", {"width": 0}, "width must be an integer in 1..1024"),
    ("narx-mlp", {"learning_rate": 0.0}, "learning_rate must be a positive number"),
    ("narx-mlp", {"seed": -1}, "seed must be an integer"),
    ("gru", {"width": "8"}, "width must be an integer"),
    ("narx-mlp", {"hidden": 3}, "unknown hyperparameter 'hidden' for model 'narx-mlp'; it takes: sample_time"),
    ("narx-mlp", {"prefilter": "lowpass"}, "prefilter must be one of step-mean, none"),
])
def test_bad_hyperparameters_are_one_line(name, hyper, text):
    with pytest.raises(ModelError, match=text) as info:
        get_model(name, **hyper)
    assert "\n" not in str(info.value)


def test_methods_are_refused_across_kinds(narx_data):
    assert applicable_methods("narx-sparse") == ["native"] and "native" not in applicable_methods("mrpim")
    with pytest.raises(IdentificationError, match="trained by its own library: use method 'native'") as info:
        identify("narx-mlp", narx_data, "lsq")
    assert "\n" not in str(info.value)
    with pytest.raises(IdentificationError, match="'native' trains only"):
        identify("classical-pi", narx_data, "native")
    assert identify(get_model("narx-sparse", sample_time=DT, degree=1, n_thresholds=1), narx_data,
                    "auto").method == "native"


def test_too_few_rows_for_the_weights_is_one_line():
    ds = _dataset(reference_linear, n=60)
    with pytest.raises((ModelError, IdentificationError), match="narx-mlp") as info:
        identify(get_model("narx-mlp", sample_time=DT, width=64), ds, "native")
    assert "\n" not in str(info.value)


def _split_recording(y_after: np.ndarray | None = None) -> Dataset:
    """One recording cut into an identification window (first half) and a validation window (second half),
    as a measured dataset lists one file twice; ``y_after`` replaces the output of the second half."""
    u = _input(0)
    y = reference_narx(u)
    if y_after is not None:
        y = np.concatenate([y[: N // 2], y_after])
    t = np.arange(N) * DT
    half = N // 2 * DT
    return Dataset(name="split", records=[
        Record(file="rec.csv#1", t=t, u=u, y=y, role="identification", window=(0.0, half)),
        Record(file="rec.csv#2", t=t, u=u, y=y, role="validation", window=(half, N * DT))])


@pytest.mark.parametrize("name, hyper", [("narx-sparse", {"degree": 2}), ("narx-mlp", {"width": 4, "max_epochs": 30})])
def test_a_learner_sees_no_output_of_the_validation_window(name, hyper):
    """The output of the validation window (here: the same recording's second half) takes no part in
    training: other outputs there give the same weights, bit for bit."""
    model = get_model(name, sample_time=DT, **hyper)
    honest = identify(model, _split_recording(), "native", seed=0)
    other = identify(model, _split_recording(np.linspace(5.0, -5.0, N - N // 2)), "native", seed=0)
    assert honest.params == other.params


# --- the recurrent network (optional extra [neural]) ------------------------------------
needs_torch = pytest.mark.skipif(not torch_available(),
                                 reason='PyTorch not installed: the optional extra pip install -e ".[neural]"')


def test_gru_training_without_the_extra_names_it(narx_data):
    if torch_available():
        pytest.skip("PyTorch is installed: the refusal without it cannot be seen here")
    with pytest.raises(ModelError, match=r"\[neural\]"):
        identify(get_model("gru", sample_time=DT, window=50, washout=10, max_epochs=2), narx_data, "native")


@needs_torch
def test_gru_kernel_equals_pytorch_forward():
    import torch

    model = get_model("gru", sample_time=DT, width=5)
    params = _random_params(model, 2, DT, 0.5)
    u = _input(4, 300)
    ours = model.simulate(u, DT, params)
    gru = torch.nn.GRU(1, 5, batch_first=True, dtype=torch.float64)
    w_ih, w_hh, b_ih, b_hh, readout, bias = model.gru_weights(params)
    with torch.no_grad():
        gru.weight_ih_l0.copy_(torch.tensor(w_ih[:, None]))
        gru.weight_hh_l0.copy_(torch.tensor(w_hh))
        gru.bias_ih_l0.copy_(torch.tensor(b_ih))
        gru.bias_hh_l0.copy_(torch.tensor(b_hh))
        h, _ = gru(torch.tensor(((u - 1.0) / 0.5)[None, :, None]))
    theirs = (h[0].numpy() @ readout + bias) * 2.0 + 0.2
    np.testing.assert_allclose(ours, theirs, rtol=1e-10, atol=1e-10)


@needs_torch
def test_a_fit_record_shorter_than_a_training_window_is_named_in_the_notes():
    records = [(_input(0, 400), reference_linear(_input(0, 400)), DT, slice(None)),
               (_input(1, 30), reference_linear(_input(1, 30)), DT, slice(None))]
    model = get_model("gru", sample_time=DT, width=2, window=50, washout=10, max_epochs=2)
    _, _, notes = model.train(records, DT, 0, lambda p: 0.0)
    assert any("1 of 2 fit records (30 model steps) are shorter than one training window (50 steps)" in n for n in notes)
    _, _, notes = model.train(records[:1], DT, 0, lambda p: 0.0)
    assert not any("training window" in n for n in notes)


@needs_torch
def test_gru_learns_a_linear_system_and_is_seeded():
    """Free run on a new input within 2.5 % (rms) of the output's range; an untrained network is ~30 %."""
    ds = _dataset(reference_linear, noise_sd=0.002, n=800)
    model = get_model("gru", sample_time=DT, width=8, window=100, washout=20, max_epochs=300, learning_rate=0.05)
    fit = identify(model, ds, "native", seed=0)
    u = _input(11, 800)
    y = reference_linear(u)
    rms = math.sqrt(float(np.mean((fit.simulate(u, DT) - y) ** 2)))
    assert rms < 0.025 * np.ptp(y), rms
    assert identify(model, ds, "native", seed=0).params == fit.params


# --- the kernels against slow references from their defining equations ------------------------
def _lag_vector(us, ys, i, k, n_out, n_in, y_rest):
    """Past outputs y(i - k), ..., y(i - n_out k) (y_rest before the record), then inputs
    u(i), u(i - k), ..., u(i - (n_in - 1) k) (u(0) before the record)."""
    past = [ys[i - a * k] if i - a * k >= 0 else y_rest for a in range(1, n_out + 1)]
    inputs = [us[i - b * k] if i - b * k >= 0 else us[0] for b in range(n_in)]
    return np.array(past + inputs)


def test_polynomial_and_perceptron_kernels_match_slow_references():
    from hysbench.models.black_box import mlp_simulate, poly_simulate

    rng = np.random.default_rng(11)
    us = rng.normal(size=40)
    k, n_out, n_in, y_rest = 2, 2, 3, 0.3
    n_var = n_out + n_in
    exponents = rng.integers(0, 3, size=(7, n_var))
    coefs = rng.normal(0, 0.2, size=7)
    coefs[2] = 0.0
    ys = []
    for i in range(us.size):
        x = _lag_vector(us, ys, i, k, n_out, n_in, y_rest)
        ys.append(sum(c * np.prod(x ** e) for c, e in zip(coefs, exponents)))
    np.testing.assert_allclose(poly_simulate(us, k, n_out, n_in, y_rest, exponents, coefs), ys,
                               rtol=1e-12, atol=1e-12)

    sizes = np.array([n_var, 4, 3, 1])
    layers = [(rng.normal(0, 0.5, (a, b)), rng.normal(0, 0.5, b)) for a, b in zip(sizes[:-1], sizes[1:])]
    weights = np.concatenate([np.concatenate((W.ravel(), c)) for W, c in layers])
    ys = []
    for i in range(us.size):
        a = _lag_vector(us, ys, i, k, n_out, n_in, y_rest)
        for j, (W, c) in enumerate(layers):
            a = a @ W + c
            a = np.tanh(a) if j < len(layers) - 1 else a
        ys.append(a[0])
    np.testing.assert_allclose(mlp_simulate(us, k, n_out, n_in, y_rest, weights, sizes), ys,
                               rtol=1e-12, atol=1e-12)


def test_gru_kernel_matches_the_gru_equations():
    """PyTorch's GRU cell written out (r, z gates; n = tanh(W_in x + b_in + r (W_hn h + b_hn));
    h' = (1 - z) n + z h), k interleaved chains from h = 0, a linear readout; no PyTorch needed."""
    from hysbench.models.recurrent import gru_simulate

    rng = np.random.default_rng(12)
    H, k = 4, 3
    w_ih, w_hh = rng.normal(size=3 * H), rng.normal(0, 0.6, (3 * H, H))
    b_ih, b_hh = rng.normal(size=3 * H), rng.normal(size=3 * H)
    readout, readout_bias = rng.normal(size=H), 0.4
    us = rng.normal(size=30)

    def sigmoid(v):
        return 1.0 / (1.0 + np.exp(-v))

    g = slice(0, H), slice(H, 2 * H), slice(2 * H, 3 * H)
    chains = [np.zeros(H) for _ in range(k)]
    ref = []
    for i, x in enumerate(us):
        h = chains[i % k]
        r = sigmoid(w_ih[g[0]] * x + b_ih[g[0]] + w_hh[g[0]] @ h + b_hh[g[0]])
        z = sigmoid(w_ih[g[1]] * x + b_ih[g[1]] + w_hh[g[1]] @ h + b_hh[g[1]])
        n = np.tanh(w_ih[g[2]] * x + b_ih[g[2]] + r * (w_hh[g[2]] @ h + b_hh[g[2]]))
        chains[i % k] = (1 - z) * n + z * h
        ref.append(readout @ chains[i % k] + readout_bias)
    np.testing.assert_allclose(gru_simulate(us, k, w_ih, w_hh, b_ih, b_hh, readout, readout_bias), ref,
                               rtol=1e-12, atol=1e-12)

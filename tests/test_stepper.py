"""Causal steppers (models/stepper.py): for every registered model, stepping through a record equals
``simulate``; the state is a plain value that round-trips; the inverse stepper equals the batch inverse."""

import json

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from hysbench.models import MRPIM, ModelError, get_model, list_models
from hysbench.models.pi_stepper import PIInverseStepper, PIStepper
from hysbench.models.stepper import ReplayStepper

DT = 1e-3
RANGE = (0.5, 2.5)
# the configuration a stepper is tested with: the registered default, except where that is non-causal
CAUSAL = {"bouc-wen-oscillator": {"input_interpolation": "linear"}}
# models with a constant-time stepper (the P-I family's step structure)
CONSTANT_TIME = {"classical-pi", "mrpim", "rate-dependent-pi", "mrpim+relaxation", "mrpim+creep",
                 "mrpim+interference"}


def model_and_params(name: str, seed: int = 0):
    """The model and a parameter set drawn around its defaults (the paper's Table 2 for the MRPIM family)."""
    model = get_model(name, **CAUSAL.get(name, {}))
    rng = np.random.default_rng(seed)
    params = {}
    for p in model.parameters():
        if p.log_scale:
            v = p.value * float(np.exp(rng.uniform(-0.5, 0.5)))
        else:
            v = p.value + 0.1 * (p.max - p.min) * rng.uniform(-0.5, 0.5)
        params[p.name] = float(min(max(v, p.min), p.max))
    if name.startswith("mrpim"):
        params.update(MRPIM().preset("paper"))
    return model, params


def pieces_to_input(pieces, u0):
    """Ramps to each target over n samples, then a constant stretch of m samples: reversals and holds."""
    u = [u0]
    for target, n, m in pieces:
        u += list(np.linspace(u[-1], target, n + 1)[1:]) + [target] * m
    return np.array(u)


inputs = st.builds(
    pieces_to_input,
    st.lists(st.tuples(st.floats(RANGE[0], RANGE[1]), st.integers(1, 8), st.integers(0, 4)), min_size=1, max_size=5),
    st.floats(RANGE[0], RANGE[1]))


def assert_close(a, b, rel):
    """Equal to ``rel`` of b's largest finite magnitude; a non-finite sample (a drawn parameter set that
    diverges) must be non-finite at the same sample in both."""
    a = np.asarray(a, dtype=float)
    finite = np.isfinite(b)
    assert np.array_equal(np.isfinite(a), finite), (a, b)
    scale = float(np.max(np.abs(b[finite]), initial=0.0))
    assert np.max(np.abs(a[finite] - b[finite]), initial=0.0) <= rel * scale, (a, b)


@pytest.mark.parametrize("name", list_models())
@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(u=inputs)
def test_stepping_through_a_record_equals_simulate(name, u):
    model, params = model_and_params(name)
    y = model.simulate(u, DT, params, input_range=RANGE)
    s = model.stepper(DT, params, input_range=RANGE)
    assert_close([s.step(v) for v in u], y, 1e-12)
    # a snapshot (through JSON) restored into a fresh stepper continues identically
    s.reset()
    half = u.size // 2
    first = [s.step(v) for v in u[:half]]
    snapshot = json.loads(json.dumps(s.state))
    rest = [s.step(v) for v in u[half:]]
    other = model.stepper(DT, params, input_range=RANGE)
    other.set_state(snapshot)
    assert np.array_equal([other.step(v) for v in u[half:]], rest, equal_nan=True)
    assert_close(first + rest, y, 1e-12)


@pytest.mark.parametrize("name", sorted(CONSTANT_TIME))
def test_the_p_i_family_has_constant_time_steppers(name):
    model, params = model_and_params(name)
    assert isinstance(model.stepper(DT, params, input_range=RANGE), PIStepper)
    assert isinstance(model.inverse_stepper(DT, params, input_range=RANGE), PIInverseStepper)


def test_a_time_varying_offset_is_followed_past_its_first_block():
    from hysbench.models import pi_stepper
    model, params = model_and_params("mrpim+creep")
    params.update(creep_time=0.05, creep_size=0.7)
    t = np.arange(pi_stepper.BASE_BLOCK + 300) * DT
    u = 1.5 - np.cos(2 * np.pi * 3 * t)
    y = model.simulate(u, DT, params, input_range=RANGE)
    assert_close(model.stepper(DT, params, input_range=RANGE).run(u), y, 1e-12)


@pytest.mark.parametrize("name, why", [
    ("bouc-wen-oscillator", "'fourier' input interpolation uses the whole record"),
    ("mrpim", "'smoothed' derivative uses later samples"),
])
def test_a_model_that_needs_later_samples_refuses_a_stepper(name, why):
    hyper = {"derivative": "smoothed"} if name == "mrpim" else {}
    model = get_model(name, **hyper)
    with pytest.raises(ModelError, match=why):
        model.stepper(DT, model.default_params(), input_range=RANGE)


def test_a_stepper_needs_the_input_range_and_finite_input():
    model, params = model_and_params("mrpim")
    with pytest.raises(ModelError, match="input range"):
        model.stepper(DT, params)
    s = model.stepper(DT, params, input_range=RANGE)
    with pytest.raises(ModelError, match="finite"):
        s.step(float("nan"))
    with pytest.raises(ModelError, match="state keys"):
        s.set_state({"plays": []})


def test_the_replay_stepper_is_the_fallback_of_models_without_a_step_structure():
    model, params = model_and_params("mrpim+delay")
    assert isinstance(model.stepper(DT, params, input_range=RANGE), ReplayStepper)


INVERTIBLE = [n for n in list_models() if get_model(n, **CAUSAL.get(n, {})).inverse_unavailable is None]


@pytest.mark.parametrize("name", INVERTIBLE)
@settings(max_examples=5, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(u=inputs, max_rate=st.sampled_from([None, 50.0]))
def test_the_inverse_stepper_equals_the_batch_inverse(name, u, max_rate):
    model, params = model_and_params(name)
    y = model.simulate(u, DT, params, input_range=RANGE)
    batch = model.invert(y, DT, params, input_range=RANGE, max_rate=max_rate)
    scale = {} if name == "viscoelastic" else {"reference_scale": float(np.max(np.abs(y)))}
    s = model.inverse_stepper(DT, params, input_range=RANGE, max_rate=max_rate, **scale)
    u_steps, clipped = [], []
    for v in y:
        u_steps.append(s.step(v))
        clipped.append(s.clipped)
    # viscoelastic: its reach tolerance follows the references so far (see its inverse_stepper)
    assert_close(u_steps, batch.u, 1e-9 if name == "viscoelastic" else 1e-12)
    assert clipped == list(batch.clipped) and s.n_clipped == batch.n_clipped


def test_the_inverse_stepper_reports_clipping_and_reproduces_a_reachable_trajectory():
    model, params = model_and_params("classical-pi")
    params = dict(params, p1=1.0, offset=0.0, **{f"a{i}": 0.1 for i in range(1, 14)})
    t = np.arange(400) * DT
    u = 1.5 - 0.8 * np.cos(2 * np.pi * 2 * t)
    y = model.simulate(u, DT, params, input_range=RANGE)
    s = model.inverse_stepper(DT, params, input_range=RANGE, u_start=u[0])
    assert_close(s.run(y), u, 1e-9)
    assert s.n_clipped == 0
    s.reset()
    s.step(10 * float(np.max(y)))  # far beyond the output the input limits reach
    assert s.clipped and s.n_clipped == 1

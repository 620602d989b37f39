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
    if "delay" in params:  # the default is no delay: 7.4 samples late tests the ring and its interpolation
        params["delay"] = 7.4 * DT
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


# models whose stepper keeps a fixed-size state and advances it with the batch kernel's per-sample update
FIXED_STATE = ["bouc-wen", "dual-polynomial", "elliptical", "preisach", "viscoelastic", "mrpim+delay",
               "mrpim+resonance", "mrpim+saturation", "bouc-wen-oscillator"]


@pytest.mark.parametrize("name", FIXED_STATE)
def test_a_constant_time_stepper_keeps_a_state_of_fixed_size(name):
    model, params = model_and_params(name)
    s = model.stepper(DT, params, input_range=RANGE)
    assert not isinstance(s, ReplayStepper)
    u = 1.5 - np.cos(np.linspace(0.0, 12.0, 400))
    sizes = []
    for k, v in enumerate(u):
        s.step(v)
        if k in (3, 399):
            sizes.append({key: np.size(val) for key, val in s.state.items()})
    assert sizes[0] == sizes[1]


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


@pytest.mark.parametrize("name", ["mrpim+creep", "mrpim+interference"])
@pytest.mark.parametrize("inverse", [False, True])
def test_a_time_varying_offset_far_into_a_run_costs_fixed_memory_and_is_the_closed_form(name, inverse):
    """A stepper 2^40 samples into a run (about 35 years at 1 ms) holds the offset of one block only
    and adds the creep and interference there: its output minus the same stepper's at sample 0 (the
    same plays) is the closed-form offset difference, computed with math."""
    import math

    from hysbench.models import pi_stepper
    model, params = model_and_params(name)
    params.update(creep_time=0.7, creep_size=0.2, interference_frequency=3.0, interference_sin=0.1,
                  interference_cos=-0.05)
    params = {k: v for k, v in params.items() if k in model.param_names}
    make = model.inverse_stepper if inverse else model.stepper
    s = make(DT, params, input_range=RANGE)
    values = list(model.simulate(np.full(3, 1.2), DT, params, input_range=RANGE)) if inverse else [1.2, 1.3, 1.1]
    at_zero = [s.step(v) for v in values]
    s.reset()
    state = dict(s.state, k=2**40)
    s.set_state(state)
    far = [s.step(v) for v in values[:1]]
    assert s._base.size <= pi_stepper.BASE_BLOCK
    if not inverse:
        def offset(k):
            out = 0.0
            if "creep_size" in params:
                out += params["creep_size"] * -math.expm1(-(k * DT) / params["creep_time"])
            if "interference_sin" in params:
                phase = 2.0 * math.pi * params["interference_frequency"] * DT * k
                out += params["interference_sin"] * math.sin(phase) + params["interference_cos"] * math.cos(phase)
            return out
        assert abs((far[0] - at_zero[0]) - (offset(2**40) - offset(0))) <= 1e-12 * (1 + abs(far[0]))
    else:
        assert math.isfinite(far[0]) and RANGE[0] <= far[0] <= RANGE[1]


def test_the_oscillator_steps_with_a_held_input_too():
    model, params = model_and_params("bouc-wen-oscillator")
    model = model.clone(input_interpolation="hold")
    u = 1.5 - np.cos(np.linspace(0.0, 12.0, 300))
    assert_close(model.stepper(DT, params).run(u), model.simulate(u, DT, params), 1e-12)


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


def test_no_registered_model_replays_its_record():
    for name in list_models():
        model, params = model_and_params(name)
        assert not isinstance(model.stepper(DT, params, input_range=RANGE), ReplayStepper), name


# unregistered chains of the extended blocks (extended_stepper.py), each against simulate
CHAINS = [("mrpim", ("relaxation", "delay")), ("mrpim", ("relaxation", "resonance")),
          ("mrpim", ("resonance", "interference")), ("mrpim", ("delay", "interference")),
          ("mrpim", ("delay", "resonance", "interference", "saturation")), ("mrpim", ("creep", "resonance")),
          ("mrpim", ("creep", "interference", "saturation")), ("mrpim", ("creep", "delay")),
          ("mrpim", ("relaxation", "creep", "delay", "resonance")),
          # bases outside the P-I family's step structure (the diagnosis extends any registered model)
          ("bouc-wen", ("relaxation", "creep", "interference")), ("preisach", ("delay", "resonance", "saturation")),
          ("elliptical", ("relaxation", "creep", "delay"))]


CHAIN_CASES = [(base, comps, side) for base, comps in CHAINS
               for side in (("upper", "lower") if "saturation" in comps else ("upper",))]


@pytest.mark.parametrize("base, components, side", CHAIN_CASES,
                         ids=["+".join((b,) + c) + ("" if "saturation" not in c else f"-{s}") for b, c, s in CHAIN_CASES])
def test_a_chain_of_extended_blocks_steps_as_simulate(base, components, side):
    from hysbench.models import ExtendedModel
    model = ExtendedModel(base=base, components=components, saturation_side=side, relaxation_powers=(1, 2))
    params = model.default_params()
    if base == "mrpim":
        params.update(MRPIM().preset("paper"))
    for name, value in (("delay", 0.0237), ("interference_sin", 0.3), ("interference_cos", -0.2),
                        ("creep_size", 0.5), ("creep_time", 0.3), ("c1", 0.7), ("c1_u2", -0.2)):
        if name in params:
            params[name] = value
    t = np.arange(300) * DT
    u = 1.5 - np.cos(2 * np.pi * 5 * t)
    if "saturation" in components:  # a level the output crosses
        free = model.simulate(u, DT, dict(params, saturation_level=1e9 if side == "upper" else -1e9),
                              input_range=RANGE)
        params["saturation_level"] = float(np.quantile(free, 0.8 if side == "upper" else 0.2))
    s = model.stepper(DT, params, input_range=RANGE)
    assert not isinstance(s, ReplayStepper)
    y = model.simulate(u, DT, params, input_range=RANGE)
    assert_close(s.run(u), y, 1e-12)
    s.reset()
    first = s.run(u[:140])
    other = model.stepper(DT, params, input_range=RANGE)
    other.set_state(json.loads(json.dumps(s.state)))
    assert_close(np.concatenate([first, other.run(u[140:])]), y, 1e-12)
    if "saturation" in components:  # the clip is reached
        assert np.any(y == params["saturation_level"])


@pytest.mark.parametrize("name, bad", [
    ("mrpim+delay", {"inputs": [1.0]}),                      # the ring holds 8 inputs at 7.4 samples
    ("mrpim+delay", {"k": -1}),
    ("mrpim+resonance", {"x": "a"}),
    ("bouc-wen-oscillator", {"k": 0.5}),
])
def test_a_chain_stepper_refuses_a_state_it_cannot_be_in(name, bad):
    model, params = model_and_params(name)
    s = model.stepper(DT, params, input_range=RANGE)
    s.run([1.0, 1.2, 1.4])
    before = s.state
    with pytest.raises(ModelError):
        s.set_state(dict(s.state, **bad))
    assert s.state == before  # a refused state changes nothing
    with pytest.raises(ModelError, match="state keys"):
        s.set_state({k: v for k, v in s.state.items() if k != next(iter(bad))})


def test_an_extension_of_a_non_causal_base_refuses_a_stepper():
    from hysbench.models import ExtendedModel
    model = ExtendedModel(components=("delay",), base_hyperparameters={"derivative": "smoothed"})
    with pytest.raises(ModelError, match="'smoothed' derivative uses later samples"):
        model.stepper(DT, model.default_params(), input_range=RANGE)


def test_a_delay_stepper_holds_the_rest_output_then_the_late_input():
    model, params = model_and_params("mrpim+delay")
    params["delay"] = 0.0104  # 10.4 samples: the actuator starts at sample 11, 0.6 samples late
    u = 1.5 - np.cos(np.linspace(0.0, 6.0, 60))
    s = model.stepper(DT, params, input_range=RANGE)
    y = s.run(u)
    assert np.all(y[:11] == y[0])
    assert s.state["k"] == 60 and len(s.state["inputs"]) == 12
    assert_close(y, model.simulate(u, DT, params, input_range=RANGE), 1e-12)


INVERTIBLE = [n for n in list_models() if get_model(n, **CAUSAL.get(n, {})).inverse_unavailable is None]


@pytest.mark.parametrize("name", INVERTIBLE)
@settings(max_examples=5, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(u=inputs, max_rate=st.sampled_from([None, 50.0]))
def test_the_inverse_stepper_equals_the_batch_inverse(name, u, max_rate):
    model, params = model_and_params(name)
    y = model.simulate(u, DT, params, input_range=RANGE)
    batch = model.invert(y, DT, params, input_range=RANGE, max_rate=max_rate)
    # the scale the batch inverse takes its reach tolerance from (viscoelastic: the excursion from the offset)
    scale = float(np.max(np.abs(y - params["offset"] if name == "viscoelastic" else y)))
    s = model.inverse_stepper(DT, params, input_range=RANGE, max_rate=max_rate, reference_scale=scale)
    u_steps, clipped = [], []
    for v in y:
        u_steps.append(s.step(v))
        clipped.append(s.clipped)
    assert_close(u_steps, batch.u, 1e-12)
    assert clipped == list(batch.clipped) and s.n_clipped == batch.n_clipped


@pytest.mark.parametrize("name", INVERTIBLE)
def test_every_inverse_stepper_keeps_a_state_of_fixed_size(name):
    from hysbench.models.inverse import ReplayInverseStepper
    model, params = model_and_params(name)
    y = model.simulate(1.5 - np.cos(np.linspace(0.0, 12.0, 400)), DT, params, input_range=RANGE)
    s = model.inverse_stepper(DT, params, input_range=RANGE, max_rate=50.0)
    assert not isinstance(s, ReplayInverseStepper)
    sizes = []
    for k, v in enumerate(y):
        s.step(v)
        if k in (3, 399):
            sizes.append({key: np.size(val) for key, val in s.state.items()})
    assert sizes[0] == sizes[1]


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


@pytest.mark.parametrize("name", ["mrpim", "rate-dependent-pi", "mrpim+relaxation", "mrpim+creep"])
@pytest.mark.parametrize("inverse, guide_time", [("exact", 0.02), ("reference-driven", 0.0),
                                                 ("reference-driven", 0.02)])
def test_each_p_i_inverse_steps_as_its_batch_and_resumes_from_a_saved_state(name, inverse, guide_time):
    """Both P-I inverses (models/inverse.py): the stepper equals the batch inverse bit for bit, names
    the inverse it runs, and a stepper given the state saved half way continues identically."""
    model, params = model_and_params(name)
    t = np.arange(1200) * DT
    y = model.simulate(1.5 - 0.9 * np.cos(2 * np.pi * 1.5 * t), DT, params, input_range=RANGE)
    options = dict(max_rate=50.0, inverse=inverse, guide_time=guide_time)
    batch = model.invert(y, DT, params, input_range=RANGE, **options)
    s = model.inverse_stepper(DT, params, input_range=RANGE, reference_scale=float(np.max(np.abs(y))), **options)
    assert s.inverse == batch.inverse == inverse
    first = [s.step(v) for v in y[:600]]
    saved = json.loads(json.dumps(s.state))
    resumed = model.inverse_stepper(DT, params, input_range=RANGE, reference_scale=float(np.max(np.abs(y))),
                                    **options)
    resumed.set_state(saved)
    rest = [resumed.step(v) for v in y[600:]]
    np.testing.assert_array_equal(np.array(first + rest), batch.u)
    assert resumed.n_clipped == batch.n_clipped
    if inverse == "reference-driven":
        with pytest.raises(ModelError, match="guide"):
            resumed.set_state(dict(saved, guide=[0.0, float("nan"), 0.0]))

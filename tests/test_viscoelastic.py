"""The ``viscoelastic`` model: interface, agreement with the data generator, batching,
regressors, bounds, identification of its own simulated data, and the batch and window kernels
against scipy's solve_ivp for several parameter sets."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from hysbench.data import Dataset, Record
from hysbench.data import virtual_dea as vd
from hysbench.identification import identify
from hysbench.models import DataScale, ModelError, get_model, list_models
from hysbench.models import dea_physics

DT = 1e-3


@pytest.fixture(scope="module")
def model():
    return get_model("viscoelastic")


@pytest.fixture(scope="module")
def truth(model):
    return model.preset("virtual-dea")


def test_registered_with_its_parameters(model):
    assert "viscoelastic" in list_models()
    assert model.param_names == ("mu", "eta_v", "mu1", "mu2", "mu3", "tau1", "tau2", "tau3", "length", "offset")
    assert model.linear_names == ("length", "offset")
    assert model.has_linear_part
    assert get_model("viscoelastic", n_branches=2).n_params == 8
    assert get_model("viscoelastic", offset=False).linear_names == ("length",)


def test_preset_is_the_virtual_dea(model, truth):
    u = vd.command_voltage(0.4, 6000)
    np.testing.assert_allclose(model.simulate(u, DT, truth), vd.displacement_mm(u, DT), rtol=1e-13, atol=1e-13)
    assert [truth[f"tau{k + 1}"] for k in range(3)] == list(vd.TRUTH.tau_k)


def test_batched_equals_single(model, truth):
    u = vd.command_voltage(1.0, 3000)
    base = model.pack(truth)
    rng = np.random.default_rng(3)
    P = base * np.exp(rng.uniform(-0.3, 0.3, (5, base.size)))
    P[:, -1] = rng.uniform(-1, 1, 5)  # offsets
    Y = model.simulate_batch(u, DT, P)
    assert Y.shape == (5, u.size)
    for i in range(5):
        assert np.array_equal(Y[i], model.simulate(u, DT, P[i]))
    assert len({Y[i].tobytes() for i in range(5)}) == 5


def test_regressors_reproduce_the_output(model, truth):
    u = vd.command_voltage(0.2, 5000)
    nonlinear = {k: truth[k] for k in model.nonlinear_names}
    Phi = model.regressors(u, DT, nonlinear)
    theta = np.array([truth["length"], 0.37])
    np.testing.assert_allclose(Phi @ theta, model.simulate(u, DT, {**truth, "offset": 0.37}), rtol=1e-12, atol=1e-12)
    with pytest.raises(ModelError):
        model.regressors(u, DT, {"mu": 1.0})


def test_default_bounds_hold_the_truth_and_scale_with_the_data(model, truth):
    lo, hi = model.bounds(DataScale(u=2.5, y=14.0, time=1.0))
    p = model.pack(truth)
    assert np.all(lo <= p) and np.all(p <= hi)
    d = model.default_params(DataScale(u=2.5, y=14.0, time=1.0))
    assert all(lo[i] <= d[n] <= hi[i] for i, n in enumerate(model.param_names))
    names = model.param_names
    lo2, hi2 = model.bounds(DataScale(u=5.0, y=7.0, time=2.0))
    i_mu, i_eta, i_tau = names.index("mu"), names.index("eta_v"), names.index("tau1")
    assert hi2[i_mu] / hi[i_mu] == pytest.approx(4 * 2)  # stress ~ u^2 / y
    assert hi2[i_eta] / hi[i_eta] == pytest.approx(4 * 2 * 2)  # stress x time
    assert hi2[i_tau] / hi[i_tau] == pytest.approx(2)


def test_result_does_not_depend_on_the_sampling(model, truth):
    """A stiff parameter set (small dashpot, stiff branch) needs RK4 substeps; sampling at 1 ms
    and at 0.25 ms must agree."""
    lo, hi = model.bounds()
    stiff = {**truth, "eta_v": lo[1], "mu3": 0.5 * hi[4]}
    n = 4000
    u_fine = vd.command_voltage(1.0, 4 * n, DT / 4)
    y_fine = model.simulate(u_fine, DT / 4, stiff)[::4]
    y = model.simulate(u_fine[::4], DT, stiff)
    assert np.max(np.abs(y - y_fine)) < 1e-4 * np.ptp(y)


def test_infeasible_parameters_give_nan_not_an_exception(model, truth):
    lo, _ = model.bounds()
    soft = {**truth, "mu": lo[0], "mu1": lo[2], "mu2": lo[3], "mu3": lo[4]}
    y = model.simulate(np.full(3000, 6.0), DT, soft)  # pushed into the Gent limit
    assert np.isnan(y[-1]) and np.isfinite(y[0])


def test_bad_input_and_hyperparameters(model, truth):
    with pytest.raises(ModelError):
        get_model("viscoelastic", n_branches=-1)
    with pytest.raises(ModelError):
        get_model("viscoelastic", thickness=0.0)
    with pytest.raises(ModelError):
        model.simulate_batch(np.ones(10), DT, np.ones((2, 3)))
    with pytest.raises(ModelError):
        model.simulate(np.array([1.0, np.nan]), DT, truth)
    with pytest.raises(ModelError):
        get_model("viscoelastic", n_branches=2).preset("virtual-dea")


def test_identifies_its_own_simulated_data(model, truth):
    """``identify`` (varpro) on three short records with sensor-like noise: from 15-20 % off, every
    parameter back within 2 % and the residual at the noise."""
    records = [vd.command_voltage(f, int(T / DT)) for f, T in ((1.0, 6.0), (0.2, 15.0), (0.05, 60.0))]
    rng = np.random.default_rng(0)
    noise = 0.01
    ds = Dataset("own", [Record(f"r{i}.csv", np.arange(u.size) * DT, u,
                                model.simulate(u, DT, {**truth, "offset": 0.2}) + rng.normal(0, noise, u.size))
                         for i, u in enumerate(records)])
    names = model.nonlinear_names
    off = dict(zip(names, [1.2, 0.85, 1.15, 0.85, 1.2, 1.15, 0.85, 1.2]))
    fit = identify(model, ds, "varpro", seed=0, start={n: truth[n] * off[n] for n in names},
                   n_candidates=0, n_starts=1, max_nfev=100, tol=1e-10)
    assert fit.success
    for n in names:
        assert fit.params[n] == pytest.approx(truth[n], rel=0.02), n
    assert np.sqrt(fit.fitness / len(ds.records)) == pytest.approx(noise, rel=0.05)  # eq. 9: mean square per record
    assert fit.params["length"] == pytest.approx(truth["length"], rel=0.02)
    assert fit.params["offset"] == pytest.approx(0.2, abs=0.02)


def test_windowed_forms_equal_the_full_simulation(truth):
    model = get_model("viscoelastic", warmup_stride=1)  # exact: every sample interval integrated
    u = vd.command_voltage(0.4, 7000)
    rng = np.random.default_rng(5)
    P = model.pack(truth) * np.exp(rng.uniform(-0.2, 0.2, (3, model.n_params)))
    window = slice(4500, 6999)
    full = model.simulate_batch(u, DT, P)
    assert np.array_equal(model.simulate_window_batch(u, DT, P, window), full[:, window])
    n_nl = len(model.nonlinear_names)
    batch = model.windowed_regressors_batch(u, DT, P[:, :n_nl], window)
    assert batch.shape == (3, window.stop - window.start, 2)
    for i in range(3):
        nonlinear = dict(zip(model.nonlinear_names, P[i, :n_nl]))
        single = model.windowed_regressors(u, DT, nonlinear, window)
        assert np.array_equal(batch[i], single)
        assert np.array_equal(single, model.regressors(u, DT, nonlinear)[window])
        np.testing.assert_allclose(single @ P[i, n_nl:], full[i, window], rtol=1e-12, atol=1e-12)


def test_long_warmup_steps_change_the_window_negligibly(model, truth):
    """The identifiers' windowed forms (warm-up crossed in 5-sample steps) against the exact run,
    on the longest record of the default dataset, and the exact form against the full simulation."""
    assert model.warmup_stride == 5
    u = vd.command_voltage(0.02, 500_000)
    window = slice(450_000, 500_000)
    P = model.pack(truth)[None, :]
    fast = model.simulate_window_batch(u, DT, P, window)[0]
    exact = get_model("viscoelastic", warmup_stride=1).simulate_window_batch(u, DT, P, window)[0]
    full = model.simulate(u, DT, truth)[window]
    assert np.array_equal(exact, full)
    assert np.max(np.abs(fast - exact)) < 1e-5 * np.ptp(exact)
    assert not np.array_equal(fast, exact)  # the long steps were taken


# --- the batch and window kernels against solve_ivp, several parameter sets ---------------------------
N_REF = 161
#: rows of (mu, eta_v, mu1..3, tau1..3, length, offset) in the model's units (kPa, kPa s, s, mm, mm): the
#: virtual DEA, fast branches (two RK4 substeps per sample), a stiff third branch (four substeps)
REFERENCE_SETS = np.array([
    [7.87, 15.9, 178.0, 117.0, 349.0, 0.268, 2.03, 58.2, 14.0, 0.0],
    [5.0, 9.0, 250.0, 60.0, 500.0, 0.02, 0.15, 3.0, 11.0, 0.3],
    [7.87, 5.0, 178.0, 117.0, 1000.0, 0.05, 0.5, 10.0, 17.0, -0.2],
])


def reference_drive():
    t = np.arange(N_REF) * DT
    return 2.4 * np.sin(np.pi * t / t[-1]) ** 2 * (1.0 + 0.3 * np.sin(2 * np.pi * 15.0 * t))


def dea_rhs(u_kv, state, p):
    """The virtual DEA's equations (hysbench.data.virtual_dea), each region's nominal stress along the
    actuation direction from the Gent energies, the branches' Zhao-Koh-Suo flow, the dashpot and the
    Maxwell stress in the platform's force balance."""
    K = p.n_branches
    lam_a = state[0]
    ratio = p.L_active / p.L_passive
    lam_p = p.lam0 - ratio * (lam_a - p.lam0)
    d = [0.0] * len(state)
    stress = []
    for reg, lam in enumerate((lam_a, lam_p)):
        l3 = 1.0 / (lam * p.lam_t)  # thickness stretch, incompressible
        s = p.mu * (lam - l3 * l3 / lam) / (1.0 - (lam ** 2 + p.lam_t ** 2 + l3 ** 2 - 3.0) / p.J)
        for k in range(K):
            j = 1 + 2 * (reg * K + k)
            xi, xi_t = state[j], state[j + 1]
            e = (lam / xi, p.lam_t / xi_t, xi * xi_t * l3)  # the branch spring's elastic stretches
            g = p.mu_k[k] / (1.0 - (e[0] ** 2 + e[1] ** 2 + e[2] ** 2 - 3.0) / p.J)
            sig = [g * v * v for v in e]  # its true stresses, up to the pressure
            s += (sig[0] - sig[2]) / lam
            eta = p.mu_k[k] * p.tau_k[k]
            d[j] = xi * (2 * sig[0] - sig[1] - sig[2]) / (6 * eta)
            d[j + 1] = xi_t * (2 * sig[1] - sig[0] - sig[2]) / (6 * eta)
        stress.append(s)
    thickness = p.H / (lam_a * p.lam_t)
    maxwell = p.eps_r * dea_physics.EPS0 * (1e3 * u_kv / thickness) ** 2 / lam_a
    c_a, c_p = 4 * p.eta_v / lam_a ** 2, 4 * p.eta_v / lam_p ** 2
    d[0] = (stress[1] - stress[0] + maxwell) / (c_a + ratio * c_p)
    return d


def reference_output(u, row):
    """y(t_k) = length (lam_a - lam0) + offset by solve_ivp (DOP853, rtol 1e-12), one call per sample
    interval (the input, linear between samples, kinks there), from the rest state."""
    p = vd.TRUTH.with_changes(mu=row[0] * 1e3, eta_v=row[1] * 1e3, mu_k=tuple(row[2:5] * 1e3),
                              tau_k=tuple(row[5:8]))
    state = np.array([p.lam0] + [p.lam0, p.lam_t] * (2 * p.n_branches))
    out = [state[0]]
    for k in range(u.size - 1):
        def rhs(t, x, k=k):
            return dea_rhs(u[k] + (t - k * DT) / DT * (u[k + 1] - u[k]), x, p)

        sol = solve_ivp(rhs, (k * DT, (k + 1) * DT), state, method="DOP853", rtol=1e-12, atol=1e-14)
        assert sol.success
        state = sol.y[:, -1]
        out.append(state[0])
    return row[8] * (np.array(out) - p.lam0) + row[9]


@pytest.fixture(scope="module")
def reference_outputs():
    u = reference_drive()
    return u, np.array([reference_output(u, row) for row in REFERENCE_SETS])


def test_batch_kernel_matches_solve_ivp_for_three_parameter_sets(model, reference_outputs):
    """simulate_batch (every sample interval by RK4, |J| h <= 0.25) against solve_ivp for three parameter
    sets: within 2e-7 of each output's peak-to-peak (RK4's error at the kernel's step, 5e-8 at most
    here, falls 16-fold per halved step); each row is the serial kernel's single-set result."""
    u, ref = reference_outputs
    phys = model.physical_vectors(REFERENCE_SETS)
    assert [dea_physics.substeps(u[0], DT, phys[i], 3) for i in range(3)] == [1, 2, 4]
    Y = model.simulate_batch(u, DT, REFERENCE_SETS)
    for i in range(3):
        assert np.max(np.abs(Y[i] - ref[i])) < 2e-7 * np.ptp(ref[i])
        single = REFERENCE_SETS[i, 8] * dea_physics.simulate_stretch(u, DT, phys[i], 3) + REFERENCE_SETS[i, 9]
        assert np.array_equal(Y[i], single)


def test_window_kernel_matches_solve_ivp_for_three_parameter_sets(model, reference_outputs):
    """simulate_window_batch for three parameter sets: exact (warmup_stride 1) within 2e-7 of each
    output's peak-to-peak of solve_ivp, on a window and on a row subset; with the identifiers' 5-sample
    warm-up steps (sized for stability, not accuracy) within 2e-5, the window starting right after a
    15 Hz drive (the docstring's 2e-7 is for the virtual DEA's records)."""
    u, ref = reference_outputs
    exact = get_model("viscoelastic", warmup_stride=1)
    window, rows = slice(80, N_REF), np.array([3, 40, 81, 82, 150, N_REF - 1])
    tolerance = np.ptp(ref, axis=1)[:, None]
    assert np.all(np.abs(exact.simulate_window_batch(u, DT, REFERENCE_SETS, window) - ref[:, window])
                  < 2e-7 * tolerance)
    assert np.all(np.abs(exact.simulate_window_batch(u, DT, REFERENCE_SETS, rows) - ref[:, rows]) < 2e-7 * tolerance)
    fast = model.simulate_window_batch(u, DT, REFERENCE_SETS, window)
    assert np.all(np.abs(fast - ref[:, window]) < 2e-5 * tolerance)
    for i in range(3):
        assert np.array_equal(fast[i], model.simulate_window_batch(u, DT, REFERENCE_SETS[i:i + 1], window)[0])


@settings(max_examples=15)
@given(seed=st.integers(0, 10_000), n_sets=st.integers(1, 4), start=st.integers(0, N_REF - 1),
       stride=st.sampled_from([1, 5]))
def test_window_batch_rows_are_the_single_set_runs(seed, n_sets, start, stride):
    """Property: each row of the window kernel, for any parameter sets, window and warm-up stride, is that
    set run alone (stride 1: the serial kernel's samples in the window)."""
    model = get_model("viscoelastic", warmup_stride=stride)
    rng = np.random.default_rng(seed)
    P = REFERENCE_SETS[rng.integers(0, 3, n_sets)] * np.exp(rng.uniform(-0.3, 0.3, (n_sets, 10)))
    u = reference_drive()
    window = slice(start, N_REF)
    W = model.simulate_window_batch(u, DT, P, window)
    phys = model.physical_vectors(P)
    for i in range(n_sets):
        assert np.array_equal(W[i], model.simulate_window_batch(u, DT, P[i:i + 1], window)[0])
        if stride == 1:
            single = P[i, 8] * dea_physics.simulate_stretch(u, DT, phys[i], 3)[window] + P[i, 9]
            assert np.array_equal(W[i], single)

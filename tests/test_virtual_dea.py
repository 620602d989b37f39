"""The virtual DEA: kernel against a slow reference, calibration figures on a fresh run,
time-step convergence, sensor, dataset regeneration, CLI refusals."""

from __future__ import annotations

import math
import tomllib
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from hysbench.benchmarks import cli
from hysbench.data.metrics import loop_width, peak_to_peak
from hysbench.data.protocol import (
    FREQUENCIES_HZ,
    IDENTIFICATION_WEIGHTS,
    VALIDATION_FREQUENCIES_HZ,
    paper_voltage,
    period_samples,
)
from hysbench.data import load_dataset
from hysbench.data import virtual_dea as vd
from hysbench.models.dea_physics import EPS0
from hysbench.data.dea_sensor import LaserSensor

DEFAULT_DATASET = vd.default_dataset_path()


# --- a slow, obvious reference: stresses from the strain energy, scipy's integrator -------------
def gent_energy(mu, J, l1, l2, l3):
    return -0.5 * mu * J * math.log(1.0 - (l1 * l1 + l2 * l2 + l3 * l3 - 3.0) / J)


def reference_rhs(t, state, u_of_t, p: vd.DEAParameters):
    K = p.n_branches
    lam_a = state[0]
    ratio = p.L_active / p.L_passive
    lam_p = p.lam0 - ratio * (lam_a - p.lam0)
    h = 1e-6
    d = np.zeros_like(state)
    total = []
    for reg, lam in enumerate((lam_a, lam_p)):
        def w_total(stretch):  # energy per unit reference volume; thickness from incompressibility
            w = gent_energy(p.mu, p.J, stretch, p.lam_t, 1.0 / (stretch * p.lam_t))
            for k in range(K):
                xi, xi_t = state[1 + 2 * (reg * K + k)], state[2 + 2 * (reg * K + k)]
                w += gent_energy(p.mu_k[k], p.J, stretch / xi, p.lam_t / xi_t, xi * xi_t / (stretch * p.lam_t))
            return w

        s = (w_total(lam + h) - w_total(lam - h)) / (2 * h)  # nominal stress along lam
        for k in range(K):
            j = 1 + 2 * (reg * K + k)
            xi, xi_t = state[j], state[j + 1]
            e = np.array([lam / xi, p.lam_t / xi_t, xi * xi_t / (lam * p.lam_t)])
            sig = np.empty(3)  # true stresses of the branch spring, e_i dW/de_i (pressure cancels below)
            for i in range(3):
                ep, em = e.copy(), e.copy()
                ep[i] += h
                em[i] -= h
                sig[i] = e[i] * (gent_energy(p.mu_k[k], p.J, *ep) - gent_energy(p.mu_k[k], p.J, *em)) / (2 * h)
            eta = p.mu_k[k] * p.tau_k[k]
            d[j] = xi * (2 * sig[0] - sig[1] - sig[2]) / (6 * eta)
            d[j + 1] = xi_t * (2 * sig[1] - sig[0] - sig[2]) / (6 * eta)
        total.append(s)
    phi = 1e3 * u_of_t(t)
    thickness = p.H / (lam_a * p.lam_t)
    maxwell_nominal = p.eps_r * EPS0 * (phi / thickness) ** 2 / lam_a
    # force balance: S_a - s_M + 4 eta_v v / lam_a^2 = S_p + 4 eta_v (-ratio v) / lam_p^2, solved for v
    c_a, c_p = 4 * p.eta_v / lam_a**2, 4 * p.eta_v / lam_p**2
    d[0] = (total[1] - total[0] + maxwell_nominal) / (c_a + ratio * c_p)
    return d


def test_kernel_matches_slow_reference():
    dt, n = 1e-3, 2501
    t = np.arange(n) * dt
    u = vd.command_voltage(1.0, n)
    p = vd.TRUTH
    x = vd.displacement_mm(u, dt, p)
    K = p.n_branches
    y0 = np.array([p.lam0] + [p.lam0, p.lam_t] * (2 * K))
    sol = solve_ivp(reference_rhs, (0, t[-1]), y0, t_eval=t, args=(lambda s: np.interp(s, t, u), p),
                    method="DOP853", rtol=1e-10, atol=1e-12, max_step=dt)
    assert sol.success
    ref = 1e3 * p.L_active * (sol.y[0] - p.lam0)
    assert np.max(np.abs(x - ref)) < 1e-5 * np.max(np.abs(ref))
    assert np.max(np.abs(ref)) > 5.0  # the check is over a real actuation, not a flat line


# --- calibration figures on a freshly simulated run -----------------------------------------------
@pytest.fixture(scope="module")
def figures():
    return vd.calibration_figures(vd.TRUTH)


def test_p2p_falls_as_the_paper_reports(figures):
    target, tol = vd.CALIBRATION_TARGETS["p2p_change_pct"]
    assert abs(figures["p2p_change_pct"] - target) <= tol
    assert figures["p2p_monotone_decreasing"]


def test_width_grows_as_the_paper_reports(figures):
    target, tol = vd.CALIBRATION_TARGETS["width_change_pct"]
    assert abs(figures["width_change_pct"] - target) <= tol
    assert figures["width_monotone_increasing"]
    # the figures are the foundation's metrics on the final period
    run = figures["runs"][1.0]
    u, x = run.final_loop()
    assert figures["width_mm"][1.0] == loop_width(u, x)
    assert figures["p2p_mm"][1.0] == peak_to_peak(x)


def test_creep_transition_at_0p1hz(figures):
    target, tol = vd.CALIBRATION_TARGETS["creep_transition_s"]
    assert abs(figures["creep_transition_s"][0.1] - target) <= tol


def test_displacements_and_asymmetry(figures):
    assert 10.0 <= figures["max_displacement_mm"] <= 16.0
    assert figures["min_displacement_mm"] >= -1e-9  # the active region only extends
    for f in FREQUENCIES_HZ:
        assert 3.0 <= figures["p2p_mm"][f] <= 15.0
        assert figures["asymmetry"][f] < -0.1  # far from point-symmetric (symmetric = 0)


def test_halving_the_step_changes_p2p_and_width_by_less_than_half_a_percent(figures):
    coarse = figures["runs"][1.0]
    fine = vd.run_frequency(1.0, dt=0.5e-3)
    assert abs(fine.p2p / coarse.p2p - 1) < 0.005
    assert abs(fine.width / coarse.width - 1) < 0.005


def test_response_modes_predict_a_small_step():
    """The linearised modes (the time constants a diagnosis should find) against the simulated step."""
    from hysbench.models import dea_physics

    modes = vd.response_modes()
    assert abs(sum(m.static_gain_share for m in modes) - 1) < 1e-9
    assert max(m.tau_s for m in modes) > max(vd.TRUTH.tau_k)  # the creep mode is slower than any branch
    p, K = vd.TRUTH.vector(), vd.TRUTH.n_branches
    state = dea_physics.initial_state(p, K)
    dea_physics.simulate_from(np.full(300_001, 1.5), 0.01, p, K, state)
    lam_start = state[0]
    du, dt, n = 0.002, 1e-3, 300_001
    step = 1e3 * vd.TRUTH.L_active * (dea_physics.simulate_from(np.full(n, 1.5 + du), dt, p, K, state)
                                      - (lam_start - vd.TRUTH.lam0))
    t = np.arange(n) * dt
    predicted = du * sum(m.gain_mm_per_kv * (1 - np.exp(-t / m.tau_s)) for m in modes)
    assert np.max(np.abs(step - predicted)) < 2e-3 * du * sum(m.gain_mm_per_kv for m in modes)


# --- creep transition definition -----------------------------------------------------------------
def brute_force_transition(y, f, dt, tol=0.02):
    n = period_samples(f, dt)
    cycles = [y[i * n:(i + 1) * n] for i in range(len(y) // n)]
    final = cycles[-1]
    band = tol * (max(final) - min(final))
    for j in range(len(cycles)):
        if all(abs(sum(c) / len(c) - sum(final) / len(final)) <= band for c in cycles[j:]):
            return j * n * dt
    raise AssertionError("unreachable: the final cycle is always inside its own band")


@given(st.floats(0.5, 5.0), st.floats(5.0, 60.0), st.sampled_from([0.2, 0.5, 1.0]), st.floats(-1.0, 1.0))
def test_creep_transition_matches_brute_force(size, tau, f, wiggle):
    dt = 0.01
    t = np.arange(int(round(200 / dt))) * dt
    y = np.sin(2 * np.pi * f * t) * 3 - size * np.exp(-t / tau) * (1 + 0.2 * wiggle * np.cos(0.05 * t))
    assert vd.creep_transition_s(y, f, dt) == pytest.approx(brute_force_transition(y, f, dt), abs=1e-9)


# --- input and sensor -------------------------------------------------------------------------------
@pytest.mark.parametrize("f", FREQUENCIES_HZ)
def test_command_voltage_is_eq1_and_exactly_periodic(f):
    n = period_samples(f)
    u = vd.command_voltage(f, 3 * n + 7)
    t = np.arange(u.size) * 1e-3
    assert np.max(np.abs(u - paper_voltage(t, f))) < 1e-12
    assert np.array_equal(u[:n], u[n:2 * n]) and np.array_equal(u[:7], u[3 * n:])


def test_sensor_quantises_adds_the_stated_noise_and_clips():
    s = LaserSensor()
    assert s.lsb_mm == 200 / 65536
    rng = np.random.default_rng(1)
    x = np.full(200_000, 3.21)
    y = s.measure(x, rng)
    codes = y / s.lsb_mm
    assert np.array_equal(codes, np.round(codes))  # every output is a whole number of LSBs
    assert abs(np.mean(y) - 3.21) < 0.001
    sd = np.std(y)  # quantisation adds lsb^2/12 to the variance
    assert sd == pytest.approx(math.sqrt(s.noise_sd_mm**2 + s.lsb_mm**2 / 12), rel=0.02)
    x = np.array([0.0, 1e-4, 0.002, 1.0])
    quiet = LaserSensor(noise_sd_mm=0.0).measure(x, rng)
    assert np.array_equal(quiet / s.lsb_mm, np.round((s.rest_distance_mm + x) / s.lsb_mm) - s.rest_code)
    far = LaserSensor(noise_sd_mm=0.0).measure(np.array([-40.0, 80.0]), rng)  # beyond 0..100 mm
    assert far[0] == pytest.approx(-s.rest_distance_mm, abs=s.lsb_mm)
    assert far[1] == pytest.approx(s.range_mm - s.rest_distance_mm, abs=s.lsb_mm)


def test_sensor_is_seeded():
    x = np.linspace(0, 10, 5000)
    a = LaserSensor().measure(x, np.random.default_rng(7))
    b = LaserSensor().measure(x, np.random.default_rng(7))
    c = LaserSensor().measure(x, np.random.default_rng(8))
    assert np.array_equal(a, b) and not np.array_equal(a, c)


# --- the default dataset ------------------------------------------------------------------------
def test_default_dataset_is_the_protocol_through_the_creep_transition(figures):
    ds = load_dataset(DEFAULT_DATASET)
    assert [r.frequency_hz for r in ds.records] == list(FREQUENCIES_HZ)
    assert ds.input_unit == "kV" and ds.output_unit == "mm"
    total = sum(p.stat().st_size for p in DEFAULT_DATASET.iterdir())
    assert total < 30e6
    for r in ds.records:
        f = r.frequency_hz
        if f in IDENTIFICATION_WEIGHTS:
            assert r.role == "identification" and r.weight == IDENTIFICATION_WEIGHTS[f]
        else:
            assert f in VALIDATION_FREQUENCIES_HZ and r.role == "validation" and r.weight == 1.0
        n = period_samples(f)
        tc = figures["creep_transition_s"][f]
        assert r.t.size == int(round(tc * f + 2)) * n  # through the transition, then two stable periods
        assert (r.start, r.stop) == (r.t.size - n, r.t.size)  # window = the last period
        assert np.array_equal(r.t, np.arange(r.t.size) * 1e-3)
        assert np.max(np.abs(r.u - paper_voltage(r.t, f))) < 1e-12  # commanded voltage, full precision
        codes = r.y / LaserSensor().lsb_mm
        assert np.array_equal(codes, np.round(codes))
        assert np.std(r.y - vd.displacement_mm(r.u)) == pytest.approx(0.01, rel=0.05)


def test_cli_regenerates_the_default_dataset_exactly(tmp_path, capsys):
    out = tmp_path / "regenerated"
    assert cli.main(["data", "virtual-dea", "--out", str(out), "--seed", str(vd.DEFAULT_SEED)]) == 0
    shipped, fresh = load_dataset(DEFAULT_DATASET), load_dataset(out)
    assert (out / "dataset.toml").read_text() == (DEFAULT_DATASET / "dataset.toml").read_text()
    for a, b in zip(shipped.records, fresh.records, strict=True):
        assert a.file == b.file
        for name in ("t", "u", "y"):
            assert np.array_equal(getattr(a, name), getattr(b, name)), (a.file, name)
    import json

    t_shipped = json.loads((DEFAULT_DATASET / "truth.json").read_text())
    t_fresh = json.loads((out / "truth.json").read_text())
    for key in ("seed", "parameters", "branch_relaxation_times_s", "sensor"):
        assert t_shipped[key] == t_fresh[key]
    assert t_fresh["branch_relaxation_times_s"] == list(vd.TRUTH.tau_k)
    # another seed: same noise-free signal, different noise
    other = vd.generate_record(1.0, seed=vd.DEFAULT_SEED + 1)
    assert not np.array_equal(other.y, shipped.record("f1Hz.npz").y)
    assert np.array_equal(other.u, shipped.record("f1Hz.npz").u)


def bad(argv, capsys):
    try:
        code = cli.main(argv)
    except SystemExit as exc:  # argparse usage errors
        code = exc.code
    err = capsys.readouterr().err
    return code, err


@pytest.mark.parametrize("extra, message", [
    (["--seed", "-1"], "--seed"),
    (["--seed", "x1"], "--seed"),
    (["--bogus"], "unrecognized"),
])
def test_cli_bad_options_exit_2_with_one_line(tmp_path, capsys, extra, message):
    out = tmp_path / "never"
    code, err = bad(["data", "virtual-dea", "--out", str(out), *extra], capsys)
    assert code == 2
    assert err.count("\n") == 1 and message in err and "Traceback" not in err
    assert not out.exists()


def test_cli_refuses_to_replace_what_is_not_a_dataset(tmp_path, capsys):
    precious = tmp_path / "precious"
    precious.mkdir()
    (precious / "notes.txt").write_text("keep me")
    code, err = bad(["data", "virtual-dea", "--out", str(precious)], capsys)
    assert code == 2 and err.count("\n") == 1 and "dataset.toml" in err
    assert (precious / "notes.txt").read_text() == "keep me"
    a_file = tmp_path / "file"
    a_file.write_text("x")
    code, err = bad(["data", "virtual-dea", "--out", str(a_file)], capsys)
    assert code == 2 and err.count("\n") == 1 and "not a folder" in err
    code, err = bad(["data"], capsys)
    assert code == 2 and err.count("\n") == 1


def test_dataset_toml_is_what_the_loader_reads():
    meta = tomllib.loads((DEFAULT_DATASET / "dataset.toml").read_text())
    assert meta["name"] == vd.DATASET_NAME
    assert str(vd.DEFAULT_SEED) in meta["description"]
    assert Path(DEFAULT_DATASET / "truth.json").is_file()

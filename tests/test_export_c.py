"""The C export (models/export_c.py, ``hysbench export``): the generated C99 compiles warning-free and
agrees with Python's simulate and inverse stepper to 1e-9 relative."""

import hashlib
import json
import shutil
import os
import subprocess
from pathlib import Path

import numpy as np
import pytest

from hysbench.benchmarks.cli import main
from hysbench.data.dataset import load_dataset
from hysbench.models import MRPIM, FittedModel, ModelError, get_model, load_model
from hysbench.models.export_c import ExportError, export_c

ROOT = Path(__file__).resolve().parents[1]
CC = shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
needs_cc = pytest.mark.skipif(CC is None, reason="no C compiler (cc, gcc or clang) on PATH")
FLAGS = ["-std=c99", "-Wall", "-Wextra", "-pedantic", "-Werror", "-O2"]
RANGE = (0.5, 2.5)
DT = 1e-3

DRIVER = """#include <stdio.h>
#include "{p}.h"
/* reads: mode (0 forward, 1 inverse), n, then n numbers; prints n results and the clipped count */
int main(void)
{{
    {p}_state s;
    int mode;
    long n, i;
    double x;
    if (scanf("%d %ld", &mode, &n) != 2) return 1;
    {p}_init(&s);
    for (i = 0; i < n; i++) {{
        if (scanf("%lf", &x) != 1) return 1;
        printf("%.17g\\n", mode ? {p}_inverse_step(&s, x) : {p}_step(&s, x));
    }}
    printf("%ld\\n", s.n_clipped);
    return 0;
}}
"""


def fitted(name: str) -> FittedModel:
    model = get_model(name)
    params = model.default_params()
    rng = np.random.default_rng(3)
    if name.startswith("mrpim"):
        params.update(MRPIM().preset("paper"))
        params.update(tau1=0.3, c1=0.4, creep_time=0.7, creep_size=0.2, interference_frequency=3.0,
                      interference_sin=0.1, interference_cos=-0.05)
        params = {k: v for k, v in params.items() if k in model.param_names}
    else:
        params = {k: float(abs(rng.normal()) * 0.3) for k in params}
    return FittedModel(model, params, RANGE, DT, {"scale": {"y": 10.0}})


def build(tmp_path: Path, fit: FittedModel, prefix: str = "hm", **options) -> Path:
    header, source = export_c(fit, prefix, model_file="test.json", model_sha256="0" * 64, version="test", **options)
    (tmp_path / f"{prefix}.h").write_text(header)
    (tmp_path / f"{prefix}.c").write_text(source)
    (tmp_path / "driver.c").write_text(DRIVER.format(p=prefix))
    exe = tmp_path / "run"
    done = subprocess.run([CC, *FLAGS, "-o", str(exe), str(tmp_path / f"{prefix}.c"), str(tmp_path / "driver.c"),
                           "-lm"], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr  # -Werror: any warning fails
    return exe


def run(exe: Path, mode: int, values) -> tuple[np.ndarray, int]:
    text = f"{mode} {len(values)}\n" + "\n".join(repr(float(v)) for v in values) + "\n"
    out = subprocess.run([str(exe)], input=text, capture_output=True, text=True, check=True).stdout.split()
    return np.array([float(v) for v in out[:-1]]), int(out[-1])


def close(a, b, rel):
    return np.max(np.abs(a - b)) <= rel * np.max(np.abs(b))


def drive(n=2500):
    t = np.arange(n) * DT
    return 1.5 - np.cos(2 * np.pi * 1.0 * t) + 0.05 * np.sin(2 * np.pi * 9 * t)


@needs_cc
@pytest.mark.parametrize("name", ["classical-pi", "mrpim", "rate-dependent-pi", "mrpim+relaxation", "mrpim+creep",
                                  "mrpim+interference"])
@pytest.mark.parametrize("inverse, guide_time", [("exact", 0.02), ("reference-driven", 0.0),
                                                 ("reference-driven", 0.02)])
def test_generated_c_agrees_with_simulate_and_the_inverse_stepper(tmp_path, name, inverse, guide_time):
    fit = fitted(name)
    options = dict(max_rate=50.0, inverse=inverse, guide_time=guide_time)
    exe = build(tmp_path, fit, **options)
    u = drive()
    y = fit.simulate(u)
    y_c, _ = run(exe, 0, u)
    assert close(y_c, y, 1e-9)
    inverse_stepper = fit.inverse_stepper(reference_scale=10.0, **options)
    u_py = inverse_stepper.run(y)
    u_c, n_clipped = run(exe, 1, y)
    assert close(u_c, u_py, 1e-9)
    assert n_clipped == inverse_stepper.n_clipped
    header = (tmp_path / "hm.h").read_text()
    assert f"Inverse: {inverse_stepper.inverse} (" in header


@needs_cc
def test_mrpim_on_the_validation_record_forward_and_inverse(tmp_path):
    """The virtual DEA's 0.2 Hz validation record (410 000 samples) with Table 2's MRPIM (a fixed
    model, so no fit runs here): the C model reproduces simulate, and the C inverse driven with that
    prediction reproduces Python's inverse stepper. (Whether the inverse gives the input back is the
    model's property, not the export's: MRPIM's inverse recursion through q u'' is unstable, see
    docs/deploying.md.)"""
    record = load_dataset(ROOT / "data" / "virtual_dea").record("f0.2Hz.npz")
    fit = FittedModel(MRPIM(), MRPIM().preset("paper"), RANGE, record.dt, {"scale": {"y": 10.0}})
    exe = build(tmp_path, fit, u_start=float(record.u[0]))
    y_c, _ = run(exe, 0, record.u)
    assert close(y_c, fit.simulate(record.u), 1e-9)
    u_c, n_clipped = run(exe, 1, y_c)
    inverse = fit.inverse_stepper(u_start=float(record.u[0]), reference_scale=10.0)
    assert close(u_c, inverse.run(y_c), 1e-9)
    assert n_clipped == inverse.n_clipped


@needs_cc
def test_cli_export_writes_header_and_source_that_name_their_model_file(tmp_path, capsys):
    path = fitted("mrpim").save(tmp_path / "m.json")
    code = main(["export", str(path), "--out", str(tmp_path / "c"), "--prefix", "dea"])
    assert code == 0, capsys.readouterr().err
    source = (tmp_path / "c" / "dea.c").read_text()
    assert "m.json" in source and hashlib.sha256(path.read_bytes()).hexdigest() in source
    assert "#include <math.h>" in source and "malloc" not in source
    header = (tmp_path / "c" / "dea.h").read_text()
    for decl in ("} dea_state;", "void dea_init(dea_state *s);", "double dea_step(dea_state *s, double u);",
                 "double dea_inverse_step(dea_state *s, double y_ref);"):
        assert decl in header
    done = subprocess.run([CC, *FLAGS, "-c", "-o", str(tmp_path / "dea.o"), str(tmp_path / "c" / "dea.c")],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr


@pytest.mark.parametrize("name, why", [("mrpim+delay", "delay"), ("preisach", "only the P-I family"),
                                       ("mrpim+resonance", "relative degree 2")])
def test_a_model_that_cannot_be_exported_says_so_in_one_line(tmp_path, capsys, name, why):
    model = get_model(name)
    path = FittedModel(model, model.default_params(), RANGE, DT, {}).save(tmp_path / "m.json")
    code = main(["export", str(path), "--out", str(tmp_path / "c"), "--prefix", "x"])
    err = capsys.readouterr().err
    assert code == 2 and why in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "c").exists()
    with pytest.raises(ExportError):
        export_c(FittedModel(model, model.default_params(), RANGE, DT, {}), "x")


def test_a_prefix_that_is_not_a_c_identifier_is_refused(tmp_path, capsys):
    path = fitted("mrpim").save(tmp_path / "m.json")
    code = main(["export", str(path), "--out", str(tmp_path / "c"), "--prefix", "9-x"])
    assert code == 2 and "C identifier" in capsys.readouterr().err
    assert not (tmp_path / "c").exists()
    assert json.loads(path.read_text())["model"] == "mrpim"



@pytest.mark.parametrize("option, named", [(["--max-rate", "1e-300"], "above the limit"),
                                           (["--max-rate", "1e-320"], "above the limit"),
                                           (["--u-start", "nan"], "u_start must be a finite number"),
                                           (["--u-start", "inf"], "u_start must be a finite number"),
                                           (["--u-start", "1e6"], "outside the input limits")])
def test_an_inverse_option_export_cannot_honour_is_refused_in_one_line(tmp_path, capsys, option, named):
    path = fitted("classical-pi").save(tmp_path / "m.json")
    code = main(["export", str(path), "--out", str(tmp_path / "c"), "--prefix", "dea", *option])
    err = capsys.readouterr().err
    assert code == 2 and len(err.strip().splitlines()) == 1 and named in err, err
    assert not (tmp_path / "c").exists()


def test_the_inverse_check_drives_two_samples_a_period_at_least():
    """A model file whose scale time is below two sample times (an edited file) is checked without 0/0."""
    from hysbench.models.export_c import check_inverse
    model = get_model("classical-pi")
    params = dict(model.default_params(), p1=1.0, **{f"a{i}": 0.1 for i in range(1, 14)})
    with np.errstate(all="raise"):
        check = check_inverse(FittedModel(model, params, RANGE, 1.0, {"scale": {"time": 0.5}}))
    assert check.n_samples >= 4 and check.stable

def test_the_inverse_check_passes_a_monotone_p_i_and_names_an_inverse_that_loses_the_input():
    from hysbench.models.export_c import check_inverse
    model = get_model("classical-pi")
    params = dict(model.default_params(), p1=1.0, **{f"a{i}": 0.1 for i in range(1, 14)})
    good = check_inverse(FittedModel(model, params, RANGE, DT, {}))
    assert good.stable and good.max_error < 1e-12 and good.first_sample == -1 and good.max_root <= 1.0
    assert good.inverse == "exact"  # auto: no rate terms
    # Table 2's MRPIM: the sample-by-sample exact inverse through q u'' and the envelopes loses the input
    bad = check_inverse(FittedModel(MRPIM(), MRPIM().preset("paper"), RANGE, DT, {}), inverse="exact")
    assert not bad.stable and bad.max_error > 1e-3 and bad.first_sample > 0
    assert bad.max_root > 1.0 and 0.0 < bad.share_unstable <= 1.0
    assert "not safe as a feedforward" in bad.message("mrpim") and "roots of modulus up to" in bad.message("mrpim")


def test_the_inverse_check_of_the_reference_driven_inverse_is_for_ringing():
    """The DEA's MRPIM (varpro on data/virtual_dea; tests/test_inverse.py): its exact inverse fails the
    check, its reference-driven inverse (approximate: its error is reported) does not ring; Table 2's
    MRPIM, whose rate-free loading falls after a reversal (a1 = -4.37), rings even so."""
    from hysbench.models.export_c import VARIATION_LIMIT, check_inverse
    from test_inverse import DEA_MRPIM
    fit = FittedModel(MRPIM(), DEA_MRPIM, RANGE, DT, {"scale": {"time": 1.0}})
    assert not check_inverse(fit, inverse="exact").stable
    driven = check_inverse(fit)
    assert driven.inverse == "reference-driven" and driven.stable
    assert driven.variation_ratio <= VARIATION_LIMIT and driven.max_error > 1e-3  # approximate, and said so
    assert "approximate by design" in driven.message("mrpim") and "not safe" not in driven.message("mrpim")
    paper = check_inverse(FittedModel(MRPIM(), MRPIM().preset("paper"), RANGE, DT, {}))
    assert not paper.stable and paper.variation_ratio > VARIATION_LIMIT
    assert "it rings, so it is not safe as a feedforward" in paper.message("mrpim")


def test_cli_export_warns_on_stderr_where_the_inverse_check_fails(tmp_path, capsys):
    path = FittedModel(MRPIM(), MRPIM().preset("paper"), RANGE, DT, {}).save(tmp_path / "m.json")
    code = main(["export", str(path), "--out", str(tmp_path / "c"), "--prefix", "dea", "--inverse", "exact"])
    err = capsys.readouterr().err
    assert code == 0 and "warning: mrpim: the inverse does not give back" in err
    header = (tmp_path / "c" / "dea.h").read_text()
    assert "Inverse check: mrpim: the inverse does not give back" in header and "Inverse: exact (" in header
    code = main(["export", str(path), "--out", str(tmp_path / "c2"), "--prefix", "dea"])
    err = capsys.readouterr().err
    assert code == 0 and "warning: mrpim: the reference-driven inverse" in err and "it rings" in err


@needs_cc
def test_fit_save_export_compile_run_reproduces_the_prediction(tmp_path, capsys):
    """The deployment path end to end on the shipped dataset (classical P-I, 5 plays: a quick fit)."""
    model_file = tmp_path / "pi.json"
    assert main(["fit", str(ROOT / "data" / "virtual_dea"), "--model", "classical-pi", "--method", "varpro",
                 "--hyper", "n_operators=5", "--save", str(model_file)]) == 0
    assert main(["export", str(model_file), "--out", str(tmp_path / "c"), "--prefix", "pi"]) == 0
    (tmp_path / "c" / "driver.c").write_text(DRIVER.format(p="pi"))
    exe = tmp_path / "run"
    done = subprocess.run([CC, *FLAGS, "-o", str(exe), str(tmp_path / "c" / "pi.c"), str(tmp_path / "c" / "driver.c"),
                           "-lm"], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    record = load_dataset(ROOT / "data" / "virtual_dea").record("f0.2Hz.npz")
    u = record.u[:50000]
    y_c, _ = run(exe, 0, u)
    assert close(y_c, load_model(model_file).simulate(u), 1e-9)


FAR_DRIVER = """#include <stdio.h>
#include "{p}.h"
/* reads: mode (0 forward, 1 inverse), the sample count to start at, n, then n numbers (nan, inf
   allowed); prints n results, then n_clipped and n_refused */
int main(void)
{{
    {p}_state s;
    int mode;
    long n, i;
    double x, k0;
    if (scanf("%d %lf %ld", &mode, &k0, &n) != 3) return 1;
    {p}_init(&s);
    s.k = k0;
    for (i = 0; i < n; i++) {{
        if (scanf("%lf", &x) != 1) return 1;
        printf("%.17g\\n", mode ? {p}_inverse_step(&s, x) : {p}_step(&s, x));
    }}
    printf("%ld %ld\\n", s.n_clipped, s.n_refused);
    return 0;
}}
"""


@pytest.fixture(scope="module")
def creep_c(tmp_path_factory):
    """mrpim+creep (a time-varying offset) exported with its exact inverse and the export's defaults,
    compiled once for this module with a driver that can start at any sample count."""
    if CC is None:
        pytest.skip("no C compiler (cc, gcc or clang) on PATH")
    folder = tmp_path_factory.mktemp("creep_c")
    fit = fitted("mrpim+creep")
    header, source = export_c(fit, "cr", max_rate=50.0, inverse="exact")
    (folder / "cr.h").write_text(header)
    (folder / "cr.c").write_text(source)
    (folder / "driver.c").write_text(FAR_DRIVER.format(p="cr"))
    exe = folder / "run"
    done = subprocess.run([CC, *FLAGS, "-o", str(exe), str(folder / "cr.c"), str(folder / "driver.c"), "-lm"],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    return fit, exe


def run_far(exe: Path, mode: int, values, k0: float = 0.0):
    text = f"{mode} {k0!r} {len(values)}\n" + "\n".join(repr(float(v)) for v in values) + "\n"
    out = subprocess.run([str(exe)], input=text, capture_output=True, text=True, check=True).stdout.split()
    return np.array([float(v) for v in out[:-2]]), int(out[-2]), int(out[-1])


def test_the_c_inverse_with_the_export_defaults_equals_the_fitted_inverse_stepper_with_its_defaults(creep_c):
    """Neither side is given a reach tolerance: the C inverse and ``FittedModel.inverse_stepper`` take
    the same default (the model file's data scale), so they agree sample by sample, also where the
    exact inverse's recursion amplifies a difference in the last bits."""
    fit, exe = creep_c
    u = drive(3000)
    y = fit.simulate(u)
    python = fit.inverse_stepper(max_rate=50.0, inverse="exact")
    u_py = python.run(y)
    u_c, n_clipped, n_refused = run_far(exe, 1, y)
    assert np.array_equal(u_c, u_py) and n_clipped == python.n_clipped and n_refused == 0


def test_a_non_finite_sample_is_refused_by_the_c_as_by_python_and_the_state_does_not_advance(creep_c):
    """NaN and infinite inputs (the first sample among them) are refused: the C step returns NaN, the C
    inverse its last input (the start input before any), the state does not advance, ``n_refused``
    counts them; every other sample equals the Python stepper's over the finite samples alone (Python
    refuses the others with ModelError, its state unchanged)."""
    fit, exe = creep_c
    u = drive(600)
    bad = {0: np.nan, 200: np.inf, 201: -np.inf, 450: np.nan}
    finite = np.array([k not in bad for k in range(u.size)])
    u_bad = u.copy()
    u_bad[list(bad)] = list(bad.values())
    y_c, _, n_refused = run_far(exe, 0, u_bad)
    assert n_refused == len(bad) and np.all(np.isnan(y_c[~finite]))
    assert np.array_equal(y_c[finite], fit.stepper().run(u_bad[finite]))
    stepper = fit.stepper()
    with pytest.raises(ModelError):
        stepper.step(float("nan"))
    assert stepper.state == fit.stepper().state

    y = fit.simulate(u[finite])
    y_bad = np.full(u.size, np.nan)
    y_bad[finite] = y
    y_bad[list(bad)] = list(bad.values())
    u_c, n_clipped, n_refused = run_far(exe, 1, y_bad)
    python = fit.inverse_stepper(max_rate=50.0, inverse="exact")
    assert np.array_equal(u_c[finite], python.run(y)) and n_clipped == python.n_clipped
    assert n_refused == len(bad)
    held = [python.u_start if k == 0 else u_c[k - 1] for k in sorted(bad)]
    assert np.array_equal(u_c[sorted(bad)], held)


def test_the_c_counts_samples_past_32_bits_and_agrees_with_python_there(creep_c):
    """Started 2^33 samples into a run (beyond a 32-bit long, about 100 days at 1 ms), the C model and
    its inverse equal the Python steppers started at the same sample count."""
    fit, exe = creep_c
    k0 = 2**33
    u = drive(1500)
    stepper = fit.stepper()
    stepper.set_state(dict(stepper.state, k=k0))
    y_c, _, _ = run_far(exe, 0, u, float(k0))
    assert close(y_c, stepper.run(u), 1e-12)
    inverse = fit.inverse_stepper(max_rate=50.0, inverse="exact")
    inverse.set_state(dict(inverse.state, k=k0))
    u_c, n_clipped, _ = run_far(exe, 1, y_c, float(k0))
    assert close(u_c, inverse.run(y_c), 1e-12) and n_clipped == inverse.n_clipped


SANITIZE = ["-fsanitize=address,undefined", "-fno-sanitize-recover=all", "-fno-omit-frame-pointer", "-g"]


def _sanitizers_available(tmp_path: Path) -> bool:
    probe = tmp_path / "probe.c"
    probe.write_text("int main(void) { return 0; }\n")
    done = subprocess.run([CC, *SANITIZE, "-o", str(tmp_path / "probe"), str(probe)], capture_output=True)
    return done.returncode == 0 and subprocess.run([str(tmp_path / "probe")], capture_output=True,
                                                   env={**os.environ, "ASAN_OPTIONS": "detect_leaks=0"}).returncode == 0


@needs_cc
@pytest.mark.parametrize("name", ["classical-pi", "mrpim", "rate-dependent-pi", "mrpim+relaxation", "mrpim+creep",
                                  "mrpim+interference"])
def test_generated_c_runs_clean_under_address_and_undefined_behaviour_sanitizers(tmp_path, name):
    """The exported code, forward and inverse, on a drive with a non-finite sample and inputs and targets
    beyond the limits: no out-of-bounds access, no undefined behaviour (the sanitizers stop the program
    with a report), and the same numbers as the optimised build."""
    if not _sanitizers_available(tmp_path):
        pytest.skip("the C compiler cannot build and run with -fsanitize=address,undefined here")
    fit = fitted(name)
    optimised = build(tmp_path, fit, max_rate=50.0, inverse="exact", guide_time=0.02)
    checked = tmp_path / "checked"
    done = subprocess.run([CC, *FLAGS, *SANITIZE, "-o", str(checked), str(tmp_path / "hm.c"),
                           str(tmp_path / "driver.c"), "-lm"], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    u = np.concatenate([drive(600), [np.nan, 4.0, -3.0], drive(300)])
    y = np.concatenate([fit.simulate(drive(600)), [np.inf, 40.0, -40.0], fit.simulate(drive(300))])
    env = {**os.environ, "ASAN_OPTIONS": "detect_leaks=0:abort_on_error=0", "UBSAN_OPTIONS": "print_stacktrace=1"}
    for mode, values in ((0, u), (1, y)):
        text = f"{mode} {len(values)}\n" + "\n".join(repr(float(v)) for v in values) + "\n"
        result = subprocess.run([str(checked)], input=text, capture_output=True, text=True, env=env)
        assert result.returncode == 0 and "runtime error" not in result.stderr, result.stderr[-2000:]
        assert result.stdout == subprocess.run([str(optimised)], input=text, capture_output=True, text=True,
                                               check=True).stdout

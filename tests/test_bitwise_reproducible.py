"""A result must not depend on whether numba compiled its kernels in this process or loaded them from the
on-disk cache. With fast-math model kernels it did: on a fresh machine the first process's MRPIM outputs
differed in the last bits from every later process's, and the posterior's misspecification test (a chaotic
sampler downstream of them) failed on a fresh machine and passed with a warm cache."""

import os
import subprocess
import sys
import textwrap

SNIPPET = textwrap.dedent("""
    import hashlib
    import numpy as np
    from hysbench.identification.posterior import LogPosterior, simulated_ar1_dataset
    from hysbench.models import get_model

    def digest(*arrays):
        h = hashlib.sha256()
        for a in arrays:
            h.update(np.ascontiguousarray(a, dtype=float).tobytes())
        return h.hexdigest()[:16]

    dt = 0.01
    t = np.arange(0.0, 20.0, dt)
    u = 1.5 - np.cos(2 * np.pi * 0.2 * t) + 0.2 * np.sin(2 * np.pi * 1.3 * t)
    out = {}
    mrpim = get_model("mrpim")
    p = mrpim.preset("paper")
    out["mrpim"] = digest(mrpim.simulate(u, dt, p))
    nl = np.array([[0.03, -0.03], [0.05, 0.01], [-0.02, 0.04]])
    out["regressors"] = digest(mrpim.windowed_regressors_batch(u, dt, nl, slice(500, 2000), (0.5, 2.5)))
    out["inverse"] = digest(mrpim.invert(mrpim.simulate(u, dt, p), dt, p, input_range=(0.5, 2.5)).u)
    extra = {"mrpim+relaxation": {"tau1": 0.7, "c1": 0.4},
             "mrpim+resonance": {"natural_frequency": 6.0, "damping_ratio": 0.2}}
    for name in ("rate-dependent-pi", "mrpim+relaxation", "mrpim+resonance"):
        m = get_model(name)
        q = m.preset("default") if name == "rate-dependent-pi" else {**p, **extra[name]}
        out[name] = digest(m.simulate(u, dt, q))
    small = get_model("mrpim", n_operators=4, poly_order=2)
    truth = {"gamma": 0.03, "lambda": -0.03, "p1": 3.2, "p2": 1.0, "q": 0.02, "a1": -4.7, "a2": 0.8, "a3": 0.3,
             "a4": 2.5, "offset": 0.4}
    ds = simulated_ar1_dataset(small, truth, sigma=0.02, phi=0.9, seed=1, n_periods=2, dt=0.02,
                               frequencies=(0.1, 0.4, 1.0))
    post = LogPosterior(small, ds.identification, noise="ar1")
    X = np.array([post.coords([0.03 + 0.004 * k, -0.03 + 0.003 * k], 0.02, 0.9) for k in range(8)])
    out["log_posterior"] = digest(post.log_prob(X))
    print(sorted(out.items()))
""")


def _run(cache_dir) -> str:
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache_dir)}
    done = subprocess.run([sys.executable, "-c", SNIPPET], env=env, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    return done.stdout.strip().splitlines()[-1]


def test_kernels_give_the_same_bits_compiled_or_loaded_from_the_cache(tmp_path):
    compiled = _run(tmp_path)  # an empty cache: every kernel compiled in this process
    assert any(tmp_path.rglob("*.nbi")), "the first run should have written numba's cache"
    loaded = _run(tmp_path)  # the same kernels loaded from the cache
    assert compiled == loaded

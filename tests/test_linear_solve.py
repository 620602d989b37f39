"""The one column-scaled linear least-squares solve (identification/linear.py) against obvious references."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hysbench.identification.linear import (column_norms, scaled_lstsq, solve_spectrum, spectrum_from_gram,
                                            spectrum_from_qr)


def _design(seed: int, n: int = 60, k: int = 5) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    scales = 10.0 ** rng.uniform(-4, 4, k)  # columns over eight decades
    return rng.normal(size=(n, k)) * scales, rng.normal(size=n)


def _pinv_reference(A, b, rcond):
    """Obvious reference: explicit SVD pseudo-inverse of the column-scaled matrix."""
    d = np.linalg.norm(A, axis=0)
    d[d == 0] = 1.0
    U, s, Vt = np.linalg.svd(A / d, full_matrices=False)
    keep = s > rcond * s[0]
    return (Vt[keep].T @ ((U[:, keep].T @ b) / s[keep].reshape(-1, *([1] * (b.ndim - 1))))) / (
        d[:, None] if b.ndim == 2 else d)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10_000))
def test_full_rank_matches_the_svd_reference(seed):
    A, b = _design(seed)
    x = scaled_lstsq(A, b)
    ref = _pinv_reference(A, b, 1e-10)
    np.testing.assert_allclose(x * column_norms(A), ref * column_norms(A), rtol=1e-9, atol=1e-12)


def test_rank_deficient_gives_the_minimum_norm_solution_in_scaled_coordinates():
    A, b = _design(1)
    A = np.column_stack([A, 3.0 * A[:, 1], np.zeros(A.shape[0])])  # a repeated direction and a zero column
    x = scaled_lstsq(A, b)
    ref = _pinv_reference(A, b, 1e-10)
    np.testing.assert_allclose(x, ref, rtol=1e-8, atol=1e-12)
    assert x[-1] == 0.0
    # the residual is the least-squares one: orthogonal to every column
    assert np.max(np.abs((A / column_norms(A)).T @ (b - A @ x))) < 1e-10


def test_several_right_hand_sides_equal_one_at_a_time():
    A, b = _design(2)
    B = np.column_stack([b, 2 * b + 1, np.sin(np.arange(b.size))])
    X = scaled_lstsq(A, B)
    for j in range(B.shape[1]):
        np.testing.assert_allclose(X[:, j], scaled_lstsq(A, B[:, j]), rtol=1e-12, atol=1e-14)


def test_ridge_above_max_condition_is_the_explicit_ridge_formula():
    A, b = _design(3)
    A[:, 4] = A[:, 3] * (A[0, 4] / A[0, 3]) + 1e-7 * np.abs(A[:, 3]).max() * np.random.default_rng(0).normal(
        size=A.shape[0])  # nearly collinear columns
    D = column_norms(A)
    As = A / D
    spec = solve_spectrum(*spectrum_from_qr(As, b), max_condition=1e3)
    assert spec.regularised and spec.condition_number > 1e3
    s_max = np.linalg.svd(As, compute_uv=False)[0]
    alpha2 = (s_max / 1e3) ** 2
    ref = np.linalg.solve(As.T @ As + alpha2 * np.eye(As.shape[1]), As.T @ b)
    np.testing.assert_allclose(spec.x_scaled, ref, rtol=1e-7)


def test_gram_and_qr_spectra_agree_when_well_conditioned():
    A, b = _design(4)
    As = A / column_norms(A)
    fast = solve_spectrum(*spectrum_from_gram(As.T @ As, As.T @ b))
    accurate = solve_spectrum(*spectrum_from_qr(As, b))
    np.testing.assert_allclose(fast.x_scaled, accurate.x_scaled, rtol=1e-9)
    assert fast.condition_number == pytest.approx(accurate.condition_number, rel=1e-6)


def test_non_finite_input_is_refused():
    A, b = _design(5)
    A[3, 2] = np.nan
    with pytest.raises(ValueError, match="not finite"):
        scaled_lstsq(A, b)


@pytest.mark.parametrize("shape", [(400, 6, 1), (300, 4, 3), (5, 8, 1), (7, 3, 2)])
def test_qr_triangle_is_scipys_triangle_of_the_scaled_matrix(shape):
    from hysbench.identification.linear import qr_triangle
    import scipy.linalg
    N, n, m = shape
    rng = np.random.default_rng(N + n)
    A = rng.normal(size=(N, n)) * 10.0 ** rng.uniform(-4, 4, n)
    b = rng.normal(size=(N, m))
    D = column_norms(A)
    reference = scipy.linalg.qr(np.column_stack([A / D, b]), mode="r")[0][: n + m]
    np.testing.assert_array_equal(qr_triangle(A, b, D), reference)
    np.testing.assert_array_equal(qr_triangle(A / D, b), reference)


# --- directions the data do not determine ------------------------------------------------------------------
def _dependent_reference(A, order, tol):
    """Slow reference: walk the columns in priority order, keep one when it raises the numerical rank of the
    kept columns (singular values of the column-scaled kept set, relative to the whole design's largest)."""
    As = A / np.linalg.norm(A, axis=0)
    s_max = np.linalg.svd(As, compute_uv=False)[0]
    kept, dependent = [], np.zeros(A.shape[1], dtype=bool)
    for j in order:
        s = np.linalg.svd(As[:, kept + [j]], compute_uv=False)
        if s[-1] > tol * s_max:
            kept.append(j)
        else:
            dependent[j] = True
    return dependent


def _with_constant_and_duplicate(seed):
    A, b = _design(seed, n=80, k=5)
    A[:, 0] = 1.0  # an intercept
    A = np.column_stack([A, np.full(A.shape[0], 0.385), 2.5 * A[:, 2]])  # constant column, repeated column
    return A, b


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_dependent_columns_match_the_rank_walk(seed):
    from hysbench.identification.linear import UNDETERMINED_TOL, dependent_columns
    A, _ = _with_constant_and_duplicate(seed)
    for order in (np.arange(A.shape[1]), np.arange(A.shape[1])[::-1], np.random.default_rng(seed).permutation(7)):
        got = dependent_columns(A, order)
        np.testing.assert_array_equal(got, _dependent_reference(A, list(order), UNDETERMINED_TOL))
        assert got.sum() == 2


def test_undetermined_count_from_the_spectrum():
    from hysbench.identification.linear import undetermined_count
    A, b = _with_constant_and_duplicate(3)
    ev, _, _ = spectrum_from_qr(A, b, column_scale=column_norms(A))
    assert undetermined_count(ev) == 2
    A2, b2 = _design(3)
    assert undetermined_count(spectrum_from_qr(A2, b2, column_scale=column_norms(A2))[0]) == 0
    # singular values 1, 1e-7, 1e-11 of s_max: only the last is below UNDETERMINED_TOL = 1e-10
    assert undetermined_count(np.array([1.0, 1e-14, 1e-22])) == 1


class _Stub:
    """The few attributes SeparableProblem's linear solve reads, for a plain design (one record, weight 1)."""

    def __init__(self, A, y, names, output_scale=1.0, lower=None):
        from types import SimpleNamespace
        from hysbench.identification.varpro import SeparableProblem
        self.sep = object.__new__(SeparableProblem)
        self.sep.problem = SimpleNamespace(row_weights=[1.0], n_nonfinite=0)
        self.sep.linear_names = tuple(names)
        # as SeparableProblem.__init__: data and linear bounds divided by the output scale
        self.sep.output_scale = output_scale
        lower = np.full(len(names), -np.inf) if lower is None else np.asarray(lower, dtype=float)
        self.sep.lin_lower = lower / output_scale
        self.sep.lin_upper = np.full(len(names), np.inf)
        self.sep._ys = [y / output_scale]
        self.sep.b = y / output_scale
        self.sep.max_condition = 1e6


def test_varpro_solve_fixes_the_constant_and_repeated_columns_at_zero():
    A, b = _with_constant_and_duplicate(4)
    names = ["offset", "a1", "a2", "a3", "a4", "a12", "a2_copy"]
    sep = _Stub(A, b, names).sep
    sol = sep.solve_blocks([A], accurate=True)
    # the constant column repeats the intercept, the copy repeats a2: both fixed, the rest is plain lstsq
    assert sol.fixed == {"a12": 0.0, "a2_copy": 0.0}
    keep = [0, 1, 2, 3, 4]
    ref = np.linalg.lstsq(A[:, keep], b, rcond=None)[0]
    np.testing.assert_allclose(sol.linear[keep], ref, rtol=1e-9, atol=1e-12)
    assert sol.linear[5] == 0.0 and sol.linear[6] == 0.0
    assert sol.condition_number_full > 1e12 and sol.condition_number < 1e9
    # the residual is the least-squares one of the full design
    full = np.linalg.lstsq(A, b, rcond=None)[0]
    assert sol.fitness == pytest.approx(float(np.sum((A @ full - b) ** 2)), rel=1e-9)


def test_varpro_solve_with_an_output_scale_returns_unscaled_parameters_and_fixed_values():
    A, b = _with_constant_and_duplicate(3)
    names = ["offset", "a1", "a2", "a3", "a4", "a12", "a2_copy"]
    lower = np.full(len(names), -np.inf)
    lower[5] = 0.25  # the constant column's weight cannot be 0: it is fixed at its bound nearest 0
    plain = _Stub(A, b, names, lower=lower).sep.solve_blocks([A], accurate=True)
    scaled = _Stub(A, b, names, output_scale=2.0 ** 40, lower=lower).sep.solve_blocks([A], accurate=True)
    assert plain.fixed == {"a12": 0.25, "a2_copy": 0.0}
    assert scaled.fixed == plain.fixed
    np.testing.assert_allclose(scaled.linear, plain.linear, rtol=1e-12)
    assert scaled.fitness == pytest.approx(plain.fitness, rel=1e-12)


def test_varpro_solve_of_a_determined_design_is_unchanged_bit_for_bit():
    A, b = _design(5)
    sep = _Stub(A, b, [f"c{i}" for i in range(A.shape[1])]).sep
    sol = sep.solve_blocks([A], accurate=True)
    assert sol.fixed == {} and sol.n_undetermined == 0
    D = column_norms(A)
    expected = solve_spectrum(*spectrum_from_qr(A, b, column_scale=D), 1e6).x_scaled / D
    np.testing.assert_array_equal(sol.linear, expected)


def test_a_nearly_constant_column_next_to_the_intercept_is_fixed_and_kept_without_one():
    from hysbench.identification.varpro import NEAR_CONSTANT
    A, b = _design(6, n=80, k=4)
    A[:, 3] = 1.0
    wiggle = 0.385 + 0.3 * NEAR_CONSTANT * 0.385 * np.sin(np.arange(A.shape[0]))  # spread 0.6 NEAR_CONSTANT of its level
    A = np.column_stack([A, wiggle])
    sep = _Stub(A, b, ["c0", "c1", "c2", "offset", "a12"]).sep
    for accurate in (True, False):
        sol = sep.solve_blocks([A], accurate=accurate)
        assert sol.fixed == {"a12": 0.0} and sol.nearly_constant == ["a12"]
        np.testing.assert_allclose(sol.linear[:4], np.linalg.lstsq(A[:, :4], b, rcond=None)[0], rtol=1e-8)
    without_intercept = np.column_stack([A[:, :3], wiggle])
    sep = _Stub(without_intercept, b, ["c0", "c1", "c2", "a12"]).sep
    sol = sep.solve_blocks([without_intercept], accurate=True)
    assert sol.fixed == {} and sol.linear[3] != 0.0


def test_a_direction_the_bounds_pin_down_is_not_fixed():
    rng = np.random.default_rng(7)
    c1, c2 = rng.normal(size=(2, 60))
    A = np.column_stack([c1, c2, c1 - c2])  # exactly dependent: c3 = c1 - c2
    b = c1 - c2  # reached only through c3 when every weight is non-negative
    sep = _Stub(A, b, ["w1", "w2", "w3"]).sep
    sep.lin_lower = np.zeros(3)
    sol = sep.solve_blocks([A], accurate=True)
    assert sol.fixed == {} and sol.fitness < 1e-20 and sol.linear[2] > 0.99
    sep.lin_lower = np.full(3, -np.inf)  # unbounded: the same direction is fixed at no cost
    assert sep.solve_blocks([A], accurate=True).fixed == {"w3": 0.0}

"""The banded least-squares system and the fast solves against straightforward ones."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from adaproj_edge.errors import WarpError
from adaproj_edge.geometry.analytic import simulate_surface
from adaproj_edge.warp import reference, solve
from adaproj_edge.warp.anderson import Anderson
from adaproj_edge.warp.engine import WarpSettings
from adaproj_edge.warp.mesh import MeshGeometry
from adaproj_edge.warp.planner import compute_warp
from adaproj_edge.warp.system import BandedLeastSquares, ComplexLeastSquares
from adaproj_edge.warp.warpmap import Grid


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31), n=st.integers(3, 30), k=st.integers(1, 4), sparse=st.booleans())
def test_banded_solve_matches_dense_least_squares(seed: int, n: int, k: int, sparse: bool) -> None:
    rng = np.random.default_rng(seed)
    m = 3 * n
    # rows touching nearby unknowns (a band), plus one identity row each (full rank)
    cols = np.full((m + n, k), -1)
    vals = np.zeros((m + n, k))
    for r in range(m):
        start = int(rng.integers(0, n))
        idx = rng.choice(np.arange(start, min(n, start + 5)), size=min(k, n - start), replace=False)
        cols[r, : idx.size] = idx
        vals[r, : idx.size] = rng.normal(size=idx.size)
    cols[m:, 0] = np.arange(n)
    vals[m:, 0] = 1.0
    rhs = rng.normal(size=m + n)
    weights = rng.uniform(0.1, 3.0, size=m + n)
    fixed = np.zeros(n, dtype=bool)
    fixed[int(rng.integers(0, n))] = True
    x_fixed = np.where(fixed, rng.normal(size=n), 0.0)
    x = BandedLeastSquares(cols, n, fixed, sparse).solve(vals, rhs, weights, x_fixed)
    # the same problem, dense
    a = np.zeros((m + n, n))
    for r in range(m + n):
        for c, v in zip(cols[r], vals[r], strict=True):
            if c >= 0:
                a[r, c] += v
    sw = np.sqrt(weights)
    b = rhs - a[:, fixed] @ x_fixed[fixed]
    xd, *_ = np.linalg.lstsq(sw[:, None] * a[:, ~fixed], sw * b, rcond=None)
    # normal equations against QR: they differ by ~cond(A)^2 eps; the identity rows (and
    # weights >= 0.1) keep cond(A) below ~100, so ~1e-12, on any CPU or BLAS
    np.testing.assert_allclose(x[~fixed], xd, rtol=1e-7, atol=1e-9)
    assert np.all(x[fixed] == x_fixed[fixed])  # copied, not solved: exact


# The fast solves (banded Cholesky of the normal equations) against the reference's
# (sparse LU, terms assembled one by one), in the normalised content domain (~1): they
# agree to ~1e-13 here; other CPUs and BLAS builds round differently, by up to cond x eps
# of the normal matrix. 1e-7 holds on any of them and is still 1e-4 px of a 1000-px
# content, where a wrong term or weight moves vertices by far more than 1e-3.
SOLVE_ATOL = 1e-7


@pytest.fixture(scope="module")
def mesh() -> MeshGeometry:
    return MeshGeometry.build(simulate_surface("bowl", step=8), Grid(12, 9))


def test_conformal_and_content_free_match_the_reference(mesh: MeshGeometry) -> None:
    v_fast = solve.solve_conformal(mesh)
    v_ref = reference.solve_conformal_reference(mesh)
    np.testing.assert_allclose(v_fast, v_ref, atol=SOLVE_ATOL)
    vf, sf = solve.solve_content_free(mesh, v_fast, 1.0)
    vr, sr = reference.solve_content_free_reference(mesh, v_fast, 1.0)
    np.testing.assert_allclose(vf, vr, atol=SOLVE_ATOL)
    np.testing.assert_allclose(sf, sr, atol=SOLVE_ATOL)


def test_content_aware_step_matches_the_reference(mesh: MeshGeometry) -> None:
    v, _ = solve.solve_content_free(mesh, solve.solve_conformal(mesh), 1.0)
    w = (np.arange(mesh.n) % 4 == 0).astype(float)
    fast = solve.ContentAwareSolver(mesh).step(v, w)
    ref = reference.ReferenceContentAwareSolver(mesh).step(v, w)
    np.testing.assert_allclose(fast, ref, atol=SOLVE_ATOL)


def test_whole_warp_matches_the_reference_backend() -> None:
    surface = simulate_surface("sphere-convex", step=8)
    cmap = np.zeros((10, 16), np.float32)
    cmap[3:8, 2:7] = 1.0
    settings = WarpSettings(grid=Grid(10, 8))
    fast = compute_warp(surface, (320, 200), cmap, settings)
    ref = compute_warp(surface, (320, 200), cmap, settings, reference.REFERENCE)
    assert fast.meta["iterations"] == ref.meta["iterations"] > 0
    # content pixels after 5 alternation steps: ~1e-10 px here; 1e-4 px on any machine
    np.testing.assert_allclose(fast.image_xy, ref.image_xy, atol=1e-4, equal_nan=True)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31), n=st.integers(3, 30), k=st.integers(1, 4), pin=st.booleans())
def test_complex_solve_matches_dense_least_squares(seed: int, n: int, k: int, pin: bool) -> None:
    rng = np.random.default_rng(seed)
    m = 3 * n
    cols = np.full((m + n, k), -1)
    vals = np.zeros((m + n, k), np.complex128)
    for r in range(m):
        start = int(rng.integers(0, n))
        idx = rng.choice(np.arange(start, min(n, start + 5)), size=min(k, n - start), replace=False)
        cols[r, : idx.size] = idx
        vals[r, : idx.size] = rng.normal(size=idx.size) + 1j * rng.normal(size=idx.size)
    if k > 1:  # one row with an unknown twice
        cols[0, :2] = cols[0, 0]
    cols[m:, 0] = np.arange(n)
    vals[m:, 0] = 1.0
    const = rng.normal(size=m + n) + 1j * rng.normal(size=m + n)
    weights = rng.uniform(0.1, 3.0, size=m + n)
    fixed = np.zeros(n, dtype=bool)
    fixed[int(rng.integers(0, n))] = pin
    z_fixed = np.where(fixed, rng.normal(size=n) + 1j * rng.normal(size=n), 0.0)
    system = ComplexLeastSquares(cols, n, fixed)
    system.factor(vals, weights)
    z = system.solve(const, z_fixed)
    a = np.zeros((m + n, n), np.complex128)
    for r in range(m + n):
        for c, v in zip(cols[r], vals[r], strict=True):
            if c >= 0:
                a[r, c] += v
    sw = np.sqrt(weights)
    b = const - a[:, fixed] @ z_fixed[fixed]
    zd, *_ = np.linalg.lstsq(sw[:, None] * a[:, ~fixed], sw * b, rcond=None)
    np.testing.assert_allclose(z[~fixed], zd, rtol=1e-7, atol=1e-9)
    assert np.all(z[fixed] == z_fixed[fixed])
    # the same factorisation serves another right-hand side
    z2 = system.solve(2 * const, z_fixed)
    zd2, *_ = np.linalg.lstsq(
        sw[:, None] * a[:, ~fixed], sw * (2 * const - (const - b)), rcond=None
    )
    np.testing.assert_allclose(z2[~fixed], zd2, rtol=1e-7, atol=1e-9)
    # rows whose constant is zero may be skipped on the caller's word (zero_rows)
    head = int(rng.integers(0, m + n + 1))
    c3 = np.where(np.arange(m + n) < head, 0.0, const)
    z3 = system.solve(c3, z_fixed)  # (the weights doubled: the same minimiser)
    # the right side summed over fewer terms (the same but for zeros: rounded alike, or
    # to a few ulps where the sums are vectorised otherwise), through the same factor: off
    # by at most a few ulps times the condition of the normal matrix; a row wrongly
    # skipped or read changes the minimiser by far more
    cond = np.linalg.cond(sw[:, None] * a[:, ~fixed]) ** 2
    tol = 64 * np.finfo(float).eps * cond * float(np.abs(z3).max())
    np.testing.assert_allclose(system.solve(c3, z_fixed, zero_rows=head), z3, rtol=0, atol=tol)
    # and when the first solve after a factorisation skips them, a later one does not
    system.factor(vals, 2.0 * weights)
    skipped = system.solve(c3, z_fixed, zero_rows=head)
    np.testing.assert_allclose(system.solve(c3, z_fixed), skipped, rtol=0, atol=tol)
    np.testing.assert_allclose(skipped[~fixed], z3[~fixed], rtol=1e-7, atol=1e-9)


def test_anderson_reaches_the_same_fixed_point_sooner() -> None:
    rng = np.random.default_rng(2)
    q, _ = np.linalg.qr(rng.normal(size=(30, 30)))
    a = q @ np.diag(np.linspace(0.2, 0.9, 30)) @ q.T  # a contraction, rate 0.9
    b = rng.normal(size=30)
    fixed = np.linalg.solve(np.eye(30) - a, b)

    def steps(accel: Anderson | None) -> int:
        x = np.zeros(30)
        for k in range(1, 500):
            g = a @ x + b
            if np.linalg.norm(g - x) < 1e-10:
                np.testing.assert_allclose(x, fixed, atol=1e-8)
                return k
            x = g if accel is None else accel.next(x, g)
        raise AssertionError("no convergence")

    assert steps(Anderson(5)) < 0.5 * steps(None)


def test_the_alternation_stops_by_its_convergence_test() -> None:
    # a real convergence test: on a dome with an off-centre subject the alternation ends
    # well before its cap, with its last plain step below the tolerance
    surface = simulate_surface("sphere-convex", step=4)
    cmap = np.zeros((50, 80), np.float32)
    cmap[10:40, 10:35] = 1.0
    warp = compute_warp(surface, (640, 400), cmap, WarpSettings(max_iterations=50))
    assert 0 < warp.meta["iterations"] < 25
    assert warp.meta["guard"]["choice"] == "content-aware"


def test_the_paper_as_written_reference() -> None:
    surface = simulate_surface("bowl", step=8)
    grid = Grid(12, 9)
    # its own mesh set-up agrees with the engine's where there is no crease
    mine, engine_mesh = reference.paper_mesh(surface, grid), MeshGeometry.build(surface, grid)
    assert mine.n == engine_mesh.n and mine.tris.shape == engine_mesh.tris.shape
    np.testing.assert_allclose(np.sort(mine.lengths), np.sort(engine_mesh.lengths), rtol=1e-12)
    cmap = np.zeros((10, 16), np.float32)
    cmap[2:8, 3:9] = 1.0
    settings = WarpSettings(grid=grid, alternation="paper")
    warp = compute_warp(surface, (320, 200), cmap, settings, reference.REFERENCE)
    assert warp.meta["alternation"] == "paper" and 1 <= warp.meta["iterations"] <= 10
    xy = warp.image_xy.reshape(-1, 2)
    assert np.isfinite(xy).all()
    # the content is the maximal inscribed rectangle: the warp covers all of it
    assert xy[:, 0].min() <= -0.5 + 1e-6 and xy[:, 0].max() >= 319.5 - 1e-6
    assert xy[:, 1].min() <= -0.5 + 1e-6 and xy[:, 1].max() >= 199.5 - 1e-6


def test_a_singular_system_is_a_warp_error() -> None:
    # unknown 2 appears in no row: its normal equation is 0 = 0 (LAPACK's factorisation
    # reports it, called directly by both systems)
    cols = np.array([[0, 1], [1, -1], [0, -1]])
    vals = np.array([[1.0, -1.0], [1.0, 0.0], [1.0, 0.0]], dtype=np.complex128)
    system = ComplexLeastSquares(cols, 3, np.zeros(3, dtype=bool))
    with pytest.raises(WarpError):
        system.factor(vals, np.ones(3))
    real = BandedLeastSquares(cols, 3, np.zeros(3, dtype=bool))
    with pytest.raises(WarpError, match="singular"):
        real.solve(vals.real, np.ones(3), np.ones(3), np.zeros(3))

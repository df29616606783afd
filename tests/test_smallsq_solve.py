"""The small damped solves of smallsq.damped_step: the same numbers as np.linalg.solve (LAPACK's dgesv)."""
import numpy as np

from frictid.identify import smallsq


def _systems(seed, k, count):
    rng = np.random.default_rng(seed)
    for _ in range(count):
        n = int(rng.integers(k, 40))
        J = rng.normal(size=(n, k)) * 10 ** rng.uniform(-4, 4, size=k)
        if k == 2 and rng.random() < 0.2:  # nearly parallel columns
            J[:, 1] = J[:, 0] * rng.uniform(0.5, 2) + 1e-9 * rng.normal(size=n)
        JtJ = J.T @ J
        damp = np.diag(JtJ) * 10 ** rng.uniform(-8, 1) * rng.uniform(0, 1, size=k)
        yield J, JtJ, damp, rng.normal(size=k) * 10 ** rng.uniform(-3, 3)


def test_one_and_two_unknowns_bit_for_bit_as_lapack():
    for k, seed in ((1, 3), (2, 4)):
        for J, JtJ, damp, g in _systems(seed, k, 3000):
            got = smallsq.damped_step(JtJ, J, np.zeros(J.shape[0]), g, damp)
            want = np.linalg.solve(JtJ + np.diag(damp), -g)
            assert got.tobytes() == want.tobytes(), (JtJ, damp, g, got, want)


def test_singular_and_non_finite_fall_back_to_least_squares():
    J = np.array([[1.0, 2.0], [2.0, 4.0], [3.0, 6.0]])
    JtJ, r = J.T @ J, np.array([1.0, 0.0, -1.0])
    assert smallsq._solve_small(JtJ, np.zeros(2), J.T @ r) is None  # exactly singular
    dz = smallsq.damped_step(JtJ, J, r, J.T @ r, np.zeros(2))
    want = np.linalg.lstsq(np.vstack([J, np.zeros((2, 2))]), np.concatenate([-r, np.zeros(2)]), rcond=None)[0]
    assert np.allclose(dz, want)
    assert smallsq._solve_small(np.array([[np.nan]]), np.zeros(1), np.ones(1)) is None
    assert smallsq._solve_small(np.array([[0.0]]), np.zeros(1), np.ones(1)) is None

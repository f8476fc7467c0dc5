"""
The posterior of an estimate against the inverse information in exact rational arithmetic.

An estimate's covariance comes from the SVD of the whitened derivative J that its search
made (and kept with the forward solve, for the next estimate at that solve), its
sensitivity likewise. Here the same J is made from the estimate's own forward solve and
(J^T J)^-1 computed in fractions: no rounding but J's own, so the estimate must match it to
the rounding of an SVD (the machine epsilon times J's condition number), also when
estimates at one solve alternate between pose covariances (each whitening has its own
derivative).
"""

from fractions import Fraction
from typing import List, Optional

from cdr_translator import TranslatorSolver
from cdr_translator.estimation import measured_target, observability, TRANSLATOR_WRENCH_LABELS
from cdr_translator.estimation.problem import Derivative
import numpy as np
import pytest

#: Agreement with the exact posterior, relative to its largest entry (of each row for the
#: sensitivity), per unit of J's condition number: the rounding of a backward-stable SVD.
ROUNDING = 16.0 * np.finfo(float).eps

#: Pose covariances: a tracker's (0.2 mm, 0.1 deg) and a correlated, tighter one.
TRACKER = np.diag([4e-8] * 3 + [np.radians(0.1) ** 2] * 3)
CORRELATED = 0.25 * TRACKER + 1e-9 * np.outer([1.0, -0.5, 0.2, 0.0, 0.0, 0.0],
                                              [1.0, -0.5, 0.2, 0.0, 0.0, 0.0])


Exact = List[List[Fraction]]


def exact(matrix: np.ndarray) -> Exact:
    """Return a float matrix as fractions (exactly its values)."""
    return [[Fraction(float(value)) for value in row] for row in matrix]


def product(left: Exact, right: Exact) -> Exact:
    """Return the exact matrix product."""
    return [[sum(a * b for a, b in zip(row, column)) for column in zip(*right)] for row in left]


def transposed(matrix: Exact) -> Exact:
    """Return the transpose."""
    return [list(column) for column in zip(*matrix)]


def inverse(matrix: Exact) -> Exact:
    """Invert a nonsingular matrix of fractions by Gauss-Jordan elimination, exactly."""
    size = len(matrix)
    rows = [list(row) + [Fraction(int(i == j)) for j in range(size)]
            for i, row in enumerate(matrix)]
    for column in range(size):
        pivot = max(range(column, size), key=lambda row: abs(rows[row][column]))
        rows[column], rows[pivot] = rows[pivot], rows[column]
        head = rows[column][column]
        rows[column] = [value / head for value in rows[column]]
        for row in range(size):
            if row != column and rows[row][column] != 0:
                factor = rows[row][column]
                rows[row] = [a - factor * b for a, b in zip(rows[row], rows[column])]
    return [row[size:] for row in rows]


def rounded(matrix: Exact) -> np.ndarray:
    """Return the nearest floats."""
    return np.array([[float(value) for value in row] for row in matrix])


def check_posterior(estimate, position, quaternion, covariance: Optional[np.ndarray],
                    length: float) -> None:
    """Assert the estimate's covariance and sensitivity are the exact ones at its solve."""
    target = measured_target(position, quaternion, covariance, None, None, length)
    free = list(target.free)
    derivative = Derivative.made(target, estimate.solution.compliance.matrix)
    # in SI units: J_SI = J S_f^-1, so (J_SI^T J_SI)^-1 = S_f (J^T J)^-1 S_f
    scale = np.diag(1.0 / target.scale[free])
    jacobian = product(exact(derivative.jacobian), exact(scale))
    posterior = inverse(product(transposed(jacobian), jacobian))
    expected = rounded(posterior)
    tolerance = ROUNDING * derivative.values[0] / derivative.values[-1]
    if covariance is None:
        assert estimate.covariance is None
    else:
        error = np.abs(estimate.covariance[np.ix_(free, free)] - expected).max()
        assert error <= tolerance * np.abs(expected).max()
    # d estimate / d pose = (J^T J)^-1 J_pose^T W
    pose_jacobian = transposed(jacobian[:len(target.rows)])
    sensitivity = rounded(product(product(posterior, pose_jacobian),
                                  exact(target.weights.pose)))
    error = np.abs(estimate.sensitivity[free] - sensitivity).max(axis=1)
    assert np.all(error <= tolerance * np.abs(sensitivity).max(axis=1))


@pytest.mark.parametrize('wrench', [[2.0, -1.0, 0.5, 0.05, -0.03, 0.02],
                                    [-0.5, 3.0, -2.0, 0.1, 0.02, -0.2]])
def test_the_posterior_is_the_exact_inverse_information(solver, params, wrench):
    """Noisy poses under alternating covariances, and an exact pose, each twice."""
    solved = solver.solve(wrench[:3], wrench[3:])
    assert solved.converged
    estimator = TranslatorSolver(params)
    rng = np.random.default_rng(7)
    length = params.stack_height
    poses = []
    for covariance in (TRACKER, CORRELATED, TRACKER, None, CORRELATED):
        # an exact pose is matched exactly: the solved one itself
        noise = 0.0 if covariance is None else rng.normal(0.0, 1e-4, 3)
        position = solved.end_disk_position + noise
        for repeat in range(2):  # the same pose again: no forward solve, the kept derivative
            estimate = estimator.estimate_wrench(position, solved.end_disk_quaternion_xyzw,
                                                 pose_covariance=covariance)
            assert estimate.converged, estimate.message
            check_posterior(estimate, position, solved.end_disk_quaternion_xyzw, covariance,
                            length)
            poses.append(estimate.solves)
    assert 0 in poses  # some estimates reused a solve (and its derivative)


def test_estimates_at_one_solve_do_not_share_their_conditioning(solver, params):
    """The conditioning made once per derivative comes to each estimate as its own copy."""
    solved = solver.solve([1.0, 2.0, -1.0], [0.02, 0.0, 0.05])
    estimator = TranslatorSolver(params)
    pose = solved.end_disk_position, solved.end_disk_quaternion_xyzw
    first = estimator.estimate_wrench(*pose, pose_covariance=TRACKER)
    assert first.conditioning, 'the axial force is poorly observable'
    expected = [dict(direction, direction=list(direction['direction']))
                for direction in first.conditioning]
    first.conditioning[0]['label'] = 'changed'
    first.conditioning[0]['direction'][0] = 1e9
    second = estimator.estimate_wrench(*pose, pose_covariance=TRACKER)
    assert second.solves == 0
    assert second.conditioning == expected


def test_estimates_at_one_solve_share_the_conditioning_not_its_spreads(solver, params):
    """Under another pose covariance at the same solve: observability() with its posterior."""
    solved = solver.solve([1.0, 2.0, -1.0], [0.02, 0.0, 0.05])
    estimator = TranslatorSolver(params)
    pose = solved.end_disk_position, solved.end_disk_quaternion_xyzw
    first = estimator.estimate_wrench(*pose, pose_covariance=TRACKER)
    second = estimator.estimate_wrench(*pose, pose_covariance=CORRELATED)
    assert second.solves == 0 and second.solution is first.solution
    compliance = second.solution.compliance
    for estimate in (first, second):
        condition, directions = observability(
            compliance.matrix, range(6), range(6), params.stack_height,
            TRANSLATOR_WRENCH_LABELS, estimate.covariance, compliance)
        assert estimate.condition_number == condition
        assert estimate.conditioning == directions
    spreads = [[direction['standard_deviation'] for direction in estimate.conditioning]
               for estimate in (first, second)]
    assert spreads[0] != spreads[1]  # the posterior's: the covariances differ

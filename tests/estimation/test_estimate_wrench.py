"""
TranslatorSolver.estimate_wrench: the wrench back from the pose it gives, with its covariance.

The round trips solve seeded random wrenches inside the node's range where the translator
stays stable (|f| components up to 8 N, against the 29.3 N axial buckling load; moments up
to 0.3 N m, torsion 0.5 N m), take the end-disk pose and estimate the wrench back. The
coverage test adds seeded noise of a known covariance to one pose: the reported covariance's
95 % ellipsoid must hold the true wrench in 90-99 % of 200 trials (chi-square, 6 and 3
degrees of freedom). The noise (0.3 um, 3e-6 rad, correlated) keeps the estimate in its
linear range, the axial force's standard deviation under 1 N; with a diagonal covariance
of 3 um and 3e-5 rad the coverage measured 85 % (the stiffness changes over the spread of
8 N in the axial force).
"""

import json
import math

from cdr_translator import TranslatorSolver, WrenchEstimate
from cdr_translator.estimation import CONDITION_LIMIT
import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from scipy.stats import chi2

#: Relative accuracy of estimate(solve(w)) = w, in the scaled wrench norm.
ROUND_TRIP = 1e-6


@pytest.fixture(scope='module')
def estimator(params):
    """Estimate the wrenches (a solver of its own: its warm starts follow the estimates)."""
    return TranslatorSolver(params)


def scaled_error(estimated: np.ndarray, true: np.ndarray, length: float) -> float:
    """Return |estimated - true| / |true| with moments as forces at ``length`` (N)."""
    scale = np.repeat([1.0, length], 3)
    return float(np.linalg.norm((estimated - true) / scale) / np.linalg.norm(true / scale))


def random_wrenches(seed: int, count: int, moments: bool = True) -> np.ndarray:
    """Seeded wrenches inside the stable range (module docstring)."""
    rng = np.random.default_rng(seed)
    bounds = np.array([8.0, 8.0, 8.0, 0.3, 0.3, 0.5]) if moments else np.repeat([8.0, 0.0], 3)
    return rng.uniform(-1.0, 1.0, (count, 6)) * bounds


def test_estimate_of_a_solved_pose_is_its_wrench(solver, estimator, params):
    """Position and orientation: all six components back to 1e-6 (relative)."""
    length = params.stack_height
    for wrench in random_wrenches(11, 12):
        solved = solver.solve(wrench[:3], wrench[3:])
        assert solved.converged and solved.stable
        estimate = estimator.estimate_wrench(solved.end_disk_position,
                                             solved.end_disk_quaternion_xyzw)
        assert isinstance(estimate, WrenchEstimate)
        assert estimate.converged and not estimate.flags, estimate.message
        # an exact pose (no covariance): nothing to hold a spread against
        assert estimate.accuracy_met is None and estimate.to_dict()['accuracy_met'] is None
        assert 'accuracy not assessed' in estimate.message
        assert scaled_error(estimate.wrench, wrench, length) < ROUND_TRIP, (wrench, estimate)
        assert estimate.residual_m < 1e-10 and estimate.residual_deg < 1e-8
        assert estimate.estimated == 'wrench' and estimate.stable
        np.testing.assert_allclose(estimate.position, solved.end_disk_position, atol=1e-10)


def test_position_only_estimates_the_force_or_the_moment(solver, estimator, params):
    """A position gives the force under a known moment, or the moment under a known force."""
    length = params.stack_height
    for wrench in random_wrenches(12, 8):
        solved = solver.solve(wrench[:3], wrench[3:])
        force = estimator.estimate_wrench(solved.end_disk_position, moment=wrench[3:])
        assert force.converged and force.estimated == 'force', force.message
        assert scaled_error(force.wrench, wrench, length) < ROUND_TRIP
        np.testing.assert_array_equal(force.moment, wrench[3:])
        assert math.isnan(force.residual_deg)
    for wrench in random_wrenches(13, 3, moments=False):  # the default moment: none
        solved = solver.solve(wrench[:3])
        force = estimator.estimate_wrench(solved.end_disk_position)
        assert force.converged and scaled_error(force.wrench, wrench, length) < ROUND_TRIP
    wrench = np.array([3.0, -2.0, 1.0, 0.2, -0.1, 0.3])
    solved = solver.solve(wrench[:3], wrench[3:])
    moment = estimator.estimate_wrench(solved.end_disk_position, force=wrench[:3])
    assert moment.converged and moment.estimated == 'moment', moment.message
    np.testing.assert_array_equal(moment.force, wrench[:3])
    # not uniquely: another moment puts the end disk at the same point, and is named; which
    # of the two comes first depends on where the search starts
    assert moment.flagged and any('ambiguous' in flag for flag in moment.flags)
    assert 'ambiguous' in moment.message
    matches = (moment.wrench, moment.alternative)
    errors = sorted(scaled_error(match, wrench, length) for match in matches)
    # the position observes a moment poorly (cond ~ 1e4): the model's rounding shows more
    assert errors[0] < 1e-5 and errors[1] > 0.1, errors
    for match in matches:
        np.testing.assert_array_equal(match[:3], wrench[:3])
        again = solver.solve(match[:3], match[3:])
        np.testing.assert_allclose(again.end_disk_position, solved.end_disk_position,
                                   atol=1e-10)


def test_covariance_covers_the_spread_of_noisy_estimates(solver, params):
    """200 seeded noisy poses: the 95 % ellipsoids hold the true wrench 90-99 % of the time."""
    estimator = TranslatorSolver(params)
    rng = np.random.default_rng(2024)
    wrench = np.array([4.0, -3.0, -5.0, 0.1, -0.05, 0.08])
    solved = solver.solve(wrench[:3], wrench[3:])
    position, rotation = solved.end_disk_position, Rotation.from_quat(
        solved.end_disk_quaternion_xyzw)
    mixing = np.eye(6) + 0.3 * rng.normal(size=(6, 6))
    spread = np.diag(np.repeat([3e-7, 3e-6], 3))  # m, rad
    covariance = spread @ mixing @ mixing.T @ spread
    cholesky = np.linalg.cholesky(covariance)
    inside = {6: 0, 3: 0}
    whitened = []
    for _ in range(200):
        noise = cholesky @ rng.normal(size=6)
        quaternion = (Rotation.from_rotvec(noise[3:]) * rotation).as_quat()
        full = estimator.estimate_wrench(position + noise[:3], quaternion,
                                         pose_covariance=covariance)
        assert full.converged, full.message
        error = full.wrench - wrench
        inside[6] += error @ np.linalg.solve(full.covariance, error) <= chi2.ppf(0.95, 6)
        whitened.append(np.linalg.solve(np.linalg.cholesky(full.covariance), error))
        force = estimator.estimate_wrench(position + noise[:3], pose_covariance=covariance,
                                          moment=wrench[3:])
        assert force.converged, force.message
        assert not force.covariance[3:].any() and not force.covariance[:, 3:].any()
        error = force.force - wrench[:3]
        inside[3] += error @ np.linalg.solve(force.covariance[:3, :3], error) <= chi2.ppf(0.95, 3)
    for dof, count in inside.items():
        assert 0.90 <= count / 200 <= 0.99, (dof, count)
    # the whole shape, not only the size: whitened errors have about the unit covariance
    # (200 samples: an entry's sampling deviation is about 0.07-0.1)
    spread = np.cov(np.array(whitened).T)
    assert np.abs(spread - np.eye(6)).max() < 0.3, spread


def test_the_axial_force_is_flagged_as_poorly_observable(solver, estimator):
    """The compliance's stiff direction is named, with its singular value and role."""
    wrench = np.array([5.0, 2.0, -3.0, 0.1, -0.2, 0.05])
    solved = solver.solve(wrench[:3], wrench[3:], compliance=True)
    estimate = estimator.estimate_wrench(solved.end_disk_position,
                                         solved.end_disk_quaternion_xyzw,
                                         pose_covariance=np.eye(6) * 1e-12)
    assert estimate.ill_conditioned and estimate.condition_number > CONDITION_LIMIT
    labels = [direction['label'] for direction in estimate.conditioning]
    assert labels == ['axial force'], estimate.conditioning
    axial = estimate.conditioning[0]
    length = solved.compliance.characteristic_length
    scale = np.repeat([1.0, length], 3)
    values = np.linalg.svd(scale[:, None] * solved.compliance.matrix * scale,
                           compute_uv=False)
    # at 1 um the pose sees the axial force about as well as the 25 N prior does: the
    # estimate, and the compliance there, sit a few percent of the axial force off the truth
    assert axial['singular_value'] == pytest.approx(values[-1], rel=1e-3)
    assert axial['ratio'] == pytest.approx(values[0] / values[-1], rel=1e-3)
    assert estimate.condition_number == pytest.approx(values[0] / values[-1], rel=1e-3)
    assert (axial['twist'], axial['role']) == ('translation z', 'constraint')
    direction = np.array(axial['direction'])
    assert direction[2] > 0.9 and np.linalg.norm(direction / scale) == pytest.approx(1.0)
    # the standard deviation along it is the covariance's largest: 1 um reads as newtons
    assert axial['standard_deviation'] == pytest.approx(
        math.sqrt(np.linalg.eigvalsh(estimate.covariance / scale / scale[:, None])[-1]),
        rel=1e-3)
    assert 'poorly observable: axial force' in estimate.message
    json.dumps(estimate.to_dict())  # JSON-safe


def test_an_unreachable_pose_is_a_flagged_result(estimator, params):
    """Beyond the reach, or needing loads past the limit: converged False with the reason."""
    far = estimator.estimate_wrench([0.0, 0.0, 1.5 * params.stack_height])
    assert not far.converged and not far.accuracy_met and 'unreachable' in far.message
    assert np.isnan(far.force).all()
    assert json.loads(json.dumps(far.to_dict()))['force'] == [None, None, None]
    crushed = estimator.estimate_wrench([0.0, 0.0, 0.3 * params.stack_height], [0, 0, 0, 1])
    assert not crushed.converged and not crushed.accuracy_met, crushed.message
    # the next estimate recovers from there
    solved = TranslatorSolver(params).solve([2.0, 1.0, 0.0])
    estimate = estimator.estimate_wrench(solved.end_disk_position,
                                         solved.end_disk_quaternion_xyzw)
    assert estimate.converged and not estimate.flags, estimate.message


def test_a_pose_only_a_buckling_load_matches_stops_at_the_buckling_load(params):
    """
    A moment estimate whose held force (zero) is wrong: the match lies past buckling.

    The search presses against the buckling load; once a step within one posterior standard
    deviation buckles the translator it stops there, in a few forward solves (bisecting on
    took all 40, each past buckling 0.3-1 s), and says so: not converged, flagged.
    """
    solved = TranslatorSolver(params).solve([4.0, -3.0, 1.0], [0.05, 0.0, 0.0])
    covariance = np.diag([0.2e-3 ** 2] * 3 + [math.radians(0.1) ** 2] * 3)
    estimate = TranslatorSolver(params).estimate_wrench(
        solved.end_disk_position, solved.end_disk_quaternion_xyzw,
        pose_covariance=covariance, estimate='moment')
    assert not estimate.converged and not estimate.accuracy_met
    assert estimate.flags[0].startswith('no stable equilibrium matches the measured pose: '
                                        'the best stable match lies at the buckling load')
    assert estimate.stable and estimate.solves <= 15, estimate.solves
    np.testing.assert_array_equal(estimate.force, 0.0)


def test_a_search_stays_within_the_largest_force_and_moment(params):
    """
    The same pose with the node's limits (|m| <= 10 N m): unmatched at once, within them.

    The match past buckling lies beyond 10 N m: the search tries no load past the limits
    and ends without a solve past buckling, naming the limit it met.
    """
    solved = TranslatorSolver(params).solve([4.0, -3.0, 1.0], [0.05, 0.0, 0.0])
    covariance = np.diag([0.2e-3 ** 2] * 3 + [math.radians(0.1) ** 2] * 3)
    estimate = TranslatorSolver(params).estimate_wrench(
        solved.end_disk_position, solved.end_disk_quaternion_xyzw,
        pose_covariance=covariance, estimate='moment', max_force=100.0, max_moment=10.0)
    assert not estimate.converged and not estimate.accuracy_met
    assert estimate.flags[0] == ('no nearby wrench lowers the pose residual: no equilibrium '
                                 'matches the measured pose within |m| <= 10 N m (max_moment)')
    assert estimate.stable and estimate.solves <= 20, estimate.solves
    assert np.linalg.norm(estimate.moment) <= 10.0


def test_a_pose_near_buckling_is_ambiguous(params):
    """An equilibrium close to the axial buckling load is flagged: another branch matches too."""
    near = TranslatorSolver(params, follow_stable_branch=False).solve([0.0, 0.0, -28.0])
    assert near.stable and near.stability_margin < 0.05
    estimate = TranslatorSolver(params).estimate_wrench(near.end_disk_position,
                                                        near.end_disk_quaternion_xyzw)
    assert estimate.converged and estimate.flagged and estimate.accuracy_met is None
    assert any('near a bifurcation' in flag for flag in estimate.flags), estimate.flags
    assert estimate.force[2] == pytest.approx(-28.0, rel=1e-6)


@pytest.mark.parametrize('arguments, keywords, named', [
    (([0.0, math.nan, 0.1],), {}, 'position y'),
    (([0.0, 0.1],), {}, 'position must have 3'),
    (([0.0, 0.0, 0.17], [0.0, 0.0, 0.0, 2.0]), {}, 'quaternion_xyzw must be a unit'),
    (([0.0, 0.0, 0.17], [0.0, 0.0, 0.0, 1.0]), {'estimate': ('fx', 'fw')}, 'estimate must'),
    (([0.0, 0.0, 0.17], [0.0, 0.0, 0.0, 1.0]), {'estimate': 'axial'}, 'estimate must'),
    (([0.0, 0.0, 0.17],), {'estimate': ('fx', 'fx')}, 'twice'),
    (([0.0, 0.0, 0.17],), {'prior_covariance': np.zeros((6, 6))}, 'positive definite'),
    (([0.0, 0.0, 0.17],), {'prior_mean': [0.0] * 5}, 'prior_mean must have 6'),
    (([0.0, 0.0, 0.17],), {'target_force_sd': 0.0}, 'target_force_sd must be positive'),
    (([0.0, 0.0, 0.17],), {'moment': [0, 0, 0], 'force': [0, 0, 0]}, 'not both'),
    (([0.0, 0.0, 0.17],), {'force': [0, 0, math.inf]}, 'force z'),
    (([0.0, 0.0, 0.17], [0, 0, 0, 1]), {'pose_covariance': np.eye(3)}, 'must be 6x6'),
    (([0.0, 0.0, 0.17], [0, 0, 0, 1]), {'pose_covariance': -np.eye(6)}, 'semidefinite'),
    (([0.0, 0.0, 0.17],), {'pose_covariance': np.triu(np.ones((3, 3)))}, 'symmetric'),
    (([0.0, 0.0, 0.17],), {'pose_covariance': np.full((3, 3), math.nan)}, 'finite'),
    (([0.0, 0.0, 0.17],), {'max_force': -1.0}, 'max_force must be'),
    (([0.0, 0.0, 0.17],), {'max_moment': math.nan}, 'max_moment must be'),
])
def test_bad_input_raises_a_value_error_naming_it(estimator, arguments, keywords, named):
    """Malformed positions, quaternions, covariances and given components are named."""
    with pytest.raises(ValueError, match=named):
        estimator.estimate_wrench(*arguments, **keywords)

"""
estimate_wrench at a real tracker's noise: 0.1-0.5 mm in position, 0.05-0.2 deg in rotation.

Each trial solves a seeded random load, perturbs the end-disk pose by noise of the stated
covariance and estimates the load back. Three choices of components:

* 'wrench': all six, loads with a moment;
* 'force': a point contact at the tip (the moment held at zero);
* 'lateral': the lateral force, with the axial force and the moment held at their values.

Calibration. The posterior covariance is checked the way a Bayesian posterior is
(simulation-based calibration): the true loads are drawn from the prior the estimate is
given, here one describing a lab's loads (lateral 5 N, axial 1.5 N, moments 0.1 N m
standard deviations), so that the normalized estimation error e^T P^-1 e is chi-square
with as many degrees of freedom as components estimated when the posterior is right; its
95 % quantile must hold 90-99 % of 200 trials per setting. Directions the pose does not see
fall back to the prior with the prior's spread, and are covered in the same way.

The default prior (25 N, 2.5 N m) on loads of the node's range (lateral up to 10 N, axial up
to 3 N) must converge in at least 95 % of trials and never mark as met an estimate that
is confidently wrong. With a Gaussian posterior an error beyond 3 standard deviations
happens in 0.27 % of components by chance, so the check is that such errors are as rare as
that (at most 1 % of the met estimates) and that none exceeds 5 standard deviations, which
chance gives once in two million.
"""

import contextlib
import importlib
import io
import math
from pathlib import Path
import re
from typing import Dict, Iterator, List, Tuple

from cdr_translator import TranslatorSolver
from cdr_translator.estimation import Curvature, diagonal_prior, measured_target
import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from scipy.stats import chi2

#: (position sd m, orientation sd deg) of the trackers tried.
NOISE = [(1e-4, 0.05), (2e-4, 0.1), (5e-4, 0.2)]

#: Trials per setting.
TRIALS = 200

#: The docs' worked example: a marked Python block, then the block of what it prints.
EXAMPLE_MARKER = '<!-- docs-test: estimate-example -->'
DOCS = Path(__file__).resolve().parents[2] / 'docs'

#: The prior of the calibration trials: lateral and axial force (N), moments (N m).
LAB_SD = np.array([5.0, 5.0, 1.5, 0.1, 0.1, 0.1])

#: A walk's step standard deviations along a stream: forces (N), moments (N m).
SMALL_STEPS = np.array([0.3, 0.3, 0.1, 0.005, 0.005, 0.005])


def pose_covariance(position_sd: float, orientation_deg: float) -> np.ndarray:
    """Return the diagonal 6x6 pose covariance (m^2, rad^2)."""
    return np.diag(np.repeat([position_sd, math.radians(orientation_deg)], 3) ** 2)


def noisy_pose(solved, covariance: np.ndarray, rng: np.random.Generator
               ) -> Tuple[np.ndarray, np.ndarray]:
    """Return (position, quaternion_xyzw) of ``solved``'s end disk seen through the noise."""
    noise = np.linalg.cholesky(covariance) @ rng.normal(size=6)
    rotation = Rotation.from_rotvec(noise[3:]) * Rotation.from_quat(
        solved.end_disk_quaternion_xyzw)
    return solved.end_disk_position + noise[:3], rotation.as_quat()


def noisy_walk(solver: TranslatorSolver, rng: np.random.Generator, load: np.ndarray,
               step_sd: np.ndarray, covariance: np.ndarray, count: int
               ) -> Iterator[Tuple[np.ndarray, np.ndarray]]:
    """
    Yield the noisy end-disk pose (position, quaternion_xyzw) of each step of a load's walk.

    ``load`` (6) moves in place by ``step_sd`` times a normal draw, ``count`` times; each
    step is solved and seen through ``covariance``'s noise.
    """
    for _ in range(count):
        load += rng.normal(size=6) * step_sd
        solved = solver.solve(load[:3], load[3:])
        yield noisy_pose(solved, covariance, rng)


def run_trials(solver: TranslatorSolver, estimator: TranslatorSolver, loads: np.ndarray,
               covariance: np.ndarray, components: str, seed: int,
               prior: np.ndarray) -> Dict[str, List]:
    """Estimate each load back from a noisy pose; collect the errors and verdicts."""
    rng = np.random.default_rng(seed)
    found: Dict[str, List] = {'converged': [], 'nees': [], 'errors': [], 'deviations': [],
                              'met': [], 'free': []}
    for load in loads:
        solved = solver.solve(load[:3], load[3:])
        assert solved.converged and solved.stable, (load, solved.message)
        position, quaternion = noisy_pose(solved, covariance, rng)
        held = {} if components == 'wrench' else {'force': load[:3], 'moment': load[3:]}
        estimate = estimator.estimate_wrench(position, quaternion, pose_covariance=covariance,
                                             estimate=components, prior_covariance=prior,
                                             **held)
        found['converged'].append(estimate.converged)
        if not estimate.converged:
            continue
        free = [index for index in range(6) if estimate.target_sd[index] > 0]
        error = (estimate.wrench - load)[free]
        spread = estimate.covariance[np.ix_(free, free)]
        found['nees'].append(float(error @ np.linalg.solve(spread, error)))
        found['errors'].append(np.abs(estimate.wrench - load))
        found['deviations'].append(np.sqrt(np.diag(estimate.covariance)))
        found['met'].append(estimate.accuracy_met)
        found['free'].append(free)
        assert estimate.accuracy_met is (not estimate.flags), estimate.message
    return found


@pytest.fixture(scope='module')
def estimator(params):
    """Estimate along the trials (a solver of its own: warm starts follow the estimates)."""
    return TranslatorSolver(params)


@pytest.mark.parametrize('position_sd, orientation_deg', NOISE)
@pytest.mark.parametrize('components', ['wrench', 'force', 'lateral'])
def test_the_posterior_covers_the_truth(solver, estimator, position_sd, orientation_deg,
                                        components):
    """Loads drawn from the prior: 90-99 % of the 95 % ellipsoids hold the truth."""
    rng = np.random.default_rng(int(position_sd * 1e5) + 7 * len(components))
    loads = rng.normal(size=(TRIALS, 6)) * LAB_SD
    if components != 'wrench':
        loads[:, 3:] = 0.0  # a point contact at the tip
    covariance = pose_covariance(position_sd, orientation_deg)
    found = run_trials(solver, estimator, loads, covariance, components, 11,
                       np.diag(LAB_SD ** 2))
    assert np.mean(found['converged']) >= 0.95
    dof = len(found['free'][0])
    inside = np.mean(np.array(found['nees']) <= chi2.ppf(0.95, dof))
    assert 0.90 <= inside <= 0.99, (components, position_sd, inside)


@pytest.mark.parametrize('position_sd, orientation_deg', NOISE)
@pytest.mark.parametrize('components', ['wrench', 'force', 'lateral'])
def test_the_default_prior_converges_and_is_never_confidently_wrong(
        solver, estimator, params, position_sd, orientation_deg, components):
    """Loads across the range: >= 95 % converge; a met estimate is within its spread."""
    rng = np.random.default_rng(int(position_sd * 1e5) + 3 * len(components))
    loads = np.zeros((TRIALS, 6))
    loads[:, :2] = rng.uniform(-10.0, 10.0, (TRIALS, 2))
    loads[:, 2] = rng.uniform(-3.0, 3.0, TRIALS)
    if components == 'wrench':
        loads[:, 3:] = rng.uniform(-0.2, 0.2, (TRIALS, 3))
    covariance = pose_covariance(position_sd, orientation_deg)
    found = run_trials(solver, estimator, loads, covariance, components, 13, diagonal_prior())
    assert np.mean(found['converged']) >= 0.95
    errors, deviations = np.array(found['errors']), np.array(found['deviations'])
    met = np.array([bool(value) for value in found['met']])
    free = found['free'][0]
    sigmas = errors[:, free] / deviations[:, free]
    assert np.mean(np.any(sigmas[met] > 3.0, axis=1)) <= 0.01 if met.any() else True
    assert not np.any(sigmas[met] > 5.0)
    # every estimate at all: the posterior spread, not the estimate, takes the noise
    assert np.mean(np.all(sigmas <= 5.0, axis=1)) >= 0.99


@pytest.mark.parametrize('position_sd, orientation_deg, bound_n', [
    (2e-4, 0.1, 0.1), (5e-4, 0.2, 0.25)])
def test_the_lateral_force_is_known_when_the_axial_force_and_moment_are_held(
        solver, estimator, position_sd, orientation_deg, bound_n):
    """Lateral loads up to 10 N: within 0.1 N at 0.2 mm / 0.1 deg (95th percentile)."""
    rng = np.random.default_rng(5)
    loads = np.zeros((60, 6))
    loads[:, :2] = rng.uniform(-10.0, 10.0, (60, 2))
    loads[:, 2] = rng.uniform(-3.0, 3.0, 60)
    covariance = pose_covariance(position_sd, orientation_deg)
    found = run_trials(solver, estimator, loads, covariance, 'lateral', 17, diagonal_prior())
    assert all(found['converged'])
    errors = np.array(found['errors'])[:, :2]
    assert np.percentile(errors, 95) <= bound_n, np.percentile(errors, 95)
    assert not errors[:, 2:].any() if errors.shape[1] > 2 else True
    assert all(found['met']), 'the posterior spread is within the 0.5 N target'


def test_an_estimate_along_a_noisy_stream_is_warm(solver, params):
    """A random walk of loads seen at 0.2 mm / 0.1 deg: a few forward solves per estimate."""
    estimator = TranslatorSolver(params)
    rng = np.random.default_rng(23)
    load = np.zeros(6)
    covariance = pose_covariance(2e-4, 0.1)
    solves = []
    for _ in range(60):
        load[:2] = np.clip(load[:2] + rng.normal(scale=0.3, size=2), -10.0, 10.0)
        solved = solver.solve(load[:3])
        position, quaternion = noisy_pose(solved, covariance, rng)
        estimate = estimator.estimate_wrench(position, quaternion, pose_covariance=covariance,
                                             estimate='lateral')
        assert estimate.converged and estimate.accuracy_met, estimate.message
        solves.append(estimate.solves)
    assert np.median(solves[1:]) <= 3, solves
    assert max(solves) <= 8, solves


def test_a_warm_estimate_takes_one_forward_solve_and_agrees_with_a_cold_one(solver, params):
    """
    Six components along a noisy walk: one forward solve per warm estimate, mostly.

    The last Gauss-Newton step taken without another forward solve (search.FINISH_CHI2)
    leaves the estimate within a tenth of a posterior standard deviation (Mahalanobis
    distance) of a cold search from the prior mean, and its reported pose and residual
    are those of the stepped wrench.
    """
    warm = TranslatorSolver(params)
    rng = np.random.default_rng(5)
    load = np.array([2.0, -1.0, 0.5, 0.05, -0.03, 0.02])
    covariance = pose_covariance(2e-4, 0.1)
    solves, finished = [], 0
    for position, quaternion in noisy_walk(solver, rng, load, SMALL_STEPS, covariance, 40):
        estimate = warm.estimate_wrench(position, quaternion, pose_covariance=covariance)
        assert estimate.converged, estimate.message
        solves.append(estimate.solves)
        if 'last Gauss-Newton step' not in estimate.message:
            continue
        finished += 1
        cold = TranslatorSolver(params).estimate_wrench(position, quaternion,
                                                        pose_covariance=covariance)
        difference = estimate.wrench - cold.wrench
        assert difference @ np.linalg.solve(estimate.covariance, difference) <= 0.1 ** 2
        check = solver.solve(estimate.force, estimate.moment)
        assert np.linalg.norm(check.end_disk_position - estimate.position) < 1e-6
    assert finished >= 20 and np.mean(solves[1:]) <= 1.3, solves


def test_a_step_without_a_forward_solve_stays_within_a_tenth_of_a_spread(
        solver, params, monkeypatch):
    """
    Loads across the range, each estimated from the last one's solution (far away).

    The last Gauss-Newton step taken from the last forward solve is bounded in load
    (search.FINISH_REACH), not only in standard deviations: along the axial force one is
    15-25 N. Each estimate is within a tenth of a posterior standard deviation (Mahalanobis)
    of the search carried to the end, which takes no such step.
    """
    search_module = importlib.import_module('cdr_translator.estimation.search')
    rng = np.random.default_rng(21)
    covariance = pose_covariance(1e-4, 0.05)
    warm = TranslatorSolver(params)
    loads = np.zeros((30, 6))
    loads[:, :2] = rng.uniform(-10.0, 10.0, (30, 2))
    loads[:, 2] = rng.uniform(-3.0, 3.0, 30)
    finished = 0
    for load in loads:
        solved = solver.solve(load[:3], load[3:])
        position, quaternion = noisy_pose(solved, covariance, rng)
        estimate = warm.estimate_wrench(position, quaternion, pose_covariance=covariance,
                                        estimate='force')
        assert estimate.converged, estimate.message
        if 'last Gauss-Newton step' not in estimate.message:
            continue
        finished += 1
        with monkeypatch.context() as patch:
            patch.setattr(search_module, 'FINISH_CHI2', 0.0)
            patch.setattr(search_module, 'CONVERGED_CHI2', 1e-8)
            full = TranslatorSolver(params).estimate_wrench(
                position, quaternion, pose_covariance=covariance, estimate='force')
        difference = (estimate.wrench - full.wrench)[:3]
        spread = full.covariance[:3, :3]
        assert difference @ np.linalg.solve(spread, difference) <= 0.1 ** 2, (load, difference)
    assert finished >= 5


def test_the_same_pose_again_takes_no_forward_solve(solver, params):
    """
    A pose on two topics (PoseStamped and with its covariance): the second estimate is free.

    The step that arrived at the last estimate showed the linearization right there
    (Evaluation.linear), so the remaining Gauss-Newton step of the repeated pose, within a
    standard deviation, is taken without a forward solve, and gives the first estimate.
    """
    warm = TranslatorSolver(params)
    rng = np.random.default_rng(12)
    load = np.array([2.0, -1.0, 0.5, 0.05, -0.03, 0.02])
    covariance = pose_covariance(2e-4, 0.1)
    repeated = []
    for position, quaternion in noisy_walk(solver, rng, load, SMALL_STEPS, covariance, 20):
        first = warm.estimate_wrench(position, quaternion, pose_covariance=covariance)
        again = warm.estimate_wrench(position, quaternion, pose_covariance=covariance)
        assert first.converged and again.converged, again.message
        difference = again.wrench - first.wrench
        assert difference @ np.linalg.solve(first.covariance, difference) <= 0.1 ** 2
        repeated.append(again.solves)
    assert np.mean(repeated) <= 0.1, repeated


def test_steps_on_a_measured_curvature_and_a_second_topic_of_the_pose(
        solver, params, monkeypatch):
    """
    The last step taken on the curvature the step before it measured, along a rough walk.

    With the other way of finishing (a step shown right by its gain) switched off, every
    step taken without a forward solve follows the curvature the step arriving at the last
    forward solve measured (Evaluation.curvature, search.FINISH_MISS). Each such estimate is
    within a tenth of a posterior standard deviation of its search carried to the end. A
    tracker publishing PoseStamped and PoseWithCovarianceStamped gives each pose twice,
    the node's assumed covariance on one and the message's on the other: the second
    estimate reuses the measurement for the same pose, takes no forward solve and is
    within a tenth of a standard deviation of its own search carried to the end too.
    """
    search_module = importlib.import_module('cdr_translator.estimation.search')
    monkeypatch.setattr(search_module, 'LINEAR_FINISH_CHI2', 0.0)
    warm = TranslatorSolver(params)
    rng = np.random.default_rng(31)
    load = np.array([2.0, -1.0, 0.5, 0.05, -0.03, 0.02])
    assumed = pose_covariance(2e-4, 0.1)
    carried = pose_covariance(2e-4, 0.1000001)  # the message's own: not the same bytes

    def within_a_tenth(estimate, position, quaternion, covariance) -> bool:
        with monkeypatch.context() as patch:
            patch.setattr(search_module, 'FINISH_CHI2', 0.0)
            patch.setattr(search_module, 'CONVERGED_CHI2', 1e-8)
            full = TranslatorSolver(params).estimate_wrench(position, quaternion,
                                                            pose_covariance=covariance)
        difference = estimate.wrench - full.wrench
        return bool(difference @ np.linalg.solve(full.covariance, difference) <= 0.1 ** 2)

    again_solves, finished = [], 0
    steps = np.array([1.0, 1.0, 0.3, 0.01, 0.01, 0.01])
    for position, quaternion in noisy_walk(solver, rng, load, steps, assumed, 25):
        first = warm.estimate_wrench(position, quaternion, pose_covariance=assumed)
        assert first.converged, first.message
        if 'last Gauss-Newton step' in first.message:
            finished += 1
            assert within_a_tenth(first, position, quaternion, assumed)
        again = warm.estimate_wrench(position, quaternion, pose_covariance=carried)
        assert again.converged, again.message
        again_solves.append(again.solves)
        assert within_a_tenth(again, position, quaternion, carried)
    assert finished >= 10, finished
    assert np.mean(again_solves) <= 0.1, again_solves


def test_a_measured_curvature_serves_its_own_pose_only():
    """Curvature.scaled_miss: None for another measured pose or other measured components."""
    covariance = pose_covariance(2e-4, 0.1)
    here = measured_target([0.0, 0.0, 0.1], [0.0, 0.0, 0.0, 1.0], covariance, None, None, 0.1)
    there = measured_target([0.001, 0.0, 0.1], [0.0, 0.0, 0.0, 1.0], covariance, None, None,
                            0.1)
    position_only = measured_target([0.0, 0.0, 0.1], None, covariance, None, None, 0.1)
    miss = np.array([2e-4, 0.0, 0.0, 0.0, 0.0, 0.0])  # one standard deviation along x
    curvature = Curvature(here.frame, here.rows, miss, 4.0)
    assert curvature.scaled_miss(here, 2.0) == pytest.approx(0.25, rel=1e-6)
    assert curvature.scaled_miss(there, 2.0) is None
    assert curvature.scaled_miss(position_only, 2.0) is None


def test_held_values_that_move_along_a_stream_cost_no_extra_forward_solve(solver, params):
    """
    The lateral force with the axial force held at a value that walks: one solve each.

    The last estimate's solution moved to the new held values to first order is the start
    (search.HELD_SHIFT_N); the estimate is that of a cold search to a tenth of a posterior
    standard deviation.
    """
    warm = TranslatorSolver(params)
    rng = np.random.default_rng(8)
    load = np.array([3.0, -2.0, 1.0, 0.0, 0.0, 0.0])
    covariance = pose_covariance(2e-4, 0.1)
    solves = []
    for _ in range(30):
        load[:3] += rng.normal(size=3) * np.array([0.3, 0.3, 0.1])
        solved = solver.solve(load[:3])
        position, quaternion = noisy_pose(solved, covariance, rng)
        estimate = warm.estimate_wrench(position, quaternion, pose_covariance=covariance,
                                        estimate='lateral', force=load[:3])
        assert estimate.converged and estimate.force[2] == load[2], estimate.message
        solves.append(estimate.solves)
        cold = TranslatorSolver(params).estimate_wrench(
            position, quaternion, pose_covariance=covariance, estimate='lateral',
            force=load[:3])
        difference = (estimate.wrench - cold.wrench)[:2]
        spread = estimate.covariance[:2, :2]
        assert difference @ np.linalg.solve(spread, difference) <= 0.1 ** 2
    assert np.mean(solves[1:]) <= 1.2, solves


def test_the_worked_example_of_the_docs_prints_what_they_show():
    """The force-sensing example runs and prints the output the docs give."""
    pages = [path for path in sorted(DOCS.rglob('*.md')) if EXAMPLE_MARKER in path.read_text()]
    assert len(pages) == 1, pages
    text = pages[0].read_text()
    code, shown = re.findall(r'```(?:python)?\n(.*?)```', text[text.index(EXAMPLE_MARKER):],
                             re.DOTALL)[:2]
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        exec(compile(code, str(pages[0]), 'exec'), {})
    assert printed.getvalue().split() == shown.split(), printed.getvalue()

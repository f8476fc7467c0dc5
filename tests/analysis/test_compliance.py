"""
End-disk compliance: implicit differentiation vs finite differences, theory and Table III.

Tolerances are relative to max |C| unless stated; C is in SI units (m/N, rad/(N m)).
"""

import json

from bench.walks import random_walk
from cdr_translator import cli, TranslatorSolver
from cdr_translator.analysis.compliance import analyse, AXIS_LABELS, compliance_analysis
from cdr_translator.analysis.compliance import frame_twist, STORED_METHOD
from cdr_translator.fidelity import FidelitySolver
from cdr_translator.params.paper import PAPER_PRIMARY_MOBILITY, TABLE_III
from cdr_translator.studies.finite_difference import finite_difference_compliance
import numpy as np
import pytest
from scipy.spatial.transform import Rotation


def relative_difference(a: np.ndarray, b: np.ndarray) -> float:
    """Return the largest entry of |a - b| over the largest entry of |b|."""
    return float(np.abs(a - b).max() / np.abs(b).max())


@pytest.fixture(scope='module')
def compliance_solver(params):
    """Give these tests a solver of their own (its warm-start state is theirs)."""
    return TranslatorSolver(params)


@pytest.fixture(scope='module')
def paper_cases(compliance_solver):
    """Compliance analyses at the two Table III loads, keyed by the force in x (N)."""
    return {case.force[0]: compliance_solver.solve(case.force, compliance=True).compliance
            for case in TABLE_III}


@pytest.mark.parametrize('force, moment', [
    ((12.0, 0.0, 0.0), (0.0, 0.0, 0.0)),
    ((3.0, -6.0, -4.0), (0.05, 0.0, -0.02)),
    ((0.0, 0.0, 0.0), (0.0, 0.0, 0.1)),
])
def test_implicit_equals_central_differences_of_solves(params, compliance_solver, force,
                                                       moment):
    """(b) implicit differentiation agrees with (a) central differences to 1e-6."""
    implicit = compliance_solver.solve(force, moment, compliance=True).compliance.matrix
    reference = finite_difference_compliance(params, force, moment)
    assert relative_difference(implicit, reference) <= 1e-6


def test_compliance_after_a_warm_sequence_is_exact(params, compliance_solver):
    """A stale stored factorization only preconditions: C is exact along a sequence too."""
    for fx in np.linspace(0.0, 8.0, 5):
        compliance_solver.solve((fx, 1.0, 0.0))
    implicit = compliance_solver.solve((8.5, 1.0, 0.0), compliance=True).compliance.matrix
    reference = finite_difference_compliance(params, (8.5, 1.0, 0.0))
    assert relative_difference(implicit, reference) <= 1e-6


def scaled_error(approximate: np.ndarray, exact: np.ndarray, length: float) -> float:
    """Return |S (approximate - exact) S| / |S exact S| (Frobenius), S = diag(1, 1, 1, L, L, L)."""
    scale = np.repeat([1.0, length], 3)
    return float(np.linalg.norm(scale[:, None] * (approximate - exact) * scale[None, :])
                 / np.linalg.norm(scale[:, None] * exact * scale[None, :]))


@pytest.mark.parametrize('sigma', [0.02, 0.1, 0.4])
def test_stored_compliance_is_within_its_stated_error_of_the_exact_one(params, sigma):
    """
    A compliance from the stored factorization is within its stated error of the exact one.

    Along the bench's random walks, at the same solution; a tolerance sends the solves whose
    stated error exceeds it to the exact compliance.
    """
    solver = TranslatorSolver(params)
    problem = solver.problem
    tolerance = 0.02
    stored = exact = 0
    for wrench in random_walk(sigma, 160)[::4]:
        result = solver.solve(wrench[:3], wrench[3:], compliance=True,
                              compliance_tolerance=tolerance)
        analysis = result.compliance
        assert result.converged and analysis is not None
        reference = compliance_analysis(problem, result.unknowns / problem.x_scale, wrench,
                                        rotation=result.frames['de'][:3, :3])[0].matrix
        error = scaled_error(analysis.matrix, reference, params.stack_height)
        assert error <= analysis.estimated_error
        if analysis.method == STORED_METHOD:
            stored += 1
            assert 0.0 < analysis.estimated_error <= tolerance
        else:
            exact += 1
            assert error <= 1e-8
    assert stored >= 10  # the stored factorization served (the comparison is not vacuous)


def test_stored_compliance_only_when_asked_and_the_tolerance_is_checked(params):
    """Without compliance_tolerance C is exact; a bad tolerance raises ValueError naming it."""
    solver = TranslatorSolver(params)
    for wrench in random_walk(0.1, 20):
        result = solver.solve(wrench[:3], wrench[3:], compliance=True)
        assert result.compliance.method == 'implicit'
        assert result.compliance.estimated_error < 1e-10
    for bad in (-0.1, float('nan'), 'big'):
        with pytest.raises(ValueError, match='compliance_tolerance'):
            solver.solve((5.0, 0.0, 0.0), compliance=True, compliance_tolerance=bad)


@pytest.mark.parametrize('level', ['full', 'cc', 'rod', 'linear'])
def test_every_level_takes_the_compliance_tolerance(params, level):
    """Each level answers with compliance_tolerance; only the full model's may use it."""
    solver = FidelitySolver(params, fidelity=level)
    for fx in (5.0, 5.1):
        result = solver.solve((fx, 1.0, 0.0), compliance=True, compliance_tolerance=0.05)
    assert result.compliance is not None
    assert (result.compliance.method == STORED_METHOD) == (level == 'full')
    with pytest.raises(ValueError, match='compliance_tolerance'):
        solver.solve((5.2, 1.0, 0.0), compliance=True, compliance_tolerance=-1.0)


@pytest.mark.parametrize('force', [(0.0, 0.0, 0.0), (0.0, 0.0, -8.0), (0.0, 0.0, 15.0)])
def test_compliance_symmetric_under_axial_or_no_load(compliance_solver, force):
    """
    C = C^T when the preload is a dead force along the axis (or zero).

    The structure is conservative: C = J K^-1 J^T with K the Hessian of the potential,
    pairing [f; m] with [v; w]. (Under a lateral preload the model's C46/C64 pair differs
    by about 3 %: see docs/explanation/model.md.)
    """
    matrix = compliance_solver.solve(force, compliance=True).compliance.matrix
    assert relative_difference(matrix, matrix.T) <= 1e-7


def test_zero_load_compliance_matches_linear_beam_estimates(params, compliance_solver):
    """
    Unloaded C against small-deflection estimates of the same structure.

    l = 2 D is one joint, L_s = 2 l + L_m a secondary's length (it slides through the tube),
    EI, EA, GJ of one backbone, r the pitch radius:
    lateral: five rods bent at constant curvature in an S (end disk parallel),
        C11 = l (l + L_m)^2 / (10 EI);
    axial: primary over 2 l (the tube is rigid) parallel to four secondaries over L_s;
    tilt: the PJ/DJ angle difference stretches two secondaries, k = 5 EI / (2 l) + 2 EA r^2 / L_s;
    twist: four disk intervals in series, each the primary's GJ / D plus four secondaries as
        guided beams 12 EI r^2 / D^3, in parallel with the four secondaries' own GJ / L_s.
    """
    matrix = compliance_solver.solve((0.0, 0.0, 0.0), compliance=True).compliance.matrix
    ei = params.bending_stiffness
    ea = params.youngs_modulus * params.area
    gj = params.shear_modulus * 2.0 * params.second_moment
    joint, spacing, radius = params.joint_length, params.disk_spacing, params.pitch_radius
    secondary = 2.0 * joint + params.tube_length
    lateral = joint * (joint + params.tube_length) ** 2 / (10.0 * ei)
    axial = 1.0 / (ea / (2.0 * joint) + 4.0 * ea / secondary)
    tilt = 1.0 / (5.0 * ei / (2.0 * joint) + 2.0 * ea * radius ** 2 / secondary)
    interval = gj / spacing + 4.0 * 12.0 * ei * radius ** 2 / spacing ** 3
    intervals = 2 * (params.spacers_per_joint + 1)
    twist = 1.0 / (interval / intervals + 4.0 * gj / secondary)
    estimates = [(0, lateral, 0.03), (1, lateral, 0.03), (2, axial, 0.01), (3, tilt, 0.01),
                 (4, tilt, 0.01), (5, twist, 0.05)]
    for index, estimate, tolerance in estimates:
        assert matrix[index, index] == pytest.approx(estimate, rel=tolerance), index


@pytest.mark.parametrize('case', TABLE_III, ids=lambda case: f'{case.force[0]:g}N')
def test_table_iii_primary_mobility(paper_cases, case):
    """Both paper cases: mobility = translation x, translation y, rotation z; stable."""
    analysis = paper_cases[case.force[0]]
    assert analysis.primary_mobility == PAPER_PRIMARY_MOBILITY
    assert analysis.stable
    assert analysis.labels == ('translation x', 'translation y', 'translation z',
                               'rotation x', 'rotation y', 'rotation z')


@pytest.mark.parametrize('case', TABLE_III, ids=lambda case: f'{case.force[0]:g}N')
def test_table_iii_structure_and_arc_direction(paper_cases, case):
    """
    C_s has the paper's block pattern and the x-z eigenvector is the paper's to 0.02.

    The x-z block is nearly rank one: the end disk moves along its arc, whose direction
    depends on the bending angle only, so it is the best-defined quantity in Table III.
    """
    analysis = paper_cases[case.force[0]]
    paper_pattern = np.abs(_paper_sparse(case)) > 0.0
    assert np.array_equal(analysis.sparse_matrix != 0.0, paper_pattern)
    direction = analysis.eigenvectors[[0, 2], 0]
    assert np.allclose(direction, case.arc_direction, atol=0.02)


def _paper_sparse(case) -> np.ndarray:
    """Return the paper's C_s: its diagonal, x-z and rotation x-z couplings."""
    pattern = np.diag(np.diag(np.array(case.compliance)))
    for i, j in ((0, 2), (2, 0), (3, 5), (5, 3)):
        pattern[i, j] = case.compliance[i][j]
    return pattern


@pytest.mark.parametrize('force, index', [
    (12.0, 0), (12.0, 1), (12.0, 2), (12.0, 5), (20.0, 1),
])
def test_table_iii_diagonal_within_25_percent(paper_cases, force, index):
    """
    The diagonal terms that can match do, within 25 %.

    Not tested, with the reason in docs/explanation: C55 (and C44), set by the stretching of two
    secondaries, 2 EA r^2 / L_s, which the zero-load test confirms, is 4.7x the paper's;
    at 20 N the paper's C11 and C33 fall 2.9x from 12 N while its Table II bending angles,
    which this model reproduces, grow smoothly; C66 at 20 N rises 37 % in the paper.
    """
    case = next(case for case in TABLE_III if case.force[0] == force)
    ours = paper_cases[force].matrix[index, index]
    assert ours == pytest.approx(case.compliance[index][index], rel=0.25)


def test_analysis_thresholds_are_validated():
    """Out-of-range analysis parameters raise ValueError naming them."""
    with pytest.raises(ValueError, match='sparsity_threshold'):
        analyse(np.eye(6), 0.2, sparsity_threshold=1.5)
    with pytest.raises(ValueError, match='mobility_ratio'):
        analyse(np.eye(6), 0.2, mobility_ratio=0.0)


def test_sparsity_threshold_zero_keeps_every_term(compliance_solver):
    """With threshold 0, C_s is C itself."""
    analysis = compliance_solver.solve((12.0, 0.0, 0.0), compliance=True,
                                       sparsity_threshold=0.0).compliance
    assert np.array_equal(analysis.sparse_matrix, analysis.matrix)


def test_frame_twist_recovers_a_known_rotation_and_shift():
    """frame_twist returns the displacement and the spatial rotation vector."""
    before = np.eye(4)
    before[:3, :3] = Rotation.from_rotvec([0.3, -0.2, 0.1]).as_matrix()
    step = np.array([1e-3, -2e-3, 0.5e-3])
    after = np.eye(4)
    after[:3, :3] = Rotation.from_rotvec(step).as_matrix() @ before[:3, :3]
    after[:3, 3] = [0.01, 0.0, -0.02]
    assert np.allclose(frame_twist(before, after), np.r_[0.01, 0.0, -0.02, step], atol=1e-14)


def test_cli_compliance_equals_central_differences_of_cli_poses(capsys):
    """`solve --compliance --json` returns C equal to central differences of its own poses."""
    def run(*arguments):
        assert cli.main(['solve', *arguments, '--json']) == 0
        return json.loads(capsys.readouterr().out)

    data = run('--force', '12', '0', '0', '--compliance')
    for key in ('compliance', 'compliance_eigenvalues', 'compliance_eigenvectors',
                'primary_mobility', 'stable'):
        assert key in data
    assert list(data['primary_mobility']) == list(PAPER_PRIMARY_MOBILITY)
    matrix = np.array(data['compliance'])
    assert matrix.shape == (6, 6)
    step = 1e-2
    columns = []
    for axis in range(6):
        poses = []
        for sign in (1.0, -1.0):
            wrench = np.array([12.0, 0.0, 0.0, 0.0, 0.0, 0.0])
            wrench[axis] += sign * step * (1.0 if axis < 3 else 0.1)
            out = run('--force', *map(str, wrench[:3]), '--moment', *map(str, wrench[3:]))
            frame = np.eye(4)
            frame[:3, :3] = Rotation.from_quat(out['end_disk_quaternion_xyzw']).as_matrix()
            frame[:3, 3] = out['end_disk_position_m']
            poses.append(frame)
        columns.append(frame_twist(poses[1], poses[0])
                       / (2.0 * step * (1.0 if axis < 3 else 0.1)))
    assert relative_difference(np.column_stack(columns), matrix) <= 1e-5


def test_analysis_eigen_parts_equal_numpy_including_complex_pairs():
    """The direct LAPACK eigen call gives numpy.linalg.eig's real parts, complex pairs too."""
    rng = np.random.default_rng(3)
    skew = rng.standard_normal((6, 6))
    for matrix in (np.diag([1.0, 2.0, 3.0, 4.0, 5.0, 6.0]) + 0.1 * skew, skew - skew.T):
        analysis = analyse(matrix, 0.1, sparsity_threshold=0.0)
        values, vectors = np.linalg.eig(matrix)
        for value, vector in zip(analysis.eigenvalues, analysis.eigenvectors.T):
            k = np.argmin(np.abs(values.real - value) + np.abs(
                np.abs(vectors.real.T @ vector) - np.linalg.norm(vectors.real, axis=0)))
            expected = vectors[:, k].real / np.linalg.norm(vectors[:, k].real)
            assert abs(values[k].real - value) <= 1e-12 * np.abs(values).max()
            assert np.allclose(np.abs(expected @ vector), 1.0, atol=1e-12)


def test_analysis_of_a_singular_compliance_is_not_stable():
    """A singular C has no stiffness: smallest eigenvalue -inf, not stable."""
    analysis = analyse(np.diag([1.0, 1.0, 1.0, 1.0, 1.0, 0.0]), 0.1)
    assert analysis.smallest_stiffness_eigenvalue == -np.inf and not analysis.stable
    assert analyse(np.eye(6), 0.1).smallest_stiffness_eigenvalue == pytest.approx(1.0)


def _reference_arrangement(matrix, length, threshold, ratio):
    """Analyse as its docstring defines it, in plain numpy (no compiled parts)."""
    diagonal = np.sqrt(np.abs(np.diag(matrix)))
    bound = threshold * np.outer(diagonal, diagonal)
    np.fill_diagonal(bound, 0.0)
    sparse = np.where(np.abs(matrix) < bound, 0.0, matrix)
    values, vectors = np.linalg.eig(sparse)
    values, vectors = values.real, vectors.real
    scale = np.array([1.0, 1.0, 1.0, length, length, length])
    dominant = np.argmax(np.abs(vectors) * scale[:, None], axis=0)
    order = np.lexsort((-values, dominant))
    values, vectors, dominant = values[order], vectors[:, order], dominant[order]
    vectors = vectors / np.linalg.norm(vectors, axis=0)
    vectors *= np.sign(vectors[dominant, np.arange(6)])
    in_length_units = values / np.sum((vectors / scale[:, None]) ** 2, axis=0)
    return sparse, values, vectors, dominant, in_length_units >= ratio * in_length_units.max()


@pytest.mark.parametrize('seed', range(5))
def test_analysis_orders_scales_and_classifies_as_defined(seed):
    """C_s, the order (dominant axis, then decreasing xi), unit vectors and roles."""
    rng = np.random.default_rng(seed)
    for _ in range(40):
        root = rng.standard_normal((6, 6)) * np.repeat([1e-3, 3e-2], 3)
        matrix = root @ root.T
        if rng.random() < 0.3:  # repeated eigenvalues: the order among equals is kept
            matrix = np.diag(rng.choice([1e-6, 2e-6], 6))
        threshold, ratio = rng.uniform(0.0, 0.5), rng.uniform(0.05, 1.0)
        analysis = analyse(matrix, 0.1, sparsity_threshold=threshold, mobility_ratio=ratio)
        sparse, values, vectors, dominant, mobile = _reference_arrangement(
            matrix, 0.1, threshold, ratio)
        assert np.array_equal(analysis.sparse_matrix, sparse)
        assert np.allclose(analysis.eigenvalues, values, rtol=1e-10, atol=0.0)
        assert np.allclose(analysis.eigenvectors, vectors, atol=1e-9)
        assert analysis.labels == tuple(AXIS_LABELS[axis] for axis in dominant)
        assert analysis.roles == tuple('mobility' if m else 'constraint' for m in mobile)

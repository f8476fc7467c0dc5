"""
The fallback continuation (cdr_translator.solve.path_following) and its use by TranslatorSolver.

Torsion 40 N m stalls the default continuation (docs/explanation); the fallback takes it
to the wrench. Solves that converge without it are unchanged, failures come back as
results with a message.
"""

from cdr_translator import TranslatorSolver
from cdr_translator.params.translator_params import Accuracy
from cdr_translator.solve.path_following import hermite
import numpy as np
import pytest


def _solver(params, **options):
    """Build a solver as the hard-case suite does (no refinement, no branch following)."""
    return TranslatorSolver(params, time_limit_s=20.0, accuracy=Accuracy(0.0, 0.0),
                            follow_stable_branch=False, **options)


@pytest.fixture(scope='module')
def torsion(params):
    """Torsion 40 N m without and with the fallback."""
    moment = (0.0, 0.0, 40.0)
    return (_solver(params, fallback=False).solve((0.0, 0.0, 0.0), moment),
            _solver(params).solve((0.0, 0.0, 0.0), moment, compliance=True))


def test_torsion_40_stalls_without_the_fallback(torsion):
    """The default continuation alone still stalls (about two thirds of the way)."""
    stalled, _ = torsion
    assert not stalled.converged
    assert 'continuation stalled' in stalled.message


def test_torsion_40_converges_with_the_fallback(torsion):
    """Converged, stable, at the shot's rounding floor (said in the message)."""
    _, result = torsion
    assert result.converged, result.message
    assert 'fallback continuation' in result.message
    assert 'rounding floor' in result.message
    assert np.abs(result.residual_by_type['moment_nm']) < 1e-6
    assert result.residual_norm < 1e-7
    assert result.stable is True
    assert result.stability_margin > 0.0
    assert result.compliance is not None
    rotation = result.frames['de'][:3, :3]
    assert np.degrees(np.arccos((np.trace(rotation) - 1.0) / 2.0)) > 60.0  # big twist


def test_tracking_path_alone_converges(params):
    """path='tracking' solves the hard case without the default continuation."""
    result = _solver(params, path='tracking').solve((0.0, 0.0, 0.0), (0.0, 0.0, 40.0))
    assert result.converged, result.message
    assert 'continuation stalled' not in result.message


def test_default_path_results_are_unchanged(params):
    """A solve that converges without the fallback gives bit-identical unknowns with it."""
    for wrench in (((12.0, 0.0, 0.0), (0.0, 0.0, 0.0)), ((0.0, 0.0, 0.0), (0.0, 0.0, 10.0))):
        with_it = _solver(params).solve(*wrench)
        without = _solver(params, fallback=False).solve(*wrench)
        assert with_it.converged and without.converged
        np.testing.assert_array_equal(with_it.unknowns, without.unknowns)
        assert with_it.message == without.message


def test_failure_is_a_result_with_a_message(params):
    """Out of time in the tracking continuation: not converged, the reason in the message."""
    solver = TranslatorSolver(params.with_changes(spacers_per_joint=9), time_limit_s=0.5,
                              accuracy=Accuracy(0.0, 0.0), follow_stable_branch=False,
                              path='tracking')
    result = solver.solve((20.0, 0.0, 0.0))
    assert not result.converged
    assert 'tracking continuation failed' in result.message
    assert 'time limit' in result.message


def test_path_is_validated(params):
    """An unknown path is a ValueError naming the choices."""
    with pytest.raises(ValueError, match='path must be one of'):
        TranslatorSolver(params, path='arclength')


def test_hermite_predictor_is_exact_on_cubics():
    """Two points with values and tangents determine a cubic: extrapolated exactly."""
    def cubic(s):
        return np.array([1.0 + 2.0 * s - s ** 2 + 0.5 * s ** 3, -s ** 3])

    def slope(s):
        return np.array([2.0 - 2.0 * s + 1.5 * s ** 2, -3.0 * s ** 2])

    history = [(s, cubic(s), slope(s)) for s in (0.2, 0.5)]
    np.testing.assert_allclose(hermite(history, 0.9), cubic(0.9), rtol=1e-12)
    np.testing.assert_allclose(hermite(history[-1:], 0.9), cubic(0.5) + 0.4 * slope(0.5))

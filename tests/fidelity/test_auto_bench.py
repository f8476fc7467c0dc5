"""bench.auto_speed: its noisy random walks and its report of 'auto' against its target."""

from bench.auto_speed import markdown, random_walk, TARGET_RATIO
from cdr_translator.fidelity.validation import box_half_widths
import numpy as np
import pytest


@pytest.mark.parametrize('sigma', [0.02, 0.1, 0.4])
def test_random_walk_steps_at_sigma_within_the_force_bound(sigma):
    """Seeded walks from no load: force steps of sigma, moments in proportion, |f| <= 15 N."""
    walk = random_walk(sigma, count=2000)
    assert np.array_equal(walk, random_walk(sigma, count=2000))
    assert not np.array_equal(walk, random_walk(sigma, count=2000, seed=1))
    assert np.linalg.norm(walk[:, :3], axis=1).max() <= 15.0 * (1.0 + 1e-12)
    steps = np.diff(walk, axis=0)
    half = box_half_widths()
    for part, bound, scale in ((slice(0, 3), 15.0, sigma),
                               (slice(3, 6), 15.0 * half[3] / half[0], sigma * half[3] / half[0])):
        free = np.linalg.norm(walk[:, part], axis=1) < bound * (1.0 - 1e-9)  # not scaled back
        both = free[1:] & free[:-1]
        assert both.sum() > 200
        assert np.std(steps[both, part]) == pytest.approx(scale, rel=0.1)


def test_random_walk_rejects_a_sigma_that_is_not_positive():
    """A zero or NaN step size is named in the error."""
    for sigma in (0.0, float('nan')):
        with pytest.raises(ValueError, match='sigma'):
            random_walk(sigma)


def test_report_prints_the_ratio_against_the_target_beside_the_times():
    """Each stream's row: full's and auto's times, their ratio, the target and whether met."""
    row = {'full_per_answer_s': 150e-6, 'auto_per_answer_s': 100e-6, 'ratio': 1.5,
           'levels': {'linear': 9, 'full': 1}, 'counts': {'expansions': 1, 'checks': 2,
                                                          'failed_checks': 0},
           'time_by_kind_s': {'expansion': [1, 2e-3]}, 'around_s': 1e-3,
           'max_position_from_full_m': 5e-4, 'max_angle_from_full_deg': 0.1,
           'converged': 10, 'reduced_accuracy_met': 9, 'reduced': 9, 'stable_stated': 10,
           'largest_step_scale': 0.005, 'largest_force_n': 18.0}
    text = markdown({'date': 'now', 'machine': 'here', 'load_before': '0', 'load_after': '0',
                     'passes': 3, 'streams': {'the sequence': row}})
    line = next(line for line in text.splitlines() if line.startswith('| the sequence | 150'))
    assert '| 150.0 | 100.0 | 1.50× |' in line
    assert f'>= {TARGET_RATIO:g}×' in line and line.endswith('| no |')

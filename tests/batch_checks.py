"""Checks shared by the batch tests: a wrench sequence, and rows against single solves."""

import numpy as np
import pytest

#: Keys of BatchResult.row compared with SolveResult.to_dict (the message is '' for good rows).
SHARED_KEYS = ('converged', 'force_n', 'moment_nm', 'end_disk_position_m',
               'end_disk_quaternion_xyzw', 'pj_bending_deg', 'pj_direction_deg',
               'dj_bending_deg', 'dj_direction_deg', 'fidelity', 'error_estimate_m',
               'error_estimate_deg', 'accuracy_met', 'stable')


def sequence(count=40):
    """Return a smooth sequence of forces and moments (N, N m) about the paper's 12 N case."""
    t = np.linspace(0.0, 1.0, count)
    forces = np.stack([12.0 + 4.0 * np.sin(2 * np.pi * t), 3.0 * np.sin(3 * np.pi * t),
                       -2.0 * np.sin(1.4 * np.pi * t)], axis=1)
    moments = np.stack([0.05 * np.sin(2.6 * np.pi * t), 0.04 * np.cos(1.8 * np.pi * t),
                        0.06 * np.sin(4.2 * np.pi * t)], axis=1)
    return forces, moments


def good(summary):
    """Say whether a to_dict summary is a good row (BatchResult's empty message)."""
    return (summary['converged'] and summary['stable'] is not False
            and summary['accuracy_met'] is not False)


def assert_rows_equal(batch, results, compliance=False):
    """Assert that each row of ``batch`` says what its single solve's to_dict says (1e-9 m)."""
    assert len(batch) == len(results)
    for index, result in enumerate(results):
        summary, row = result.to_dict(), batch.row(index)
        for key in SHARED_KEYS:
            expected, actual = summary[key], row[key]
            if isinstance(expected, list):
                assert np.allclose(actual, expected, rtol=0.0, atol=1e-9), (index, key)
            elif isinstance(expected, float):
                assert actual == pytest.approx(expected, rel=1e-9, abs=1e-9), (index, key)
            else:
                assert actual == expected, (index, key, actual, expected)
        assert row['message'] == ('' if good(summary) else summary['message'])
        if compliance:
            assert np.allclose(row['compliance'], summary['compliance'], rtol=1e-9,
                               atol=1e-15)
        assert np.allclose(batch.end_disk_position[index], result.end_disk_position,
                           rtol=0.0, atol=1e-9)

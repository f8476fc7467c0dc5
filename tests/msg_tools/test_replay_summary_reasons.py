"""The replay summary's reasons for flagged and failed estimates: kinds, counts, merges."""

from cdr_wire.reader import ReadReport
from msg_tools.replay_summary import reason_kind, REASONS_SHOWN, ReplaySummary
import pytest


@pytest.mark.parametrize('flag, kind', [
    ('near a bifurcation (stability margin 0.0184): another wrench may match this pose',
     'near a bifurcation'),
    ('uninformative: the force spread 24.8 N exceeds the force it reports (5.11 N)',
     'uninformative'),
    ('accuracy target missed (posterior standard deviation): fx 3.26 > 0.5',
     'accuracy target missed'),
    ('the pose is further from the model than its covariance allows (chi-square tail '
     'probability 0 at 6 degrees of freedom)',
     'the pose is further from the model than its covariance allows'),
    ('time limit reached', 'time limit reached'),
])
def test_a_flag_s_kind_leaves_out_what_differs_from_pose_to_pose(flag, kind):
    """The text before any ':', without parenthesized asides."""
    assert reason_kind(flag) == kind


def test_reasons_count_once_per_estimate_rank_and_merge():
    """Counted once per estimate and kind, most frequent first, the rest summed up."""
    first, later = (ReplaySummary(ReadReport('in.mcap', 0), ['/wrench'], []) for _ in range(2))
    first.count_reasons(['uninformative: the force spread 3 N exceeds the force (1 N)',
                         'uninformative: the moment spread 0.3 N m exceeds the moment (0 N m)',
                         'accuracy target missed (posterior standard deviation): fx 3 > 0.5'])
    later.count_reasons(['time limit reached', 'accuracy target missed: fy 2 > 0.5'])
    first.merge(later)
    assert first.pose_reasons == {'uninformative': 1, 'accuracy target missed': 2,
                                  'time limit reached': 1}
    assert first.reasons_text() == ('2 accuracy target missed, 1 time limit reached, '
                                    '1 uninformative')
    for letter in 'abcdef':
        first.count_reasons([f'reason {letter}'])
    assert len(first.pose_reasons) == 9
    assert first.reasons_text().startswith('2 accuracy target missed, 1 reason a, ')
    assert first.reasons_text().endswith(f', {9 - REASONS_SHOWN} other reason(s)')

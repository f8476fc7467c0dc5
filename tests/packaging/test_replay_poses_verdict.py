"""The replay-with-poses bench judges its ratio on the confidence interval of the median."""

from bench.replay_poses import verdict


def test_met_only_when_the_whole_interval_is_within_the_target():
    """Fifteen rounds all near 2.5 are met; all near 3.5 missed."""
    low = [2.4 + 0.01 * index for index in range(15)]
    high = [3.4 + 0.01 * index for index in range(15)]
    assert verdict(low).startswith('met (median 95% interval 2.4')
    assert verdict(high).startswith('missed (median 95% interval 3.4')


def test_a_median_at_the_target_is_not_decided():
    """Rounds spread across the target decide nothing, whichever side the median is on."""
    spread = [2.2, 2.5, 2.7, 2.8, 2.9, 2.95, 2.98, 2.99, 3.05, 3.1, 3.15, 3.2, 3.3, 3.4, 3.8]
    assert verdict(spread).startswith('not decided (median 95% interval 2.8-3.2')
    assert verdict([ratio + 0.02 for ratio in spread]).startswith('not decided')


def test_five_rounds_cannot_decide():
    """Five rounds have no 95 % interval of their median: the verdict says so."""
    assert verdict([2.0, 2.1, 2.2, 2.3, 2.4]) == (
        'not decided (5 rounds are too few for a 95% interval of the median)')
    assert verdict([2.0 + 0.1 * index for index in range(6)]).startswith('met')

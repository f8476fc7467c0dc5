"""The speed-against-error report's batch-throughput table, from the JSON form of a run."""

from bench.speed_vs_error_report import batch_throughput


def test_batch_throughput_gives_answers_per_second_against_one_at_a_time():
    """Answers/s is one over the time per answer; the ratio compares with mean single solves."""
    rows = [{'level': 'cc', 'setting': 'one arc per joint',
             'sequence': {'batch_per_answer_s': 1e-5, 'mean_time_s': 4e-5,
                          'median_time_s': 2e-5}},
            {'level': 'full', 'setting': '8 steps (default)',
             'sequence': {'batch_per_answer_s': 5e-4, 'mean_time_s': 2.5e-4,
                          'median_time_s': 1e-4}}]
    lines = batch_throughput(rows, 1000)
    assert lines[1] == '## Batch throughput' and '1000-wrench sequence' in lines[3]
    assert lines[-2:] == ['| cc | one arc per joint | 100,000 | 25,000 | 4× |',
                          '| full | 8 steps (default) | 2,000 | 4,000 | 0.5× |']

"""
The Markdown report of bench.speed_vs_error, written from its JSON form.

Kept apart from the measuring so that ``python -m bench.speed_vs_error --redraw`` writes
the same tables again from speed_vs_error.json without measuring.
"""

import statistics
from typing import List, Sequence, Tuple

from cdr_translator.fidelity import validation


def format_ms(seconds: float) -> str:
    """Return ``seconds`` in milliseconds, three significant digits below 100 ms."""
    milliseconds = 1e3 * seconds
    return f'{milliseconds:.3g}' if milliseconds < 100 else f'{milliseconds:.0f}'


def _ratio(reference_s: float, seconds: float) -> str:
    value = reference_s / seconds
    return f'{value:,.0f}×' if value >= 10 else f'{value:.2g}×'


def _err(value: float, digits: int = 3) -> str:
    return '0' if value == 0.0 else f'{value:.{digits}g}'


def batch_throughput(table_rows: List[dict], sequence_length: int) -> List[str]:
    """Return the lines of the batch-throughput table: answers/s of one solve_many call."""
    lines = ['', '## Batch throughput', '',
             f'One `solve_many` call over the {sequence_length}-wrench sequence (fastest of '
             'three passes, each from a fresh solver), against the same answers from one '
             '`solve()` call each (their mean time: both include the few slow answers); the '
             'errors are the sequence columns above.', '',
             '| level | setting | batch answers/s | one solve() at a time, answers/s | '
             'batch against one at a time |', '|---|---|---|---|---|']
    for row in table_rows:
        sequence = row['sequence']
        batch, single = 1.0 / sequence['batch_per_answer_s'], 1.0 / sequence['mean_time_s']
        lines.append(f"| {row['level']} | {row['setting']} | {batch:,.0f} | {single:,.0f} | "
                     f'{batch / single:.2g}× |')
    return lines


def _levels(series: dict) -> str:
    """Return the levels a series used, most used first."""
    return ', '.join(f'{level} {count}' for level, count in sorted(
        series['levels'].items(), key=lambda item: -item[1]))


def _budget_row(name: str, series: dict, full: dict, budget: Tuple[float, float]) -> str:
    """Return one line of a budget table: times, against the full model's, errors, levels."""
    inside = series['max_position_m'] <= budget[0] and series['max_angle_deg'] <= budget[1]
    counts = series.get('auto_counts', {})
    checks = (f"; checks {counts['checks']} ({counts['failed_checks']} failed), "
              f"expansions {counts['expansions']}" if counts else '')
    return (f"| {name} | {_levels(series)}{checks} | {format_ms(series['median_time_s'])} "
            f"({_ratio(full['median_time_s'], series['median_time_s'])}) | "
            f"{format_ms(series['mean_time_s'])} "
            f"({_ratio(full['mean_time_s'], series['mean_time_s'])}) | "
            f"{format_ms(series['batch_per_answer_s'])} "
            f"({_ratio(full['batch_per_answer_s'], series['batch_per_answer_s'])}) | "
            f"{_err(1e3 * series['max_position_m'])} | {_err(series['max_angle_deg'])} | "
            f"{'yes' if inside else 'NO'} |")


def budget_tables(table_rows: List[dict], budgets: Sequence[Tuple[float, float]],
                  sequence_length: int, random_count: int) -> List[str]:
    """
    Return the tables of the 'auto' rows per budget: along the sequence, on random wrenches.

    Times per answer with their speed-up over the full model (8 steps) in the same run:
    median and mean of one ``solve`` at a time, and ``solve_many`` (batch).
    """
    full = next(row for row in table_rows if row['setting'] == '8 steps (default)')
    header = ['| budget | levels used | median (ms) (× full) | mean (ms) (× full) | '
              'batch (ms) (× full) | max position error (mm) | max angle error (°) | '
              'inside the budget |', '|---|---|---|---|---|---|---|---|']
    lines = ['', '## Error budget along the sequence', '',
             f'The {sequence_length}-wrench sequence; × full: how many times faster than the '
             'full model (8 steps) in the same run.', ''] + header
    auto = [row for row in table_rows if row['level'] == 'auto']
    for row in auto:
        budget = next(b for b in budgets
                      if row['setting'] == f'budget {1e3 * b[0]:g} mm, {b[1]:g} deg')
        lines.append(_budget_row(row['setting'][7:], row['sequence'], full['sequence'],
                                 budget))
    if random_count and full.get('random'):
        lines += ['', '## Error budget on random wrenches', '',
                  f'{random_count} seeded wrenches uniform in the validated box scaled by a '
                  'size uniform in [0, 1), answered one after another (each a jump).',
                  ''] + header
        for row in auto:
            budget = next(b for b in budgets
                          if row['setting'] == f'budget {1e3 * b[0]:g} mm, {b[1]:g} deg')
            lines.append(_budget_row(row['setting'][7:], row['random'], full['random'],
                                     budget))
    return lines


def markdown(report: dict, paper_scenes: Sequence[str],
             budgets: Sequence[Tuple[float, float]], sequence_length: int) -> str:
    """
    Return the Markdown report of a speed_vs_error ``report`` (its JSON form).

    ``paper_scenes``: the static scenes whose median is the cold time; ``budgets``: the
    (position m, angle deg) budgets of the 'auto' rows; ``sequence_length``: wrenches in
    the warm-started sequence.
    """
    table_rows = report['rows']
    scenes = list(table_rows[0]['static'])
    paper = report['paper_baseline']
    paper_mean = report['paper_mean_s']
    lines = ['# Speed against error', '',
             f"Measured {report['date']} on {report['machine']}; load average "
             f"{report['load_before']} before and {report['load_after']} after the run "
             '(the machine was shared with other jobs: times are pessimistic and vary by '
             'tens of percent between runs).', '',
             'Reference: the full model at 32 RK4 steps per disk interval, residual 1e-12. '
             'Errors: end-disk position |p - p_ref| and the largest of the PJ/DJ bending-angle '
             'errors and the end-disk orientation error. Times: wall clock of `solve()`, '
             'median; static scenes are cold solves (from the unloaded state), the sequence '
             f'is {sequence_length} wrenches warm-started one after the other; "batch" is '
             'the same sequence in one `solve_many` call, time per answer (its rows equal '
             'the single solves: largest distance in the last column).', '']
    if paper:
        lines += ["Paper baseline (`method='paper'`: the same model interpreted, "
                  'Levenberg-Marquardt with a one-column-per-residual FD Jacobian, paper '
                  'tolerances, cold): ' + ', '.join(
                      f"{name} {value['time_s']:.1f} s ({value['position_m'] * 1e3:.3g} mm, "
                      f"{value['angle_deg']:.2g}° from the reference)"
                      for name, value in paper.items())
                  + f'; mean {paper_mean:.1f} s is the divisor of every "× paper" column.', '']
    lines += ['| level | setting | unknowns | cold, paper cases (ms) | × paper | static: max '
              'position error (mm) | static: max angle error (°) | sequence median (ms) | '
              '× paper | sequence: max position error (mm) | sequence: max angle error (°) | '
              'batch per answer (µs) | batch rows from single solves (m) |',
              '|---|---|---|---|---|---|---|---|---|---|---|---|---|']
    for row in table_rows:
        cold = statistics.median(row['static'][name]['time_s'] for name in paper_scenes)
        static_position = max(value['position_m'] for value in row['static'].values())
        static_angle = max(value['angle_deg'] for value in row['static'].values())
        sequence = row['sequence']
        lines.append(
            f"| {row['level']} | {row['setting']} | {row['unknowns']} | {format_ms(cold)} | "
            f"{_ratio(paper_mean, cold) if paper_mean else '-'} | "
            f'{_err(1e3 * static_position)} | {_err(static_angle)} | '
            f"{format_ms(sequence['median_time_s'])} | "
            f"{_ratio(paper_mean, sequence['median_time_s']) if paper_mean else '-'} | "
            f"{_err(1e3 * sequence['max_position_m'])} | {_err(sequence['max_angle_deg'])} | "
            f"{1e6 * sequence['batch_per_answer_s']:.3g} | "
            f"{_err(sequence['batch_deviation_m'], 2)} |")
    lines += batch_throughput(table_rows, sequence_length)
    lines += ['', '## Errors per static scene (position mm / angle °; level used by auto)', '',
              '| level | setting | ' + ' | '.join(scenes) + ' |',
              '|---|---|' + '---|' * len(scenes)]
    for row in table_rows:
        cells = []
        for name in scenes:
            value = row['static'][name]
            cell = f"{_err(1e3 * value['position_m'], 2)} / {_err(value['angle_deg'], 2)}"
            if row['level'] == 'auto':
                cell += f" ({value['fidelity']})"
            if not value['converged']:
                cell += ' (not converged)'
            cells.append(cell)
        lines.append(f"| {row['level']} | {row['setting']} | " + ' | '.join(cells) + ' |')
    lines += budget_tables(table_rows, budgets, sequence_length,
                           report.get('random_count', 0))
    compliance = report['compliance']
    lines += ['', '## Compliance and node', '',
              '| what | time |', '|---|---|',
              '| implicit C after a cold solve (median over the scenes) | '
              f"{format_ms(compliance['implicit_after_cold_median_s'])} ms |",
              '| implicit C along the sequence (warm solves of '
              f"{format_ms(compliance['warm_solve_median_s'])} ms) | "
              f"{format_ms(compliance['implicit_along_sequence_median_s'])} ms |",
              '| C by central differences of 12 full solves '
              '(`finite_difference_compliance`, the check) | '
              f"{format_ms(compliance['finite_difference_s'])} ms |"]
    for level, seconds in compliance['reduced_median_s'].items():
        lines.append(f'| C of the {level} level (central differences of its own solves) | '
                     f'{format_ms(seconds)} ms |')
    lines.append('| linear level: expansion (C, dx/dw, frame and point sensitivities) about a '
                 'new cached solution | '
                 f"{format_ms(compliance['linear_tangent_build_median_s'])} ms |")
    node = report['node']
    if 'error' in node:
        lines.append(f"| translator_node sustained rate | not measured: {node['error']} |")
    else:
        lines.append(f"| translator_node sustained rate ({node['offered_hz']:.0f} Hz offered "
                     f"for {node['seconds']:g} s over DDS by a client sharing the 2 cores, no "
                     'MCAP log, latest wins) | '
                     f"{node['answers_per_s']:.0f} answers/s ({node['received']} received, "
                     f"median latency {node['latency_p50_ms']:.1f} ms) |")
    lines += ['', '## Targets', '', '| target | measured |', '|---|---|']
    lines += [f'| {target} | {value} |' for target, value in report['targets']]
    bounds = report.get('validation')
    if bounds:
        lines += ['', '## Validated ranges (config/fidelity_validation.yaml)', '',
                  'Largest errors over the samples in each nested box |f_i| <= s·'
                  f'{validation.BOX_FORCE_N[0]:g} N, |m_i| <= s·{validation.BOX_MOMENT_NM[0]:g} '
                  "N m (for 'linear': offsets from the cached wrench).", '',
                  '| level | s | samples | max position error (mm) | max angle error (°) |',
                  '|---|---|---|---|---|']
        for level, bound in bounds.items():
            for scale, count, position, angle in zip(bound['scales'], bound['samples'],
                                                     bound['max_position_error_m'],
                                                     bound['max_angle_error_deg']):
                lines.append(f'| {level} | {scale:g} | {count} | {_err(1e3 * position)} | '
                             f'{_err(angle)} |')
    return '\n'.join(lines) + '\n'

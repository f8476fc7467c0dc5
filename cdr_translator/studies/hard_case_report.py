"""The hard-case suite's Markdown report: per-case table, convergence rates, buckling, failures."""

import math
from typing import Optional, Sequence

from .buckling import Buckling, HeldBuckling
from .hard_cases import CaseReport, Wrench


def _wrench_text(wrench: Wrench) -> str:
    force, moment = wrench
    text = 'F (' + ', '.join(f'{value:g}' for value in force) + ') N'
    if any(moment):
        text += ', M (' + ', '.join(f'{value:g}' for value in moment) + ') N m'
    return text


def _yes_no(value: Optional[bool]) -> str:
    return 'unknown' if value is None else ('yes' if value else 'no')


def _held_text(held: HeldBuckling, free: Optional[Buckling]) -> str:
    ratio = ('' if free is None else
             f', {held.critical_load_n / free.critical_load_n:.1f} times the free-end load')
    above = held.above
    return (
        f'**Axial buckling load with both end disks held: {held.critical_load_n:.1f} N**'
        f'{ratio} (smallest singular value of J_d {held.smallest_singular_value:.1e}, '
        f'against {held.unloaded_singular_value:.1e} unloaded); clamped-guided estimate '
        f'{held.estimate_n:.1f} N '
        f'({100.0 * (held.critical_load_n / held.estimate_n - 1.0):+.1f} %). Held re-solves '
        f'perturbed along the buckling mode: 2 % below, back to the straight state: '
        f'{_yes_no(held.below.converged and not held.below.left_straight)}; 2 % above, to a '
        f'buckled state: {_yes_no(above.left_straight)} (compression '
        f'{above.compression_n:.1f} -> {above.compression_after_n:.1f} N).')


def markdown_report(reports: Sequence[CaseReport], buckling: Optional[Buckling] = None,
                    held: Optional[HeldBuckling] = None) -> str:
    """Return the report: per-case table, convergence rates, buckling (free, held), failures."""
    solves = [outcome for report in reports for outcome in report.loads]
    converged = sum(outcome.converged for outcome in solves)
    lines = [
        '| case | solves | outcome | iterations | time (ms) | residual | stable | '
        'PJ bending (deg) | end-disk rotation (deg) |',
        '|---|---|---|---|---|---|---|---|---|',
    ]
    for report in reports:
        final = report.final
        lines.append(
            f'| {report.case.name} | {len(report.loads)} | {report.outcome} | '
            f'{report.iterations} | {1e3 * report.time_s:.1f} | {report.residual:.1e} | '
            f'{_yes_no(report.stable)} | {math.degrees(final.pj_bending[0]):.2f} | '
            f'{math.degrees(final.end_disk_rotation):.2f} |')
    verified = sum(report.verified for report in reports)
    lines += [
        '',
        f'**Convergence rate: {converged}/{len(solves)} solves '
        f'({100.0 * converged / len(solves):.1f} %)**; cases converged: '
        f'{sum(report.converged for report in reports)}/{len(reports)}; verified (at the '
        f"case's or a finer discretization): {verified}/{len(reports)}.",
    ]
    if buckling is not None:
        lines += [
            '',
            f'**Axial buckling load: {buckling.critical_load_n:.3f} N** (smallest singular '
            f'value of the Jacobian {buckling.smallest_singular_value:.1e}, against '
            f'{buckling.unloaded_singular_value:.1e} unloaded); Euler estimate '
            f'{buckling.euler_estimate_n:.3f} N '
            f'({100.0 * (buckling.critical_load_n / buckling.euler_estimate_n - 1.0):+.1f} %). '
            f'Stable 2 % below: {_yes_no(buckling.stable_below)}; 2 % above: '
            f'{_yes_no(buckling.stable_above)}.',
        ]
    if held is not None:
        lines += ['', _held_text(held, buckling)]
    unstable = [report for report in reports if report.stable is False]
    unknown = [report for report in reports if report.converged and report.stable is None]
    failing = [report for report in reports if not report.verified]
    for title, chosen, text in (
            ('Not verified or not converged', failing, lambda r: r.outcome),
            ('Unstable equilibria', unstable, lambda r: r.stability),
            ('Stability unknown', unknown, lambda r: r.stability)):
        if chosen:
            lines += ['', f'{title}:', '']
            lines += [f'* {report.case.name}: {text(report)}' for report in chosen]
    return '\n'.join(lines) + '\n'

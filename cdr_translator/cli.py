"""
Command line: argument parsing and printing only; the physics lives in the solver.

    python -m cdr_translator solve --force FX FY FZ [--moment MX MY MZ] [--compliance]
                                   [--verify] [--fidelity full|rod|cc|auto
                                   [--max-position-error M] [--max-angle-error DEG]]
                                   [--params FILE] [--json]
    python -m cdr_translator paper [--params FILE]
    python -m cdr_translator delta --sliders Q1 Q2 Q3 [--payload FX FY FZ]
                                   [--fidelity LEVEL [BUDGET]] [--params FILE] [--json]
    python -m cdr_translator delta-ik --target X Y Z [--payload FX FY FZ]
                                      [--fidelity LEVEL [BUDGET]] [--params FILE] [--json]
    python -m cdr_translator atlas --grid N [--payload FX FY FZ]... [--params FILE]...
                                   --out PATH.zarr [--workers K] [--scheduler ADDRESS]
                                   [--chunk-size M] [--plot] [--fidelity LEVEL [BUDGET]]
    python -m cdr_translator compile [--params FILE]

    LEVEL: full|rod|cc|auto, the legs' model level; BUDGET (auto): [--max-position-error M]
    [--max-angle-error DEG], each leg's error budget.

Exit codes: 0 converged (and stable), 3 not converged (the result is still printed; for
``paper``, either case), 2 bad input (every key of the params file is checked, as the nodes
do), 4 ``solve`` or ``delta`` converged to an unstable equilibrium (``stable: false`` in the
output: past a bifurcation no stable branch was found; docs/explanation). delta-ik: 0
only when the target is reached; an unreachable target prints the nearest reachable point
and exits 3. atlas: 0 when every sample converged, 3 otherwise. Every command: 130 on
Ctrl-C, 141 when standard output was closed early (``| head``), no traceback. ``--json``
prints strict JSON: a non-finite number is null.
"""

import argparse
import math
import sys
import time
from typing import Any, Callable, Dict, List, Optional, Tuple, Union

import numpy as np

from . import _jit
from .analysis.compliance import MOBILITY_RATIO, SPARSITY_THRESHOLD
from .bvp.problem import JACOBIANS
from .console import add_command, CommandParser, json_text, run_command
from .fidelity import FIDELITIES, FidelitySolver
from .interface.fidelity_options import add_fidelity_arguments
from .interface.settings import CdrSettings, TranslatorSettings
from .params.paper import TABLE_II
from .params.translator_params import (Accuracy, DEFAULT_PARAMS_PATH, ParameterError,
                                       TranslatorParams)
from .robot.atlas import run_cli as run_atlas
from .robot.delta import DeltaRobot
from .robot.held_leg import axial_load_text
from .robot.inverse import InverseResult
from .robot.levels import ROBOT_FIDELITIES
from .robot.result import DeltaResult
from .robot.samples import AtlasSpec, solve_chunk
from .solve.continuation import LIFT_FROM_SPACERS
from .solve.result import SolveResult
from .solve.solver import METHODS, TranslatorSolver

EXIT_CONVERGED = 0
EXIT_BAD_INPUT = 2
EXIT_NOT_CONVERGED = 3
EXIT_UNSTABLE = 4


def _parser() -> argparse.ArgumentParser:
    parser = CommandParser(
        prog='python -m cdr_translator',
        description='Cosserat-rod kinestatics of the dual-continuum-joint translator.')
    commands = parser.add_subparsers(dest='command', required=True)
    solve = add_command(commands, 'solve', 'solve one end-disk wrench',
                        'Prints the bending angles, the end-disk pose and the verdicts '
                        '(converged, stable, accuracy); --json one object.')
    solve.add_argument('--force', nargs=3, type=float, required=True,
                       metavar=('FX', 'FY', 'FZ'), help='force on the end disk, N, in {pe}')
    solve.add_argument('--moment', nargs=3, type=float, default=(0.0, 0.0, 0.0),
                       metavar=('MX', 'MY', 'MZ'), help='moment on the end disk, N m, in {pe}')
    solve.add_argument('--method', choices=METHODS, default='fast',
                       help="'paper' runs the published numerics (slow baseline)")
    solve.add_argument('--max-iterations', type=int, default=None,
                       help='iterations per continuation step (Newton, or Levenberg-'
                            'Marquardt for --method paper)')
    solve.add_argument('--time-limit', type=float, default=10.0,
                       help='give up after this many seconds (default: %(default)s)')
    solve.add_argument('--compliance', action='store_true',
                       help='add the 6x6 end-disk compliance and its primary-mobility analysis')
    solve.add_argument('--verify', action='store_true',
                       help='re-check the solution independently (cdr_translator.solve.verify)')
    solve.add_argument('--sparsity-threshold', type=float, default=SPARSITY_THRESHOLD,
                       help='C_s drops |C_ij| below this times sqrt(|C_ii C_jj|) '
                            '(default: %(default)s)')
    solve.add_argument('--mobility-ratio', type=float, default=MOBILITY_RATIO,
                       help='an eigen-twist at least this fraction of the most compliant one '
                            'is a primary mobility (default: %(default)s)')
    add_fidelity_arguments(solve)
    solve.add_argument('--json', action='store_true', help='print one JSON object')
    paper = add_command(commands, 'paper', "solve the paper's Table II cases and compare")
    delta = add_command(commands, 'delta', 'Continuum Delta Robot forward statics: platform '
                                           'pose and leg loads for slider positions')
    delta.add_argument('--sliders', nargs=3, type=float, required=True,
                       metavar=('Q1', 'Q2', 'Q3'), help='slider positions from home, m')
    delta.add_argument('--json', action='store_true', help='print one JSON object')
    inverse = add_command(commands, 'delta-ik', 'Continuum Delta Robot inverse statics: '
                                                'slider positions for a platform target')
    inverse.add_argument('--target', nargs=3, type=float, required=True,
                         metavar=('X', 'Y', 'Z'), help='platform centre, m, world frame')
    inverse.add_argument('--json', action='store_true', help='print one JSON object')
    for command in (delta, inverse):
        _add_payload_arguments(command)
    atlas = add_command(
        commands, 'atlas', 'Continuum Delta Robot workspace / stiffness atlas over the slider '
                           'box x payloads x params files, on Dask, into Zarr')
    atlas.add_argument('--grid', type=int, required=True, metavar='N',
                       help='N slider positions per axis over the stroke (N^3 samples)')
    atlas.add_argument('--payload', nargs=3, type=float, action='append', default=None,
                       metavar=('FX', 'FY', 'FZ'),
                       help='force on the platform, N, world frame; repeat for several '
                            '(default: none)')
    atlas.add_argument('--params', action='append', default=None, metavar='FILE',
                       help='ROS 2 params YAML; repeat for design variants (default: '
                            f'{DEFAULT_PARAMS_PATH})')
    atlas.add_argument('--out', required=True, metavar='PATH.zarr', help='Zarr store')
    atlas.add_argument('--workers', type=int, default=None, metavar='K',
                       help='worker processes of the local cluster (default: one per core)')
    atlas.add_argument('--scheduler', default=None, metavar='ADDRESS',
                       help='use this running Dask scheduler (e.g. tcp://10.0.0.5:8786)')
    atlas.add_argument('--chunk-size', type=int, default=None, metavar='M',
                       help='samples per chunk (default: N*N, one slider-3 layer)')
    atlas.add_argument('--time-limit', type=float, default=30.0,
                       help='per forward solve, s (default: %(default)s)')
    atlas.add_argument('--plot', action='store_true',
                       help='draw the workspace and stiffness maps (PNG beside the store)')
    atlas.add_argument('--no-progress', action='store_true', help='no progress bar')
    for command in (delta, inverse, atlas):
        _add_level_arguments(command)
    compile_ = add_command(
        commands, 'compile', "compile the numba kernels into numba's cache (make setup's "
                             'last step), so that no node or solve compiles them later')
    for command in (solve, paper, delta, inverse, compile_):
        command.add_argument('--params', default=str(DEFAULT_PARAMS_PATH),
                             help='ROS 2 params YAML (default: %(default)s)')
    return parser


def _add_payload_arguments(command: argparse.ArgumentParser) -> None:
    """Add the payload and time-limit options shared by delta and delta-ik."""
    command.add_argument('--payload', nargs=3, type=float, default=(0.0, 0.0, 0.0),
                         metavar=('FX', 'FY', 'FZ'), help='force on the platform, N, world frame')
    command.add_argument('--payload-moment', nargs=3, type=float, default=(0.0, 0.0, 0.0),
                         metavar=('MX', 'MY', 'MZ'),
                         help='moment on the platform, N m, world frame')
    command.add_argument('--payload-offset', nargs=3, type=float, default=(0.0, 0.0, 0.0),
                         metavar=('X', 'Y', 'Z'),
                         help='where the force acts, m, platform frame (default: its centre)')
    command.add_argument('--time-limit', type=float, default=30.0,
                         help='give up a forward solve after this many seconds '
                              '(default: %(default)s)')


def _add_level_arguments(command: argparse.ArgumentParser) -> None:
    """Add the legs' fidelity level and its error budget (delta, delta-ik, atlas)."""
    command.add_argument('--fidelity', choices=ROBOT_FIDELITIES, default='full',
                         help="the legs' model level (docs/howto/robot.md); auto: the "
                              'cheapest level within the budget at every leg, else full')
    command.add_argument('--max-position-error', type=float, default=0.0, metavar='M',
                         help="error budget of --fidelity auto: each leg's end disk, m")
    command.add_argument('--max-angle-error', type=float, default=0.0, metavar='DEG',
                         help="error budget of --fidelity auto: each leg's angles, deg")


def _table(result: SolveResult) -> str:
    data = result.to_dict()
    rows = [
        ('converged', f"{data['converged']} ({data['message']})"),
        ('iterations', data['iterations']),
        ('residual norm', f"{data['residual_norm']:.3e}"),
        ('PJ bending / direction', f"{data['pj_bending_deg']:.3f} deg / "
                                   f"{data['pj_direction_deg']:.3f} deg"),
        ('DJ bending / direction', f"{data['dj_bending_deg']:.3f} deg / "
                                   f"{data['dj_direction_deg']:.3f} deg"),
        ('end-disk rotation', f"{data['end_disk_rotation_deg']:.4f} deg"),
        ('end-disk position', '[' + ', '.join(
            f'{1e3 * v:.4f}' for v in data['end_disk_position_m']) + '] mm'),
        ('end-disk quaternion xyzw', '[' + ', '.join(
            f'{v:.6f}' for v in data['end_disk_quaternion_xyzw']) + ']'),
        ('max arc deviation PJ / DJ', f"{data['max_arc_deviation_mm']['pj']:.4f} mm / "
                                      f"{data['max_arc_deviation_mm']['dj']:.4f} mm"),
        ('solve time', f"{1e3 * data['solve_time_s']:.2f} ms"),
        ('fidelity', data['fidelity']),
    ]
    if 'stability_margin' in data:
        margin = data['stability_margin']
        rows.append(('stable / margin', f"{data['stable']} / "
                                        + ('n/a' if margin is None else f'{margin:.4g}')))
    analysis = result.compliance
    if analysis is not None:
        rows.append(('compliance C (SI)', ''))
        rows.extend(('', '  '.join(f'{v:+.4e}' for v in row)) for row in analysis.matrix)
        rows.append(('eigenvalues of C_s', '  '.join(
            f'{label}: {value:.4e}' for label, value in zip(analysis.labels,
                                                            analysis.eigenvalues))))
        rows.append(('primary mobility', ', '.join(analysis.primary_mobility)))
        rows.append(('compliance time', f'{1e3 * analysis.time_s:.2f} ms'))
    if result.verification is not None:
        rows.append(('verified', f'{result.verification.passed} '
                                 f'({result.verification.message})'))
    width = max(len(name) for name, _ in rows)
    return '\n'.join(f'{name:<{width}}  {value}' for name, value in rows)


def _delta_table(result: DeltaResult) -> str:
    data = result.to_dict()
    rows = [('converged', f"{data['converged']} ({data['message']})"),
            ('platform position', _mm(data['platform_position_m'])),
            ('platform displacement', _mm(data['platform_displacement_m'])),
            ('platform rotation', f"{data['platform_rotation_deg']:.3e} deg"),
            ('equilibrium residual', f"{data['equilibrium_residual_norm']:.3e} (N, N m)"),
            ('solve time', f"{1e3 * data['solve_time_s']:.1f} ms "
                           f"({_counted(data['leg_solves'], 'leg solve')})")]
    rows.extend(_stability_rows(data))
    for leg, ((pj, dj), wrench) in enumerate(zip(data['leg_bending_deg'],
                                                 data['leg_tip_wrench']), start=1):
        rows.append((f'leg {leg} PJ / DJ bending', f'{pj:.3f} deg / {dj:.3f} deg'))
        rows.append((f'leg {leg} tip force (leg frame)',
                     '[' + ', '.join(f'{v:.4f}' for v in wrench[:3]) + '] N'))
        rows.append((f'leg {leg} tip moment (leg frame)',
                     '[' + ', '.join(f'{v:.5f}' for v in wrench[3:]) + '] N m'))
    width = max(len(name) for name, _ in rows)
    return '\n'.join(f'{name:<{width}}  {value}' for name, value in rows)


def _stability_rows(data: dict) -> List[Tuple[str, str]]:
    """Rows for the platform compliance eigenvalues and the stability verdict."""
    eigenvalues = data['platform_compliance_eigenvalues']
    if eigenvalues is None:
        return [('stable', 'not computed')]
    legs = data['leg_stability'] or []
    return [('stable (closed chain)', f"{data['stable']} (stiffness margin "
                                      f"{data['stiffness_margin_n_per_m']:.4g} N/m)"),
            ('legs held at both ends', ', '.join(
                f"{leg['stable']} ({axial_load_text(leg['axial_load_n'])}, held buckling load "
                f"{leg['critical_load_n']:.4g} N)"
                if leg['critical_load_n'] is not None else str(leg['stable']) for leg in legs)),
            ('compliance eig. transl.', '  '.join(
                f'{v:.4e}' for v in eigenvalues['translation_m_per_n']) + ' m/N'),
            ('compliance eig. rot.', '  '.join(
                f'{v:.4e}' for v in eigenvalues['rotation_rad_per_nm']) + ' rad/(N m)')]


def _inverse_table(result: InverseResult) -> str:
    data = result.to_dict()
    # the message says what happened (reached, nearest reachable point, failure): a bare
    # 'converged True' beside an unreachable target would read as a contradiction
    rows = [('result', data['message']),
            ('reachable', str(data['reachable'])),
            ('sliders', _mm(data['sliders_m'])),
            ('target', _mm(data['target_m'])),
            ('platform position', _mm(data['platform_position_m'])),
            ('position error', f"{1e3 * data['position_error_m']:.5g} mm"),
            ('platform rotation', f"{data['platform_rotation_deg']:.4f} deg (parasitic)"),
            ('binding limits', ', '.join(data['binding_limits']) or 'none'),
            ('solve time', f"{1e3 * data['solve_time_s']:.1f} ms "
                           f"({_counted(data['iterations'], 'iteration')}, "
                           f"{_counted(data['forward_solves'], 'forward solve')})")]
    if 'stable' in data:
        rows.extend(_stability_rows(data))
    width = max(len(name) for name, _ in rows)
    return '\n'.join(f'{name:<{width}}  {value}' for name, value in rows)


def _mm(values: List[float]) -> str:
    return '[' + ', '.join(f'{1e3 * v:.4f}' for v in values) + '] mm'


def _counted(count: int, noun: str) -> str:
    """Return '1 iteration', '2 iterations'."""
    return f'{count} {noun}' + ('' if count == 1 else 's')


def _comparison_cell(paper: float, ours: float, spec: str) -> str:
    text = f'{paper:{spec}} | {ours:{spec}} ({ours - paper:+{spec}})'
    return f'{text:>30}'


def _paper_comparison(params: TranslatorParams, accuracy: Accuracy) -> Tuple[str, bool]:
    """Return the Table II comparison and whether both cases converged."""
    solver = TranslatorSolver(params, accuracy=accuracy)
    lines = ["Table II of the paper vs this solver (cold solves; 'ours - paper' in brackets)",
             f"{'':36}" + ''.join(f'{f"F = [{case.force[0]:g}, 0, 0] N":>30}'
                                  for case in TABLE_II)]
    results = []
    for case in TABLE_II:
        solver.reset()
        results.append(solver.solve(case.force))
    quantities = (
        ('Bending angle of PJ (deg)', lambda r: math.degrees(r.pj_bending[0]),
         lambda c: c.pj_bending_deg, '.3f'),
        ('Bending angle of DJ (deg)', lambda r: math.degrees(r.dj_bending[0]),
         lambda c: c.dj_bending_deg, '.3f'),
        ('Rotation angle of end disk (deg)', lambda r: math.degrees(r.end_disk_rotation),
         lambda c: c.end_disk_rotation_deg, '.3f'),
        ('Max deviation from arcs (mm)', lambda r: 1e3 * max(r.max_arc_deviation.values()),
         lambda c: c.max_arc_deviation_mm, '.4f'),
    )
    for name, ours, theirs, spec in quantities:
        cells = ''.join(_comparison_cell(theirs(case), ours(result), spec)
                        for case, result in zip(TABLE_II, results))
        lines.append(f'{name:36}{cells}')
    lines.append(f"{'':36}" + ''.join(f'{"paper | ours (diff)":>30}' for _ in TABLE_II))
    lines.append(f'Parameters: tube_length {1e3 * params.tube_length:g} mm, youngs_modulus '
                 f'{params.youngs_modulus / 1e9:g} GPa, poisson_ratio {params.poisson_ratio:g}, '
                 f'spacers_per_joint {params.spacers_per_joint}, steps_per_segment '
                 f'{params.steps_per_segment}')
    lines.append('Converged: ' + ', '.join(
        f"{r.converged} in {_counted(r.iterations, 'iteration')}, {1e3 * r.solve_time_s:.1f} ms"
        for r in results))
    return '\n'.join(lines), all(result.converged for result in results)


def warm_up_kernels(params: TranslatorParams, params_path: str,
                    progress: Optional[Callable[[str], object]] = None) -> None:
    """
    Run every compiled kernel once (loading or compiling it); ``progress`` hears each stage.

    Solves once at every fidelity level, with each Jacobian, and the CDR; a cold solve with
    spacer disks runs the multiple-shooting kernels (multiple_shooting_kernels.py), four
    warm solves along a path the extrapolating predictor (chord.extrapolate), a batch
    after them the compiled run of warm rows (solve/warm_fast_path.py). After each stage
    ``progress`` gets one line: the stage, the kernel signatures compiled and loaded so far,
    the time so far (a cold cache takes minutes, which should not pass in silence).
    """
    stages = _warm_up_stages(params, params_path)
    started = time.perf_counter()
    for number, (name, stage) in enumerate(stages, 1):
        stage()
        if progress is not None:
            counts = _jit.kernel_counts()
            progress(f'[{number}/{len(stages)}] {name}: {counts.compiled} signatures compiled, '
                     f'{counts.loaded} loaded from the cache so far, '
                     f'{time.perf_counter() - started:.0f} s')


def _warm_up_stages(params: TranslatorParams, params_path: str
                    ) -> List[Tuple[str, Callable[[], None]]]:
    """Return the stages of ``warm_up_kernels``, named, in order."""
    # 'auto' under a budget, so that it looks up the validated ranges (a compiled lookup)
    leveled: Dict[str, FidelitySolver] = {}

    def fidelity_levels() -> None:
        leveled.update({fidelity: FidelitySolver(params, fidelity) for fidelity in FIDELITIES
                        if fidelity != 'auto'})
        leveled['auto'] = FidelitySolver(params, 'auto', max_position_error=1e-3,
                                         max_angle_error_deg=0.5)
        for solver in leveled.values():  # to_dict reads the compliance's analysis too
            solver.solve([1.0, 0.0, 0.0], compliance=True).to_dict()

    def linear_sequences() -> None:
        wrenches = np.array([[1.0, 0.0, 0.0, 0.0, 0.0, 0.0], [1.5, 0.0, 0.0, 0.0, 0.0, 0.0]])
        for model in leveled['linear'].reduced.values():  # the compiled sequence solves
            model.poses(wrenches, model.solve_sequence(wrenches)[0])
        leveled['linear'].tangent.poses(wrenches)

    def jacobians() -> None:
        for jacobian in JACOBIANS:
            TranslatorSolver(params, jacobian=jacobian).solve([1.0, 0.0, 0.0], compliance=True)

    def along_a_path() -> None:
        solver = TranslatorSolver(params)
        for force in (1.0, 1.5, 2.0, 2.5):
            solver.solve([force, 0.0, 0.0])
        solver.solve_many([[2.6, 0.0, 0.0], [2.7, 0.0, 0.0]])  # a compiled run of rows

    def spacer_disks() -> None:
        spacers = max(params.spacers_per_joint, LIFT_FROM_SPACERS or 0)
        TranslatorSolver(params.with_changes(spacers_per_joint=spacers)).solve(
            [1.0, 0.0, 0.0])

    def robot(level: str) -> Callable[[], None]:
        def run() -> None:  # reduced legs run a compiled chain of their own
            robot = DeltaRobot.from_yaml(params_path, fidelity=level)
            for sliders in ([0.0, 0.0, 0.0], [0.001, 0.0, 0.0]):  # cold, then warm
                robot.solve(sliders, [0.0, 0.0, -1.0], compliance=True).to_dict()
            if level != 'full':  # and their atlas's compiled loop over samples
                solve_chunk(AtlasSpec.build(2, [(0.0, 0.0, -1.0)], [params_path],
                                            fidelity=level), 0, 4)
        return run

    return [('the translator at every fidelity level', fidelity_levels),
            ('linear sequences', linear_sequences), ('each Jacobian', jacobians),
            ('warm solves along a path', along_a_path), ('spacer disks', spacer_disks)] + [
        (f'the robot with {level} legs', robot(level)) for level in ('full', 'cc', 'rod')]


def _compile_kernels(params: TranslatorParams, params_path: str) -> int:
    """
    Run every kernel (``warm_up_kernels``) so that numba's cache holds them all.

    Says each stage as it ends, then what it compiled and where; a kernel that did not run
    is named as not cached. Every line is flushed: ``make setup`` pipes it.
    """
    def say(text: str) -> None:
        print(text, flush=True)

    elapsed = _jit.timed_warm_up(lambda: warm_up_kernels(params, params_path, say), say)
    missing = _jit.uncached_kernels()
    if missing:
        print(f'error: not cached: {", ".join(missing)}', file=sys.stderr)
        return EXIT_NOT_CONVERGED
    counts = _jit.kernel_counts()
    print(f'all {len(_jit.KERNELS)} numba kernels are in the cache at {_jit.CACHE_LOCATION} '
          f'({counts.compiled} signatures compiled, {counts.loaded} loaded, {elapsed:.1f} s)')
    return EXIT_CONVERGED


def main(argv: Optional[List[str]] = None) -> int:
    """Run the command line; return the exit code (console.run_command: 130, 141 too)."""
    return run_command(lambda: _run(argv))


def _run(argv: Optional[List[str]]) -> int:
    """Parse ``argv``, run the subcommand and print its result; return the exit code."""
    args = _parser().parse_args(argv)
    result: Any  # SolveResult, DeltaResult or InverseResult, printed by its table
    table: Callable[[Any], str]
    solver: Union[TranslatorSolver, FidelitySolver]
    if args.command == 'atlas':
        return run_atlas(args)
    try:
        if args.command in ('delta', 'delta-ik'):
            # every key checked, as cdr_node does; the legs' model and the geometry from it
            robot_settings = CdrSettings.from_params_file(args.params)
            robot = DeltaRobot(robot_settings.params, robot_settings.geometry,
                               time_limit_s=args.time_limit, fidelity=args.fidelity,
                               max_position_error=args.max_position_error,
                               max_angle_error=args.max_angle_error)
            if args.command == 'delta':
                result = robot.solve(args.sliders, args.payload, args.payload_moment,
                                     args.payload_offset, compliance=True)
                table = _delta_table
            else:
                result = robot.inverse(args.target, args.payload, args.payload_moment,
                                       args.payload_offset)
                table = _inverse_table
        else:
            # every key checked, as translator_node and replay do; the accuracy target too
            settings = TranslatorSettings.from_params_file(args.params)
            params, accuracy = settings.params, settings.accuracy
            if args.command == 'paper':
                text, converged = _paper_comparison(params, accuracy)
                print(text)
                return EXIT_CONVERGED if converged else EXIT_NOT_CONVERGED
            if args.command == 'compile':
                return _compile_kernels(params, args.params)
            options = {'compliance': args.compliance,
                       'sparsity_threshold': args.sparsity_threshold,
                       'mobility_ratio': args.mobility_ratio}
            if args.fidelity == 'full':
                solver = TranslatorSolver(params, method=args.method,
                                          max_iterations=args.max_iterations,
                                          time_limit_s=args.time_limit, accuracy=accuracy)
                options['verify'] = args.verify
            elif args.method != 'fast' or args.verify or args.max_iterations is not None:
                raise ValueError('--method, --verify and --max-iterations apply to '
                                 '--fidelity full only')
            else:
                solver = FidelitySolver(params, args.fidelity, args.max_position_error,
                                        args.max_angle_error, time_limit_s=args.time_limit,
                                        accuracy=accuracy)
            result = solver.solve(args.force, args.moment, **options)
            table = _table
    except (ParameterError, ValueError) as error:
        print(f'error: {error}', file=sys.stderr)
        return EXIT_BAD_INPUT
    data = result.to_dict()   # its 'stable' also holds the compliance's verdict when that
    try:                      # was the only one (the paper's method)
        print(json_text(data) if args.json else table(result))
        sys.stdout.flush()   # a full disk shows here, not in the interpreter's last flush
    except BrokenPipeError:
        raise
    except OSError as error:
        print(f'error: cannot write the result to standard output: {error.strerror or error}',
              file=sys.stderr)
        return EXIT_BAD_INPUT
    if not (result.converged and getattr(result, 'reachable', True)):
        return EXIT_NOT_CONVERGED
    if data.get('stable') is False:
        print('warning: the equilibrium found is unstable (stable: false); see '
              'docs/explanation/solution_quality.md', file=sys.stderr)
        return EXIT_UNSTABLE
    return EXIT_CONVERGED

"""
What translator_node does with one WrenchStamped, without ROS: checks, frames, the solve.

Replay uses this to publish exactly what the live node would have: the same input checks
(finite, magnitudes within ``max_force``/``max_moment``), the same frame handling (base frame
or empty: {pe} components; end-disk frame: a follower load, rotated into {pe} with the
solved end-disk orientation until that orientation settles; anything else rejected) and the
same solver settings (``solve_time_limit_s``), all read from the one params file.
"""

from dataclasses import dataclass
import math
from typing import (Any, Callable, Dict, Iterator, List, Mapping, Optional, Sequence, Tuple,
                    Union)
import warnings

import numpy as np
from numpy.typing import ArrayLike

from . import messages
from .batch_row import BatchRow
from .diagnostics_period import StreamDiagnostics
from .settings import TranslatorSettings
from ..fidelity import FidelitySolver
from ..params.translator_params import TranslatorParams
from ..solve.result import SolveResult
from ..solve.solver import check_wrench, TranslatorSolver

#: A follower load's orientation has settled when no rotation-matrix entry changes more.
FOLLOWER_TOLERANCE = 1e-12
#: Solves allowed for a follower load before it is reported as not converged.
FOLLOWER_MAX_SOLVES = 8

#: Fidelity levels whose ``solve_many`` rows with compliance say all a ``solve`` result does.
BATCHED_FIDELITIES = ('full', 'cc', 'rod')

#: One wrench as ``messages.wrench_from_message`` gives it: force, moment, frame_id, stamp.
Wrench = Tuple[np.ndarray, np.ndarray, str, Mapping[str, int]]


def node_solver(params: TranslatorParams, settings: TranslatorSettings) -> FidelitySolver:
    """
    Build the solver translator_node uses: fidelity, error budget, time limit and accuracy.

    The node and replay both build theirs here, so that they solve alike.
    """
    return FidelitySolver(params, fidelity=settings.fidelity,
                          max_position_error=settings.max_position_error,
                          max_angle_error_deg=settings.max_angle_error,
                          time_limit_s=settings.solve_time_limit_s,
                          accuracy=settings.accuracy)


def check_magnitude(force: ArrayLike, moment: ArrayLike, max_force: float,
                    max_moment: float) -> None:
    """Raise ValueError naming the magnitude when |force| or |moment| exceeds its limit."""
    for name, vector, limit, unit in (('force', force, max_force, 'N'),
                                      ('moment', moment, max_moment, 'N m')):
        magnitude = math.hypot(*np.asarray(vector, dtype=float).tolist())  # 1 us, not 10
        if magnitude > limit:
            raise ValueError(f'|{name}| = {magnitude:.6g} {unit} exceeds max_{name} = '
                             f'{limit:.6g} {unit}')


def in_end_disk_frame(frame_id: str, base_frame: str, end_disk_frame: str) -> bool:
    """
    Tell whether a wrench's frame_id is the end-disk frame (True) or the base frame (False).

    An empty frame_id means the base frame; any other name raises ValueError (no tf here).
    """
    if frame_id in ('', base_frame):
        return False
    if frame_id == end_disk_frame:
        return True
    raise ValueError(f'unknown frame_id {frame_id!r}: expected {base_frame!r} (or empty) or '
                     f'{end_disk_frame!r}')


def solve_wrench(solver: Union[TranslatorSolver, FidelitySolver], force: np.ndarray,
                 moment: np.ndarray, end_disk: bool, rotation: np.ndarray, compliance: bool
                 ) -> Tuple[SolveResult, int]:
    """
    Solve a base-frame wrench, or an end-disk-frame one as a follower load.

    ``rotation`` is the end-disk orientation of the last converged solve (the starting
    guess of a follower load's direction). Returns the result and the number of solves.
    """
    if not end_disk:
        return solver.solve(force, moment, compliance=compliance), 1
    for solves in range(1, FOLLOWER_MAX_SOLVES + 1):
        result = solver.solve(rotation @ force, rotation @ moment, compliance=compliance)
        if not result.converged:
            return result, solves
        new_rotation = result.frames['de'][:3, :3]
        if np.abs(new_rotation - rotation).max() <= FOLLOWER_TOLERANCE:
            return result, solves
        rotation = new_rotation
    result.converged = False
    result.message = (f'the end-disk orientation of the follower load did not settle in '
                      f'{FOLLOWER_MAX_SOLVES} solves')
    return result, FOLLOWER_MAX_SOLVES


@dataclass
class Outcome:
    """What one wrench gave: the result (None if rejected), why not, and the outputs."""

    result: Optional[Union[SolveResult, BatchRow]]
    error: str
    outputs: List[Tuple[str, str, dict]]
    solves: int = 0


@dataclass
class Answer:
    """
    What one received wrench gave, its outputs built one by one when iterated (pose first).

    ``result`` is None if the wrench was rejected; ``error`` says why it was not solved.
    """

    result: Optional[SolveResult]
    error: str
    outputs: Iterator[Tuple[str, str, dict]]
    solves: int = 0


class WrenchProcessor:
    """
    The node's handling of a sequence of wrenches, warm-starting one solver along it.

    Counts received, rejected, solved (of them ``flagged``: converged to an answer not to
    act on, a WARN) and not converged messages, and reports them in the aggregated
    diagnostics (``report_counts``, ``diagnostics_status``); each answer is noted in
    ``diagnostics`` (the period's levels, worst residual, solve times, last fault) and has
    its own status among its outputs (``messages.SOLVE_STATUS_TOPIC``). translator_node
    holds one and adds its own counts (``extra_counts``: skipped wrenches, lost log
    records); offline ``skipped`` is always 0, nothing is dropped.
    """

    def __init__(self, params: TranslatorParams, settings: TranslatorSettings, *,
                 compliance: bool = True, backbones: bool = False,
                 extra_counts: Optional[Callable[[], Mapping[str, int]]] = None) -> None:
        """
        Build the solver (the node's time limit) for ``params``.

        ``extra_counts`` returns counts kept elsewhere, reported after (or in place of) the
        processor's own in the aggregated diagnostics.
        """
        self.settings = settings
        self.solver = node_solver(params, settings)
        self.compliance = compliance
        self.backbones = backbones
        self.rotation = np.eye(3)
        self.counts: Dict[str, int] = {'received': 0, 'rejected': 0, 'solved': 0,
                                       'flagged': 0, 'not_converged': 0, 'skipped': 0}
        self.extra_counts = extra_counts
        self.diagnostics = StreamDiagnostics(messages.DIAGNOSTIC_NAME, 'wrenches')

    def apply_settings(self, settings: TranslatorSettings) -> None:
        """Take a new settings snapshot: its limits, frames and solve time limit."""
        self.settings = settings
        self.solver.time_limit_s = settings.solve_time_limit_s

    def report_counts(self) -> Dict[str, Any]:
        """Return the counts the diagnostics report: the processor's, then ``extra_counts``."""
        counts: Dict[str, Any] = dict(self.counts)
        if self.extra_counts is not None:
            counts.update(self.extra_counts())
        return counts

    def diagnostics_status(self, now_s: float) -> dict:
        """Return the aggregated status of the period ending at ``now_s`` (s); start the next."""
        return self.diagnostics.status(self.report_counts(), now_s)

    def receive(self) -> None:
        """Count a received wrench (``process`` does; the node counts one as it arrives)."""
        self.counts['received'] += 1

    def reject(self, stamp: Mapping[str, int], reason: str) -> List[Tuple[str, str, dict]]:
        """Count a rejected wrench; return its ERROR status ``rejected: <reason>``."""
        self.counts['rejected'] += 1
        return self._unanswered(stamp, f'rejected: {reason}')

    def internal_error(self, stamp: Mapping[str, int], reason: str
                       ) -> List[Tuple[str, str, dict]]:
        """Count a wrench a bug left unanswered (not converged); return its ERROR status."""
        self.counts['not_converged'] += 1
        return self._unanswered(stamp, reason)

    def _unanswered(self, stamp: Mapping[str, int], reason: str
                    ) -> List[Tuple[str, str, dict]]:
        """Note an unanswered wrench in the period; return its ERROR status."""
        self.diagnostics.note(messages.ERROR, reason)
        return messages.rejection_messages(stamp, reason, topic=messages.SOLVE_STATUS_TOPIC)

    @property
    def batches(self) -> bool:
        """
        Whether ``process_many`` solves runs of base-frame wrenches by one ``solve_many``.

        Only where the batch's rows hold everything the outputs read (``batch_row``): not
        with backbones (a row keeps no shape), and where every row is solved by a path that
        records its single solve's iterations, residual and verdict: with compliance, at
        the full and the reduced levels (their compiled runs without compliance keep none).
        """
        return (not self.backbones and self.compliance
                and self.settings.fidelity in BATCHED_FIDELITIES)

    def process_many(self, wrenches: Sequence[Wrench]) -> List[Outcome]:
        """
        Handle ``wrenches`` (force, moment, frame_id, stamp) in order, as ``process`` would.

        Runs of accepted base-frame wrenches are solved by one ``solve_many``, warm along
        them (``batches``); a rejected input and a follower load (end-disk frame) end a run
        and are handled by ``process``. The outcomes equal those of ``process`` called on
        each wrench in turn, to the solver's tolerance.
        """
        if not self.batches:
            return [self.process(*wrench) for wrench in wrenches]
        outcomes: List[Outcome] = []
        run: List[Wrench] = []
        for wrench in wrenches:
            if self._in_run(wrench):
                run.append(wrench)
                continue
            outcomes += self._solve_run(run)
            run = []
            outcomes.append(self.process(*wrench))
        return outcomes + self._solve_run(run)

    def _in_run(self, wrench: Wrench) -> bool:
        """Whether ``wrench`` is accepted and in the base frame (it may join a run)."""
        try:
            return not self._check(*wrench[:3])
        except ValueError:
            return False

    def _check(self, force: np.ndarray, moment: np.ndarray, frame_id: str) -> bool:
        """
        Check a wrench as the node does; return whether it is in the end-disk frame.

        ValueError names what rejects it (not finite, too large, an unknown frame).
        """
        settings = self.settings
        check_wrench(force, moment)
        check_magnitude(force, moment, settings.max_force, settings.max_moment)
        return in_end_disk_frame(frame_id, settings.base_frame, settings.end_disk_frame)

    def _tally(self, result: Union[SolveResult, BatchRow],
               rotation: Callable[[], np.ndarray]) -> None:
        """
        Count and note an answer; a converged one's end-disk orientation starts a follower load.

        Flagged: converged to an answer not to act on (``messages.solve_level`` WARN).
        """
        level = messages.solve_level(result)
        if result.converged:
            self.counts['solved'] += 1
            self.counts['flagged'] += level == messages.WARN
            self.rotation = rotation()
        else:
            self.counts['not_converged'] += 1
        self.diagnostics.note(level, result.message, float(result.residual_norm),
                              float(result.solve_time_s))

    def _solve_run(self, run: Sequence[Wrench]) -> List[Outcome]:
        """Solve a run of accepted base-frame wrenches by one ``solve_many``."""
        if not run:
            return []
        batch = self.solver.solve_many(np.array([wrench[0] for wrench in run], dtype=float),
                                       np.array([wrench[1] for wrench in run], dtype=float),
                                       compliance=self.compliance)
        outcomes = []
        for index, wrench in enumerate(run):
            row = BatchRow(batch, index)
            self.counts['received'] += 1
            self._tally(row, lambda: row.end_disk_rotation_matrix)
            outputs = messages.output_messages(
                row, wrench[3], self.settings.base_frame, compliance=self.compliance)
            outcomes.append(Outcome(row, '' if row.converged else row.message, outputs, 1))
        return outcomes

    def process(self, force: np.ndarray, moment: np.ndarray, frame_id: str,
                stamp: Mapping[str, int]) -> Outcome:
        """Count, check, solve and build the outputs of one wrench (outputs stamped ``stamp``)."""
        self.receive()
        answer = self.answer(force, moment, frame_id, stamp)
        return Outcome(answer.result, answer.error, list(answer.outputs), answer.solves)

    def answer(self, force: np.ndarray, moment: np.ndarray, frame_id: str,
               stamp: Mapping[str, int], *, compliance: Optional[bool] = None,
               backbones: Optional[bool] = None) -> Answer:
        """
        Check and solve one wrench already counted as received; its outputs built lazily.

        ``compliance`` and ``backbones`` (default: the processor's) say whether the outputs
        hold the compliance and the backbone markers: the node asks for them only while
        someone listens or they are logged. The answer is counted and noted in the period's
        diagnostics when the solve ends; its own status is the last output.
        """
        compliance = self.compliance if compliance is None else compliance
        backbones = self.backbones if backbones is None else backbones
        try:
            end_disk = self._check(force, moment, frame_id)
        except ValueError as error:
            reason = f'rejected: {error}'
            return Answer(None, reason, iter(self.reject(stamp, str(error))))
        result, solves = solve_wrench(self.solver, np.asarray(force, dtype=float),
                                      np.asarray(moment, dtype=float), end_disk,
                                      self.rotation, compliance)
        self._tally(result, lambda: result.frames['de'][:3, :3])
        outputs = messages.iter_output_messages(
            result, stamp, self.settings.base_frame, compliance=compliance,
            backbones_params=self.solver.params if backbones else None,
            extra_values={'follower_solves': solves} if end_disk else None)
        return Answer(result, '' if result.converged else result.message, outputs, solves)


def __getattr__(name: str) -> Any:
    """Serve ``InputSettings``, the name TranslatorSettings had here before 0.2."""
    if name == 'InputSettings':
        warnings.warn(f'{__name__}.InputSettings is deprecated; use '
                      'cdr_translator.interface.settings.TranslatorSettings',
                      DeprecationWarning, stacklevel=2)
        return TranslatorSettings
    raise AttributeError(f'module {__name__!r} has no attribute {name!r}')

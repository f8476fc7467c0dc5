"""
What translator_node does with one measured end-disk pose, without ROS: checks, the estimate.

Deflection-based force sensing on the node (cdr_translator/estimation): a
``measured_end_disk_pose`` (geometry_msgs/PoseStamped) or ``measured_end_disk_pose_cov``
(PoseWithCovarianceStamped, covariance row-major 6x6 in x, y, z, rotation about x, y, z)
gives ``estimated_wrench`` (WrenchStamped, in the base frame, stamped like the pose),
``estimated_wrench_covariance`` (Float64MultiArray, 6x6 row-major, with a pose covariance
only) and a diagnostic. The pose must be in the base frame (or have an empty frame_id):
there is no tf here. Replay uses this to write exactly what the live node would have.
MeasuredPoseProcessor is the check-estimate-messages template of both nodes' estimates
(cdr_node's: interface/payload_estimation.py).
"""

import abc
from dataclasses import dataclass
from typing import Any, Dict, List, Mapping, Optional, Tuple

import numpy as np

from . import messages
from .diagnostics_period import StreamDiagnostics
from .settings import estimate_components, TranslatorSettings
from ..errors import InputError
from ..estimation import diagonal_prior, measured_target, WrenchEstimate
from ..params.translator_params import TranslatorParams
from ..solve.solver import TranslatorSolver

#: Inputs: a measured end-disk pose, without and with its covariance.
MEASURED_POSE_TOPIC = 'measured_end_disk_pose'
MEASURED_POSE_COV_TOPIC = 'measured_end_disk_pose_cov'
#: Outputs: the estimated end-disk wrench and its covariance.
ESTIMATED_WRENCH_TOPIC = 'estimated_wrench'
ESTIMATED_WRENCH_COVARIANCE_TOPIC = 'estimated_wrench_covariance'
#: Every pose's own estimate status (a DiagnosticArray of one status, stamped like the
#: pose); /diagnostics carries one aggregated array a period.
ESTIMATE_STATUS_TOPIC = 'estimate_status'
#: Type of each input and output topic of the estimation.
ESTIMATION_TOPIC_TYPES: Mapping[str, str] = {
    MEASURED_POSE_TOPIC: messages.POSE_TYPE, MEASURED_POSE_COV_TOPIC: messages.POSE_COV_TYPE,
    ESTIMATED_WRENCH_TOPIC: messages.WRENCH_TYPE,
    ESTIMATED_WRENCH_COVARIANCE_TOPIC: messages.FLOAT64_MULTI_ARRAY_TYPE,
    ESTIMATE_STATUS_TOPIC: messages.DIAGNOSTIC_ARRAY_TYPE}

#: DiagnosticStatus name of the translator's wrench estimates.
ESTIMATE_DIAGNOSTIC_NAME = 'translator_node: wrench estimate'


@dataclass(frozen=True)
class MeasuredPose:
    """One measured pose as a message carries it (values unchecked)."""

    position: np.ndarray
    quaternion_xyzw: np.ndarray
    covariance: Optional[np.ndarray]  # 6x6, or None for a PoseStamped
    frame_id: str
    stamp: dict


def pose_from_message(message: Any) -> MeasuredPose:
    """
    Return the MeasuredPose of a PoseStamped or PoseWithCovarianceStamped (dict or decoded).

    The values are returned as given (NaN included): ``measured_target`` checks them.
    """
    get = messages.message_field
    head = get(message, 'header')
    pose = get(message, 'pose')
    covariance = None
    carried = pose.get('covariance') if isinstance(pose, Mapping) else getattr(
        pose, 'covariance', None)  # a PoseWithCovariance, not a Pose
    if carried is not None:
        covariance = np.asarray(carried, dtype=float).reshape(6, 6)
        pose = get(pose, 'pose')
    stamp = get(head, 'stamp')
    return MeasuredPose(np.array(_components(get(pose, 'position'), 'xyz')),
                        np.array(_components(get(pose, 'orientation'), 'xyzw')),
                        covariance, str(get(head, 'frame_id')),
                        {'sec': int(get(stamp, 'sec')), 'nanosec': int(get(stamp, 'nanosec'))})


def _components(vector: Any, axes: str) -> List[float]:
    """Return the ``axes`` components of a Point or Quaternion (dict or decoded) as floats."""
    if type(vector) is dict or isinstance(vector, Mapping):  # judged once, not per component
        return [float(vector[axis]) for axis in axes]
    return [float(getattr(vector, axis)) for axis in axes]


def check_frame(measured: MeasuredPose, frame: str) -> None:
    """Raise InputError (a ValueError) for a pose in another frame than ``frame``."""
    if measured.frame_id not in ('', frame):
        raise InputError(f'unknown frame_id {measured.frame_id!r}: a measured pose must be '
                         f'in {frame!r} (or have an empty frame_id); no tf here')


def check_pose(measured: MeasuredPose, frame: str, length: float) -> None:
    """Raise InputError naming what is wrong: the frame, a non-finite value, the quaternion."""
    check_frame(measured, frame)
    measured_target(measured.position, measured.quaternion_xyzw, measured.covariance, None,
                    None, length)


def _accuracy_text(accuracy_met: Optional[bool]) -> str:
    """Return 'true', 'false' or 'not assessed' (None: no pose covariance to judge by)."""
    return 'not assessed' if accuracy_met is None else str(bool(accuracy_met)).lower()


def _numbers_text(values: np.ndarray) -> str:
    """Return numbers as '1.2e-05 3.4' ('nan' for a component that has none)."""
    return ' '.join(f'{value:.4g}' for value in values.tolist())  # floats: no numpy scalars


def estimate_values(estimate: WrenchEstimate) -> Dict[str, Any]:
    """
    Return the diagnostic key/values of one estimate.

    The residual, conditioning and stability; ``accuracy_met`` ('true', 'false' or 'not
    assessed' for an exact pose); ``flags`` (the reasons not to act on it, '; '-joined,
    'none'); the estimated ``components``; the posterior standard deviations of the six
    components (``standard_deviation``, N and N m, fx..mz, 'nan' where not estimated or
    without a pose covariance); ``chi_square`` and its tail probability ``chi_square_p``.
    """
    poorly = ', '.join(f"{direction['label']} ({direction['ratio']:.3g} x)"
                       for direction in estimate.conditioning)
    values: Dict[str, Any] = {
        'converged': bool(estimate.converged), 'residual_m': float(estimate.residual_m),
        'residual_deg': float(estimate.residual_deg),
        'condition_number': float(estimate.condition_number),
        'poorly_observable': poorly or 'none'}
    if estimate.stable is not None:
        values['stable'] = bool(estimate.stable)
    values.update({'stability_margin': float(estimate.stability_margin),
                   'accuracy_met': _accuracy_text(estimate.accuracy_met),
                   'flags': '; '.join(estimate.flags) or 'none',
                   'components': ' '.join(estimate.components),
                   'standard_deviation': _numbers_text(estimate.standard_deviation),
                   'chi_square': float(estimate.chi_square),
                   'chi_square_p': float(estimate.chi_square_p),
                   'iterations': int(estimate.iterations), 'solves': int(estimate.solves),
                   'estimate_time_ms': 1e3 * float(estimate.estimate_time_s)})
    return values


def estimate_level(estimate: WrenchEstimate) -> int:
    """
    Return ERROR when no wrench matches the pose, WARN for one not to act on, else OK.

    Not to act on: ``flagged`` (past buckling, near a bifurcation where another wrench may
    match, the forward solve off its accuracy target, a pose residual its covariance does
    not allow, a spread beyond the target) or ``accuracy_met`` False. An exact pose's
    estimate (``accuracy_met`` None: not assessed) without flags is OK. A poorly
    observable direction is reported in the values only: the axial force always is one.
    """
    if not estimate.converged:
        return messages.ERROR
    if estimate.flagged or estimate.accuracy_met is False:
        return messages.WARN
    return messages.OK


def estimate_messages(estimate: WrenchEstimate, stamp: Mapping[str, int], base_frame: str,
                      extra_values: Optional[Mapping[str, Any]] = None, *,
                      wrench_topic: str = ESTIMATED_WRENCH_TOPIC,
                      covariance_topic: str = ESTIMATED_WRENCH_COVARIANCE_TOPIC,
                      name: str = ESTIMATE_DIAGNOSTIC_NAME,
                      status_topic: str = messages.DIAGNOSTICS_TOPIC
                      ) -> List[Tuple[str, str, dict]]:
    """
    Return (topic, type, message) of everything published for one estimate.

    A converged estimate gives the wrench (in ``base_frame``, stamped ``stamp``) and, when
    the pose came with a covariance, the wrench covariance; every estimate gives a
    status on ``status_topic`` (``estimate_values`` then ``extra_values``) with the
    estimator's message.
    """
    built = []
    if estimate.converged:
        built.append((wrench_topic, messages.WRENCH_TYPE,
                      messages.wrench_message(estimate.force, estimate.moment, base_frame,
                                              stamp)))
        if estimate.covariance is not None:
            built.append((covariance_topic, messages.FLOAT64_MULTI_ARRAY_TYPE,
                          messages.matrix_message(estimate.covariance)))
    values = estimate_values(estimate)
    values.update(extra_values or {})
    built.append((status_topic, messages.DIAGNOSTIC_ARRAY_TYPE,
                  messages.diagnostics_message(stamp, estimate_level(estimate),
                                               estimate.message, values, name=name)))
    return built


def estimation_solver(params: TranslatorParams, settings: TranslatorSettings
                      ) -> TranslatorSolver:
    """
    Return the solver of the estimates: the full model, the node's time limit and accuracy.

    Its own solver, so that the wrench stream and the pose stream each warm-start along
    themselves; the full model whatever ``fidelity``, as the estimate needs its exact
    compliance.
    """
    return TranslatorSolver(params, time_limit_s=settings.solve_time_limit_s,
                            accuracy=settings.accuracy)


@dataclass
class EstimateOutcome:
    """What one pose gave: the estimate (None if rejected), why not, and the outputs."""

    estimate: Optional[WrenchEstimate]
    error: str
    outputs: List[Tuple[str, str, dict]]


class MeasuredPoseProcessor(abc.ABC):
    """
    A node's handling of a stream of measured poses: check, estimate, messages.

    Counts, reported in every diagnostic: ``received``; ``rejected`` (bad input);
    ``solved`` (a matching load found: converged), split into ``estimated`` (no flag) and
    ``flagged`` (not to be acted on); ``not_converged`` (failed: no load matches); and
    ``skipped`` (the caller's: pushed out of the mailbox; 0 offline). Once idle,
    received = solved + not_converged + rejected + skipped. Each pose's status goes to
    ``status_topic``; ``diagnostics`` sums a period of them up (``diagnostics_status``).
    """

    diagnostic_name = ESTIMATE_DIAGNOSTIC_NAME
    status_topic = messages.DIAGNOSTICS_TOPIC

    def __init__(self) -> None:
        """Start the counts at zero."""
        self.counts: Dict[str, int] = {'received': 0, 'rejected': 0, 'solved': 0,
                                       'estimated': 0, 'flagged': 0, 'not_converged': 0,
                                       'skipped': 0}
        self.diagnostics = StreamDiagnostics(self.diagnostic_name, 'poses',
                                             residual_key='residual_m',
                                             time_key='estimate_time')

    def diagnostics_status(self, now_s: float) -> dict:
        """Return the aggregated status of the period ending at ``now_s`` (s); start the next."""
        return self.diagnostics.status(dict(self.counts), now_s)

    def reject(self, stamp: Mapping[str, int], reason: str) -> EstimateOutcome:
        """Count a rejected pose; return its ERROR status."""
        self.counts['rejected'] += 1
        self.diagnostics.note(messages.ERROR, f'rejected: {reason}')
        return EstimateOutcome(None, f'rejected: {reason}', messages.rejection_messages(
            stamp, f'rejected: {reason}', dict(self.counts), name=self.diagnostic_name,
            topic=self.status_topic))

    def internal_error(self, stamp: Mapping[str, int], reason: str
                       ) -> List[Tuple[str, str, dict]]:
        """Count a pose a bug left unanswered (not converged); return its ERROR status."""
        self.counts['not_converged'] += 1
        self.diagnostics.note(messages.ERROR, reason)
        return messages.rejection_messages(stamp, reason, dict(self.counts),
                                           name=self.diagnostic_name, topic=self.status_topic)

    def process(self, message: Any, count_received: bool = True) -> EstimateOutcome:
        """
        Check one pose message (dict or decoded), estimate the load, build the outputs.

        ``count_received`` False: the caller counted the pose when it arrived (the node).
        """
        if count_received:   # no write otherwise: the node's callback counts in another thread
            self.counts['received'] += 1
        try:
            measured = pose_from_message(message)
        except ValueError as error:  # a covariance of another size than 36
            return self.reject({'sec': 0, 'nanosec': 0}, f'malformed message: {error}')
        try:
            self.check(measured)
            estimate = self.estimate(measured)
        except InputError as error:  # the pose's values are checked once, by the estimate
            return self.reject(measured.stamp, str(error))
        if estimate.converged:
            self.counts['solved'] += 1
            self.counts['flagged' if estimate.flagged else 'estimated'] += 1
        else:
            self.counts['not_converged'] += 1
        self.diagnostics.note(estimate_level(estimate), estimate.message,
                              float(estimate.residual_m), float(estimate.estimate_time_s))
        return EstimateOutcome(estimate, '' if estimate.converged else estimate.message,
                               self.outputs(estimate, measured.stamp, dict(self.counts)))

    @abc.abstractmethod
    def check(self, measured: MeasuredPose) -> None:
        """Raise InputError naming what is wrong with a pose that ``estimate`` does not check."""

    @abc.abstractmethod
    def estimate(self, measured: MeasuredPose) -> WrenchEstimate:
        """Estimate the load of a pose; InputError naming a bad value: the pose's rejection."""

    @abc.abstractmethod
    def outputs(self, estimate: WrenchEstimate, stamp: Mapping[str, int],
                counts: Mapping[str, int]) -> List[Tuple[str, str, dict]]:
        """Return the (topic, type, message) published for an estimate."""


def estimate_options(settings: TranslatorSettings) -> Dict[str, Any]:
    """
    Return the keyword arguments of ``estimate_wrench`` the estimate parameters give.

    ``estimate_components`` '' leaves the choice to the pose (all six components with an
    orientation) and the held values unused; otherwise the others are held at
    ``estimate_held_force`` / ``estimate_held_moment``. The prior is zero-mean, its
    covariance ``estimate_prior_covariance`` or, when that is empty, diagonal from the two
    prior standard deviations. The search stays within ``max_force`` and ``max_moment``,
    the magnitudes the node accepts as wrenches.
    """
    components = estimate_components(settings.estimate_components)
    prior = (np.reshape(settings.estimate_prior_covariance, (6, 6))
             if settings.estimate_prior_covariance
             else diagonal_prior(settings.estimate_prior_force_sd,
                                 settings.estimate_prior_moment_sd))
    options: Dict[str, Any] = {
        'estimate': components, 'prior_covariance': prior,
        'target_force_sd': settings.estimate_target_force_sd,
        'target_moment_sd': settings.estimate_target_moment_sd,
        'max_force': settings.max_force, 'max_moment': settings.max_moment}
    if components is not None:
        options.update(force=np.array(settings.estimate_held_force),
                       moment=np.array(settings.estimate_held_moment))
    return options


def assumed_pose_covariance(settings: TranslatorSettings) -> Optional[np.ndarray]:
    """
    Return the covariance assumed for a pose without one (a PoseStamped), 6x6.

    Position then rotation about the base axes, from ``estimate_pose_position_sd`` and
    ``estimate_pose_orientation_sd``; None (the pose is exact, the accuracy not assessed)
    when both are 0. One of them 0 makes that part exact.
    """
    position_sd = settings.estimate_pose_position_sd
    orientation_sd = settings.estimate_pose_orientation_sd
    if position_sd == 0.0 and orientation_sd == 0.0:
        return None
    return np.diag(np.repeat([position_sd, orientation_sd], 3) ** 2)


class PoseProcessor(MeasuredPoseProcessor):
    """translator_node's measured end-disk poses: the wrench, warm along the stream."""

    status_topic = ESTIMATE_STATUS_TOPIC

    def __init__(self, params: TranslatorParams, settings: TranslatorSettings) -> None:
        """Build the estimation solver for ``params``; the estimate follows ``settings``."""
        super().__init__()
        self.settings = settings
        self.solver = estimation_solver(params, settings)
        self._options_of: Tuple[Optional[TranslatorSettings], Dict[str, Any],
                                Optional[np.ndarray]] = (None, {}, None)

    def check(self, measured: MeasuredPose) -> None:
        """
        Raise InputError for another frame.

        The estimate checks the values (a non-finite one, a bad quaternion or covariance)
        as it takes them, with the messages check_pose gives: a pose is checked once.
        """
        check_frame(measured, self.settings.base_frame)

    def _options(self) -> Tuple[Dict[str, Any], Optional[np.ndarray]]:
        """Return (estimate options, assumed pose covariance) of the current settings."""
        settings, options, covariance = self._options_of
        if settings is not self.settings:  # a run-time change replaced the snapshot
            settings, options, covariance = (self.settings, estimate_options(self.settings),
                                             assumed_pose_covariance(self.settings))
            self._options_of = (settings, options, covariance)
        return options, covariance

    def estimate(self, measured: MeasuredPose) -> WrenchEstimate:
        """
        Estimate the end-disk wrench (warm-started from the last estimate).

        A PoseWithCovarianceStamped's covariance is used as it is; a PoseStamped gets the
        one the parameters assume (``assumed_pose_covariance``).
        """
        options, assumed = self._options()
        covariance = measured.covariance if measured.covariance is not None else assumed
        return self.solver.estimate_wrench(measured.position, measured.quaternion_xyzw,
                                           pose_covariance=covariance, **options)

    def outputs(self, estimate: WrenchEstimate, stamp: Mapping[str, int],
                counts: Mapping[str, int]) -> List[Tuple[str, str, dict]]:
        """Return the estimated wrench, its covariance and the diagnostic."""
        return estimate_messages(estimate, stamp, self.settings.base_frame, counts,
                                 status_topic=self.status_topic)

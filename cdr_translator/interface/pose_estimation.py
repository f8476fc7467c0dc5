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
from .settings import TranslatorSettings
from ..estimation import measured_target, WrenchEstimate
from ..params.translator_params import TranslatorParams
from ..solve.solver import TranslatorSolver

#: Inputs: a measured end-disk pose, without and with its covariance.
MEASURED_POSE_TOPIC = 'measured_end_disk_pose'
MEASURED_POSE_COV_TOPIC = 'measured_end_disk_pose_cov'
#: Outputs: the estimated end-disk wrench and its covariance.
ESTIMATED_WRENCH_TOPIC = 'estimated_wrench'
ESTIMATED_WRENCH_COVARIANCE_TOPIC = 'estimated_wrench_covariance'
#: Type of each input and output topic of the estimation.
ESTIMATION_TOPIC_TYPES: Mapping[str, str] = {
    MEASURED_POSE_TOPIC: messages.POSE_TYPE, MEASURED_POSE_COV_TOPIC: messages.POSE_COV_TYPE,
    ESTIMATED_WRENCH_TOPIC: messages.WRENCH_TYPE,
    ESTIMATED_WRENCH_COVARIANCE_TOPIC: messages.FLOAT64_MULTI_ARRAY_TYPE}

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
    position, orientation = get(pose, 'position'), get(pose, 'orientation')
    stamp = get(head, 'stamp')
    return MeasuredPose(np.array([float(get(position, axis)) for axis in 'xyz']),
                        np.array([float(get(orientation, axis)) for axis in 'xyzw']),
                        covariance, str(get(head, 'frame_id')),
                        {'sec': int(get(stamp, 'sec')), 'nanosec': int(get(stamp, 'nanosec'))})


def check_pose(measured: MeasuredPose, frame: str, length: float) -> None:
    """Raise ValueError naming what is wrong: the frame, a non-finite value, the quaternion."""
    if measured.frame_id not in ('', frame):
        raise ValueError(f'unknown frame_id {measured.frame_id!r}: a measured pose must be in '
                         f'{frame!r} (or have an empty frame_id); no tf here')
    measured_target(measured.position, measured.quaternion_xyzw, measured.covariance, None,
                    None, length)


def estimate_values(estimate: WrenchEstimate) -> Dict[str, Any]:
    """Return the diagnostic key/values of one estimate: residual, conditioning, stability."""
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
                   'accuracy_met': bool(estimate.accuracy_met),
                   'iterations': int(estimate.iterations), 'solves': int(estimate.solves),
                   'estimate_time_ms': 1e3 * float(estimate.estimate_time_s)})
    return values


def estimate_level(estimate: WrenchEstimate) -> int:
    """
    Return ERROR when no wrench matches the pose, WARN for one not to act on, else OK.

    Not to act on: ``accuracy_met`` false (past buckling, near a bifurcation where another
    wrench may match, or the forward solve off its accuracy target). A poorly observable
    direction is reported in the values only: the axial force always is one.
    """
    if not estimate.converged:
        return messages.ERROR
    return messages.OK if estimate.accuracy_met else messages.WARN


def estimate_messages(estimate: WrenchEstimate, stamp: Mapping[str, int], base_frame: str,
                      extra_values: Optional[Mapping[str, Any]] = None, *,
                      wrench_topic: str = ESTIMATED_WRENCH_TOPIC,
                      covariance_topic: str = ESTIMATED_WRENCH_COVARIANCE_TOPIC,
                      name: str = ESTIMATE_DIAGNOSTIC_NAME) -> List[Tuple[str, str, dict]]:
    """
    Return (topic, type, message) of everything published for one estimate.

    A converged estimate gives the wrench (in ``base_frame``, stamped ``stamp``) and, when
    the pose came with a covariance, the wrench covariance; every estimate gives a
    diagnostic (``estimate_values`` then ``extra_values``) with the estimator's message.
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
    built.append((messages.DIAGNOSTICS_TOPIC, messages.DIAGNOSTIC_ARRAY_TYPE,
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

    Counts received, rejected, solved (a matching load found) and not converged poses and
    reports them in every diagnostic; ``skipped`` is the caller's (0 offline).
    """

    diagnostic_name = ESTIMATE_DIAGNOSTIC_NAME

    def __init__(self) -> None:
        """Start the counts at zero."""
        self.counts: Dict[str, int] = {'received': 0, 'rejected': 0, 'solved': 0,
                                       'not_converged': 0, 'skipped': 0}

    def reject(self, stamp: Mapping[str, int], reason: str) -> EstimateOutcome:
        """Count a rejected pose; return its ERROR diagnostic."""
        self.counts['rejected'] += 1
        return EstimateOutcome(None, f'rejected: {reason}', messages.rejection_messages(
            stamp, f'rejected: {reason}', dict(self.counts), name=self.diagnostic_name))

    def process(self, message: Any, count_received: bool = True) -> EstimateOutcome:
        """
        Check one pose message (dict or decoded), estimate the load, build the outputs.

        ``count_received`` False: the caller counted the pose when it arrived (the node).
        """
        self.counts['received'] += int(count_received)
        try:
            measured = pose_from_message(message)
        except ValueError as error:  # a covariance of another size than 36
            return self.reject({'sec': 0, 'nanosec': 0}, f'malformed message: {error}')
        try:
            self.check(measured)
        except ValueError as error:
            return self.reject(measured.stamp, str(error))
        estimate = self.estimate(measured)
        self.counts['solved' if estimate.converged else 'not_converged'] += 1
        return EstimateOutcome(estimate, '' if estimate.converged else estimate.message,
                               self.outputs(estimate, measured.stamp, dict(self.counts)))

    @abc.abstractmethod
    def check(self, measured: MeasuredPose) -> None:
        """Raise ValueError naming what is wrong with a measured pose."""

    @abc.abstractmethod
    def estimate(self, measured: MeasuredPose) -> WrenchEstimate:
        """Estimate the load of a checked pose."""

    @abc.abstractmethod
    def outputs(self, estimate: WrenchEstimate, stamp: Mapping[str, int],
                counts: Mapping[str, int]) -> List[Tuple[str, str, dict]]:
        """Return the (topic, type, message) published for an estimate."""


class PoseProcessor(MeasuredPoseProcessor):
    """translator_node's measured end-disk poses: the wrench, warm along the stream."""

    def __init__(self, params: TranslatorParams, settings: TranslatorSettings) -> None:
        """Build the estimation solver for ``params``."""
        super().__init__()
        self.settings = settings
        self.solver = estimation_solver(params, settings)

    def check(self, measured: MeasuredPose) -> None:
        """Raise ValueError for another frame, a non-finite value, a bad quaternion."""
        check_pose(measured, self.settings.base_frame, self.solver.params.stack_height)

    def estimate(self, measured: MeasuredPose) -> WrenchEstimate:
        """Estimate the end-disk wrench (warm-started from the last estimate)."""
        return self.solver.estimate_wrench(measured.position, measured.quaternion_xyzw,
                                           pose_covariance=measured.covariance)

    def outputs(self, estimate: WrenchEstimate, stamp: Mapping[str, int],
                counts: Mapping[str, int]) -> List[Tuple[str, str, dict]]:
        """Return the estimated wrench, its covariance and the diagnostic."""
        return estimate_messages(estimate, stamp, self.settings.base_frame, counts)

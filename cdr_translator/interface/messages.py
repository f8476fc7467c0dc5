"""
What the translator publishes, as plain message dicts: one definition for the node and replay.

Pure Python (no rclpy): every function returns nested dicts and lists with the ROS field
names, the form ``mcap_ros2``'s CDR encoder takes and from which the node fills its rclpy
messages. Stamps are ``{'sec': int, 'nanosec': int}``; SI units and radians throughout.
DiagnosticStatus ``level`` is an int here (rclpy wants it as one byte: ``bytes([level])``).
"""

import math
from typing import Any, Iterator, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np
from numpy.typing import ArrayLike

from .batch_row import BatchRow
from .. import geometry
from ..params.translator_params import TranslatorParams
from ..solve.result import SolveResult

#: What the outputs are built from: a single solve's result or a batch row read as one.
Solved = Union[SolveResult, BatchRow]

#: Topic names (relative, as the node uses them; the diagnostics topic is absolute).
WRENCH_TOPIC = 'wrench'
END_DISK_POSE_TOPIC = 'end_disk_pose'
BENDING_ANGLES_TOPIC = 'bending_angles'
COMPLIANCE_EIGENVALUES_TOPIC = 'compliance_eigenvalues'
COMPLIANCE_TOPIC = 'compliance'
BACKBONES_TOPIC = 'backbones'
DIAGNOSTICS_TOPIC = '/diagnostics'
#: Every wrench's own status (a DiagnosticArray of one status, stamped like the wrench);
#: /diagnostics carries one aggregated array a period (interface.diagnostics_period).
SOLVE_STATUS_TOPIC = 'solve_status'

#: Message types ('package/msg/Name') of the topics above.
WRENCH_TYPE = 'geometry_msgs/msg/WrenchStamped'
POSE_TYPE = 'geometry_msgs/msg/PoseStamped'
POSE_COV_TYPE = 'geometry_msgs/msg/PoseWithCovarianceStamped'
JOINT_STATE_TYPE = 'sensor_msgs/msg/JointState'
FLOAT64_MULTI_ARRAY_TYPE = 'std_msgs/msg/Float64MultiArray'
MARKER_ARRAY_TYPE = 'visualization_msgs/msg/MarkerArray'
DIAGNOSTIC_ARRAY_TYPE = 'diagnostic_msgs/msg/DiagnosticArray'

#: Type of every topic the node subscribes to or publishes.
TOPIC_TYPES: Mapping[str, str] = {
    WRENCH_TOPIC: WRENCH_TYPE,
    END_DISK_POSE_TOPIC: POSE_TYPE,
    BENDING_ANGLES_TOPIC: JOINT_STATE_TYPE,
    COMPLIANCE_EIGENVALUES_TOPIC: FLOAT64_MULTI_ARRAY_TYPE,
    COMPLIANCE_TOPIC: FLOAT64_MULTI_ARRAY_TYPE,
    BACKBONES_TOPIC: MARKER_ARRAY_TYPE,
    DIAGNOSTICS_TOPIC: DIAGNOSTIC_ARRAY_TYPE,
    SOLVE_STATUS_TOPIC: DIAGNOSTIC_ARRAY_TYPE,
}

#: JointState names, in the order of ``joint_positions``.
JOINT_NAMES = ('pj_bending', 'pj_direction', 'dj_bending', 'dj_direction', 'end_disk_rotation')

#: DiagnosticStatus levels (diagnostic_msgs/msg/DiagnosticStatus constants).
OK, WARN, ERROR, STALE = 0, 1, 2, 3

#: DiagnosticStatus name and hardware_id of the translator's status.
DIAGNOSTIC_NAME = 'translator_node: kinestatics'
HARDWARE_ID = 'cdr_translator'

#: Marker geometry that the model does not define (visual only): disk thickness (m).
DISK_THICKNESS_M = 0.001
#: Marker colours (r, g, b, a): primary backbone, secondary backbones, disks and tube.
#: (binary fractions, exact in float32, so that the dicts survive a CDR round trip).
PRIMARY_COLOR = (0.25, 0.5, 1.0, 1.0)
SECONDARY_COLOR = (1.0, 0.5, 0.125, 1.0)
DISK_COLOR = (0.625, 0.625, 0.625, 0.625)
#: visualization_msgs/msg/Marker type constants used here.
MARKER_CYLINDER, MARKER_LINE_STRIP = 3, 4


def stamp_from_ns(time_ns: int) -> dict:
    """Return the builtin_interfaces/Time dict of a time in integer nanoseconds."""
    seconds, nanoseconds = divmod(int(time_ns), 1_000_000_000)
    return {'sec': seconds, 'nanosec': nanoseconds}


def message_field(message: Any, name: str) -> Any:
    """Return field ``name`` of a message given as a dict or as an object with attributes."""
    if type(message) is dict or isinstance(message, Mapping):  # a dict: no ABC check
        return message[name]
    return getattr(message, name)


def stamp_to_ns(stamp: Any) -> int:
    """Return integer nanoseconds of a Time given as a dict or a decoded/rclpy message."""
    return int(message_field(stamp, 'sec')) * 1_000_000_000 + int(message_field(stamp, 'nanosec'))


def header(stamp: Mapping[str, int], frame_id: str) -> dict:
    """Return a std_msgs/Header dict."""
    return {'stamp': {'sec': int(stamp['sec']), 'nanosec': int(stamp['nanosec'])},
            'frame_id': str(frame_id)}


def _vector3(values: ArrayLike, names: str = 'xyz') -> dict:
    """Return a dict of named float components (Vector3, Point, Quaternion with 'xyzw')."""
    return dict(zip(names, np.asarray(values, dtype=float).tolist()))


def wrench_message(force: ArrayLike, moment: ArrayLike, frame_id: str,
                   stamp: Mapping[str, int]) -> dict:
    """Return a geometry_msgs/WrenchStamped dict (force in N, torque in N m)."""
    return {'header': header(stamp, frame_id),
            'wrench': {'force': _vector3(force), 'torque': _vector3(moment)}}


def wrench_from_message(message: Any) -> Tuple[np.ndarray, np.ndarray, str, dict]:
    """
    Return (force, moment, frame_id, stamp) of a WrenchStamped dict or decoded message.

    The values are returned as given (NaN included): validation is the solver's
    ``check_wrench``. ``stamp`` is a ``{'sec', 'nanosec'}`` dict.
    """
    head = message_field(message, 'header')
    wrench = message_field(message, 'wrench')
    force, torque = message_field(wrench, 'force'), message_field(wrench, 'torque')
    stamp = message_field(head, 'stamp')
    return (np.array([float(message_field(force, axis)) for axis in 'xyz']),
            np.array([float(message_field(torque, axis)) for axis in 'xyz']),
            str(message_field(head, 'frame_id')),
            {'sec': int(message_field(stamp, 'sec')),
             'nanosec': int(message_field(stamp, 'nanosec'))})


def _pose(frame: np.ndarray) -> dict:
    """Return the geometry_msgs/Pose dict of a 4x4 homogeneous frame."""
    return {'position': _vector3(frame[:3, 3]),
            'orientation': _vector3(geometry.quaternion_xyzw(frame[:3, :3]), 'xyzw')}


def pose_message(result: Solved, stamp: Mapping[str, int], frame_id: str) -> dict:
    """Return the PoseStamped of the end-disk centre and orientation in the base frame."""
    return {'header': header(stamp, frame_id),
            'pose': {'position': _vector3(result.end_disk_position),
                     'orientation': _vector3(result.end_disk_quaternion_xyzw, 'xyzw')}}


def joint_positions(result: Solved) -> List[float]:
    """Return the JointState positions (rad) in the order of ``JOINT_NAMES``."""
    pj_theta, pj_delta = result.pj_bending
    dj_theta, dj_delta = result.dj_bending
    return [float(pj_theta), float(pj_delta), float(dj_theta), float(dj_delta),
            float(result.end_disk_rotation)]


def joint_state_message(result: Solved, stamp: Mapping[str, int],
                        frame_id: str = '') -> dict:
    """Return the sensor_msgs/JointState of the bending angles and directions (rad)."""
    return {'header': header(stamp, frame_id), 'name': list(JOINT_NAMES),
            'position': joint_positions(result), 'velocity': [], 'effort': []}


def _compliance(result: Solved) -> Any:
    """Return ``result.compliance``; ValueError when the solve did not compute it."""
    compliance = getattr(result, 'compliance', None)
    if compliance is None:
        raise ValueError('the result holds no compliance: solve with compliance=True')
    return compliance


def compliance_eigenvalues_message(result: Solved) -> dict:
    """
    Return the Float64MultiArray of the six compliance eigenvalues (SI), ordered by axis.

    One dimension labelled 'eigenvalue'. They come in the order of the analysis' labels
    (the axis each eigenvector mostly moves along, ComplianceAnalysis), not by size, and mix
    units (m/N, rad/(N m) and their couplings), as the 6x6 compliance matrix does.
    """
    values = [float(value) for value in np.asarray(_compliance(result).eigenvalues).ravel()]
    return {'layout': {'dim': [{'label': 'eigenvalue', 'size': len(values),
                                'stride': len(values)}],
                       'data_offset': 0},
            'data': values}


def compliance_message(result: Solved) -> dict:
    """
    Return the Float64MultiArray of the 6x6 compliance matrix, row-major.

    Layout dims 'rows' (size 6, stride 36) and 'cols' (size 6, stride 6), so element
    (i, j) is ``data[6 * i + j]``: the twist component i per unit wrench component j,
    wrench [f; m] in the base frame at the end-disk centre, twist [v; w].
    """
    return matrix_message(np.asarray(_compliance(result).matrix, dtype=float))


def matrix_message(matrix: np.ndarray) -> dict:
    """Return the Float64MultiArray of a matrix, row-major, layout dims 'rows' and 'cols'."""
    rows, cols = matrix.shape
    return {'layout': {'dim': [{'label': 'rows', 'size': rows, 'stride': rows * cols},
                               {'label': 'cols', 'size': cols, 'stride': cols}],
                       'data_offset': 0},
            'data': [float(value) for value in matrix.ravel()]}


def _color(rgba: Sequence[float]) -> dict:
    """Return a std_msgs/ColorRGBA dict."""
    return _vector3(rgba, 'rgba')


def _marker(head: dict, namespace: str, marker_id: int, marker_type: int, pose: dict,
            scale: Sequence[float], color: Sequence[float],
            points: Optional[list] = None) -> dict:
    """Return one visualization_msgs/Marker dict (action ADD, never expiring)."""
    return {'header': head, 'ns': namespace, 'id': marker_id, 'type': marker_type,
            'action': 0, 'pose': pose, 'scale': _vector3(scale), 'color': _color(color),
            'lifetime': {'sec': 0, 'nanosec': 0}, 'frame_locked': False,
            'points': points or [], 'colors': [], 'texture_resource': '',
            'texture': {'header': header({'sec': 0, 'nanosec': 0}, ''), 'format': '',
                        'data': b''},
            'uv_coordinates': [], 'text': '', 'mesh_resource': '',
            'mesh_file': {'filename': '', 'data': b''},
            'mesh_use_embedded_materials': False}


def backbones_message(result: SolveResult, params: TranslatorParams,
                      stamp: Mapping[str, int], frame_id: str) -> dict:
    """
    Return the MarkerArray of the deflected translator, in the base frame.

    Namespace 'backbones': one LINE_STRIP per rod (id 0 the primary, 1-4 the secondaries)
    through ``result.backbones``, line width the backbone diameter. Namespace 'disks': a
    CYLINDER at each frame 'pe', 'pm', 'dm', 'de' (ids 0-3; the base disk, the tube faces,
    the end disk), radius pitch radius + backbone diameter, ``DISK_THICKNESS_M`` thick.
    Namespace 'tube': the rigid multi-lumen tube as one CYLINDER from 'pm' to 'dm'.
    """
    head = header(stamp, frame_id)
    identity = {'position': _vector3((0.0, 0.0, 0.0)),
                'orientation': _vector3((0.0, 0.0, 0.0, 1.0), 'xyzw')}
    width = params.backbone_diameter
    markers = [
        _marker(head, 'backbones', index, MARKER_LINE_STRIP, identity, (width, 0.0, 0.0),
                PRIMARY_COLOR if index == 0 else SECONDARY_COLOR,
                [_vector3(point) for point in rod])
        for index, rod in enumerate(np.asarray(result.backbones))]
    diameter = 2.0 * (params.pitch_radius + params.backbone_diameter)
    for index, name in enumerate(('pe', 'pm', 'dm', 'de')):
        markers.append(_marker(head, 'disks', index, MARKER_CYLINDER,
                               _pose(result.frames[name]),
                               (diameter, diameter, DISK_THICKNESS_M), DISK_COLOR))
    proximal, distal = result.frames['pm'], result.frames['dm']
    tube = proximal.copy()
    tube[:3, 3] = 0.5 * (proximal[:3, 3] + distal[:3, 3])
    length = float(np.linalg.norm(distal[:3, 3] - proximal[:3, 3]))
    markers.append(_marker(head, 'tube', 0, MARKER_CYLINDER, _pose(tube),
                           (diameter, diameter, length), DISK_COLOR))
    return {'markers': markers}


def value_text(value: Any) -> str:
    """Format a diagnostic value: bools lower case, floats with 6 significant digits."""
    kind = type(value)   # the plain types first: a status per wrench formats a dozen
    if kind is float:
        return f'{value:.6g}'
    if kind is bool:
        return 'true' if value else 'false'
    if kind is int or kind is str:
        return str(value)
    if isinstance(value, (bool, np.bool_)):
        return 'true' if value else 'false'
    if isinstance(value, (float, np.floating)):
        return f'{float(value):.6g}'
    return str(value)


def diagnostics_message(stamp: Mapping[str, int], level: int, message: str,
                        values: Mapping[str, Any], *, name: str = DIAGNOSTIC_NAME,
                        hardware_id: str = HARDWARE_ID) -> dict:
    """
    Return a DiagnosticArray dict holding one DiagnosticStatus.

    ``level`` is OK, WARN, ERROR or STALE; ``values`` become KeyValue pairs in their order
    (bools 'true'/'false', floats with 6 significant digits, anything else ``str``).
    """
    if level not in (OK, WARN, ERROR, STALE):
        raise ValueError(f'diagnostic level must be 0, 1, 2 or 3, got {level!r}')
    return {'header': header(stamp, ''),
            'status': [{'level': int(level), 'name': name, 'message': str(message),
                        'hardware_id': hardware_id,
                        'values': [{'key': str(key), 'value': value_text(value)}
                                   for key, value in values.items()]}]}


def solve_diagnostic_values(result: Solved) -> dict:
    """Return the key/values that describe one solve: converged, residual, iterations, time."""
    values = {'converged': bool(result.converged),
              'residual_norm': float(result.residual_norm),
              'iterations': int(result.iterations),
              'solve_time_ms': 1e3 * float(result.solve_time_s),
              'method': result.method,
              'fidelity': getattr(result, 'fidelity', 'full')}
    compliance = getattr(result, 'compliance', None)
    if compliance is not None:
        values['stable'] = bool(compliance.stable)
    stable = getattr(result, 'stable', None)
    if stable is not None:  # the solve's own verdict (docs/explanation/solution_quality.md) wins
        values['stable'] = bool(stable)
        values['stability_margin'] = float(result.stability_margin)
    if math.isfinite(getattr(result, 'error_estimate_m', math.nan)):
        values['error_estimate_m'] = float(result.error_estimate_m)
        values['error_estimate_deg'] = float(result.error_estimate_deg)
        met = getattr(result, 'accuracy_met', None)
        if met is not None:  # None: no target was checked, which is no "met"
            values['accuracy_met'] = bool(met)
        values['steps_per_segment'] = int(result.steps_per_segment)
    return values


def solve_level(result: Solved) -> int:
    """
    Return ERROR if the solve failed, WARN if it converged to an answer not to act on, else OK.

    Not to act on: an unstable equilibrium (the solve's verdict, or the compliance's when
    only that was computed), or one whose estimated discretization error misses the
    accuracy target (docs/explanation/solution_quality.md).
    """
    if not result.converged:
        return ERROR
    stable = getattr(result, 'stable', None)
    if stable is None:
        compliance = getattr(result, 'compliance', None)
        stable = compliance.stable if compliance is not None else True
    # accuracy_met None (nothing estimated) is no shortfall; only False warns
    return OK if stable and getattr(result, 'accuracy_met', None) is not False else WARN


def output_messages(result: Solved, stamp: Mapping[str, int], base_frame: str, *,
                    compliance: bool = True, backbones_params: Optional[TranslatorParams] = None,
                    extra_values: Optional[Mapping[str, Any]] = None
                    ) -> List[Tuple[str, str, dict]]:
    """
    Return (topic, type, message) of everything published for one solved wrench.

    A converged result gives the pose, the bending angles, the compliance eigenvalues and
    matrix (when ``compliance`` and the result holds one) and the backbone markers (when
    ``backbones_params`` is given); every result, converged or not, gives its status on
    ``SOLVE_STATUS_TOPIC`` (a DiagnosticArray of one status, stamped ``stamp``), whose values
    are ``solve_diagnostic_values`` followed by ``extra_values`` (e.g. the follower load's
    solves). A result that did not converge publishes no pose: only an ERROR status.
    """
    return list(iter_output_messages(result, stamp, base_frame, compliance=compliance,
                                     backbones_params=backbones_params,
                                     extra_values=extra_values))


def iter_output_messages(result: Solved, stamp: Mapping[str, int], base_frame: str, *,
                         compliance: bool = True,
                         backbones_params: Optional[TranslatorParams] = None,
                         extra_values: Optional[Mapping[str, Any]] = None
                         ) -> Iterator[Tuple[str, str, dict]]:
    """
    Yield what ``output_messages`` returns, in the same order, each built when asked for.

    The pose comes first: translator_node publishes it before it builds the others.
    """
    if result.converged:
        yield END_DISK_POSE_TOPIC, POSE_TYPE, pose_message(result, stamp, base_frame)
        yield (BENDING_ANGLES_TOPIC, JOINT_STATE_TYPE,
               joint_state_message(result, stamp, base_frame))
        if compliance and getattr(result, 'compliance', None) is not None:
            yield (COMPLIANCE_EIGENVALUES_TOPIC, FLOAT64_MULTI_ARRAY_TYPE,
                   compliance_eigenvalues_message(result))
            yield COMPLIANCE_TOPIC, FLOAT64_MULTI_ARRAY_TYPE, compliance_message(result)
        if backbones_params is not None:
            if not isinstance(result, SolveResult):
                raise ValueError("backbones need a solve's result: a batch row keeps no shape")
            yield (BACKBONES_TOPIC, MARKER_ARRAY_TYPE,
                   backbones_message(result, backbones_params, stamp, base_frame))
    values = solve_diagnostic_values(result)
    values.update(extra_values or {})
    yield (SOLVE_STATUS_TOPIC, DIAGNOSTIC_ARRAY_TYPE,
           diagnostics_message(stamp, solve_level(result), result.message, values))


def rejection_messages(stamp: Mapping[str, int], reason: str,
                       extra_values: Optional[Mapping[str, Any]] = None, *,
                       name: str = DIAGNOSTIC_NAME, topic: str = DIAGNOSTICS_TOPIC
                       ) -> List[Tuple[str, str, dict]]:
    """
    Return (topic, type, message) published for an input that was not solved (ERROR).

    ``name`` is the status of the stage the input was for (the translator's solve);
    ``topic`` where it goes (translator_node: ``SOLVE_STATUS_TOPIC``; cdr_node: /diagnostics).
    """
    values = {'converged': False}
    values.update(extra_values or {})
    return [(topic, DIAGNOSTIC_ARRAY_TYPE,
             diagnostics_message(stamp, ERROR, reason, values, name=name))]

"""
What cdr_node reads and publishes, as plain message dicts (no rclpy): topics and builders.

Forward statics: ``sliders`` and ``platform_wrench`` in, ``platform_pose``,
``leg_bending_angles``, ``leg_tip_wrenches`` and ``/diagnostics`` out. Inverse statics:
``target_position`` (geometry_msgs/PointStamped, the platform centre wanted, world frame)
in, ``slider_command`` (sensor_msgs/JointState, one position per slider, m, named
``SLIDER_NAMES``) and ``predicted_platform_pose`` (geometry_msgs/PoseStamped: where the
platform goes under the current payload at those sliders, its parasitic rotation
included) out, with a diagnostic; an unreachable target publishes no command, only an
ERROR diagnostic naming the nearest reachable point and the binding stroke limits.

The dict shapes are cdr_translator.interface.messages' (the translator node's), which this
module reuses for headers, diagnostics and each leg's joint angles; the node fills rclpy
messages from them and logs those.
"""

from typing import Any, List, Mapping, Optional, Sequence, Tuple

import numpy as np

from . import messages
from .. import geometry
from ..robot.inverse import InverseResult
from ..robot.result import DeltaResult

#: Inputs: the payload on the platform, and the slider positions.
PLATFORM_WRENCH_TOPIC = 'platform_wrench'
SLIDERS_TOPIC = 'sliders'
#: Input of the inverse statics: the platform target position.
TARGET_TOPIC = 'target_position'
#: Outputs (relative names, /diagnostics absolute as in every ROS 2 node).
PLATFORM_POSE_TOPIC = 'platform_pose'
SLIDER_COMMAND_TOPIC = 'slider_command'
PREDICTED_POSE_TOPIC = 'predicted_platform_pose'
LEG_ANGLES_TOPIC = 'leg_bending_angles'
LEG_WRENCHES_TOPIC = 'leg_tip_wrenches'
DIAGNOSTICS_TOPIC = messages.DIAGNOSTICS_TOPIC

#: Names a sliders JointState may give its positions (any order), leg 1 to 3.
SLIDER_NAMES = ('slider_1', 'slider_2', 'slider_3')

#: Names of the leg_bending_angles JointState: the translator node's joints, per leg.
LEG_JOINT_NAMES = tuple(f'leg{leg}_{name}' for leg in (1, 2, 3)
                        for name in messages.JOINT_NAMES)

#: DiagnosticStatus name of the robot's status.
DIAGNOSTIC_NAME = 'cdr_node: forward statics'
#: DiagnosticStatus name of an inverse-statics answer.
INVERSE_DIAGNOSTIC_NAME = 'cdr_node: inverse statics'
#: The status that reports an input's rejection (unreadable, wrong frame, bad value): the
#: stage it was for. The payload is the forward statics' input (the inverse takes the latest).
INPUT_DIAGNOSTIC_NAMES = {SLIDERS_TOPIC: DIAGNOSTIC_NAME, PLATFORM_WRENCH_TOPIC: DIAGNOSTIC_NAME,
                          TARGET_TOPIC: INVERSE_DIAGNOSTIC_NAME}


def sliders_from_joint_state(names: Sequence[str], positions: Sequence[float]) -> np.ndarray:
    """
    Return the three slider positions (m, legs 1 to 3) carried by a JointState.

    Either ``names`` is empty and there are exactly three positions, in leg order, or the
    names are ``SLIDER_NAMES`` in any order with one position each. ValueError otherwise;
    the values themselves are checked by the solver (finite, within the stroke).
    """
    names, positions = list(names), [float(value) for value in positions]
    if not names:
        if len(positions) != 3:
            raise ValueError(f'an unnamed sliders JointState needs 3 positions, got '
                             f'{len(positions)}')
        return np.array(positions)
    if sorted(names) != sorted(SLIDER_NAMES) or len(positions) != len(names):
        raise ValueError(f'sliders JointState names must be {list(SLIDER_NAMES)} (any order) '
                         f'with one position each, got names {names} and {len(positions)} '
                         'positions')
    by_name = dict(zip(names, positions))
    return np.array([by_name[name] for name in SLIDER_NAMES])


def target_from_point(message: Any) -> Tuple[np.ndarray, str, dict]:
    """
    Return (target (3,) m, frame_id, stamp) of a PointStamped dict or decoded message.

    Values as given (NaN included): the inverse solver validates them.
    """
    head = messages.message_field(message, 'header')
    point = messages.message_field(message, 'point')
    stamp = messages.message_field(head, 'stamp')
    return (np.array([float(messages.message_field(point, axis)) for axis in 'xyz']),
            str(messages.message_field(head, 'frame_id')),
            {'sec': int(messages.message_field(stamp, 'sec')),
             'nanosec': int(messages.message_field(stamp, 'nanosec'))})


def point_message(target: Sequence[float], stamp: Mapping[str, int], frame_id: str) -> dict:
    """Return a geometry_msgs/PointStamped dict of a target position (m)."""
    return {'header': messages.header(stamp, frame_id),
            'point': dict(zip('xyz', map(float, target)))}


def slider_command_message(result: InverseResult, stamp: Mapping[str, int],
                           frame_id: str) -> dict:
    """Return the JointState commanding the sliders (m, legs 1 to 3)."""
    return {'header': messages.header(stamp, frame_id), 'name': list(SLIDER_NAMES),
            'position': [float(value) for value in result.sliders], 'velocity': [],
            'effort': []}


def inverse_output_messages(result: InverseResult, stamp: Mapping[str, int], frame_id: str,
                            extra_values: Optional[Mapping[str, Any]] = None
                            ) -> List[Tuple[str, str, dict]]:
    """
    Return (topic, type, message) of everything published for one inverse solve.

    A reached target gives the slider command and the predicted platform pose (with its
    parasitic rotation); every result gives a diagnostic: OK, WARN when the predicted pose
    is not stable, ERROR (no command) when the target is unreachable or the solve failed.
    """
    built = []
    forward = result.forward
    reached = result.converged and result.reachable and forward is not None
    if reached and forward is not None:
        built = [(SLIDER_COMMAND_TOPIC, messages.JOINT_STATE_TYPE,
                  slider_command_message(result, stamp, frame_id)),
                 (PREDICTED_POSE_TOPIC, messages.POSE_TYPE,
                  platform_pose_message(forward, stamp, frame_id))]
    values = {'converged': bool(result.converged), 'reachable': bool(result.reachable),
              'position_error_m': float(result.position_error),
              'platform_rotation_deg': float(np.degrees(result.platform_rotation_angle)),
              'binding_limits': ', '.join(result.binding) or 'none',
              'iterations': int(result.iterations),
              'forward_solves': int(result.forward_solves),
              'solve_time_ms': 1e3 * float(result.solve_time_s)}
    stable = None if result.forward is None else result.forward.stable
    if stable is not None:
        values['stable'] = bool(stable)
    values.update(extra_values or {})
    level = messages.ERROR if not reached else (messages.WARN if stable is False
                                                else messages.OK)
    built.append((DIAGNOSTICS_TOPIC, messages.DIAGNOSTIC_ARRAY_TYPE,
                  messages.diagnostics_message(stamp, level, result.message, values,
                                               name=INVERSE_DIAGNOSTIC_NAME)))
    return built


def platform_pose_message(result: DeltaResult, stamp: Mapping[str, int],
                          frame_id: str) -> dict:
    """Return the PoseStamped of the platform origin and orientation in the world frame."""
    quaternion = geometry.quaternion_xyzw(result.platform_rotation)
    return {'header': messages.header(stamp, frame_id),
            'pose': {'position': dict(zip('xyz', map(float, result.platform_position))),
                     'orientation': dict(zip('xyzw', map(float, quaternion)))}}


def leg_angles_message(result: DeltaResult, stamp: Mapping[str, int], frame_id: str) -> dict:
    """Return the JointState of every leg's bending angles and directions (rad)."""
    positions = [value for leg in result.leg_results for value in messages.joint_positions(leg)]
    return {'header': messages.header(stamp, frame_id), 'name': list(LEG_JOINT_NAMES),
            'position': positions, 'velocity': [], 'effort': []}


def leg_wrenches_message(result: DeltaResult) -> dict:
    """
    Return the Float64MultiArray of the leg tip wrenches, row-major (3 legs x 6).

    Row i is [fx, fy, fz, mx, my, mz] (N, N m): the wrench the platform applies to leg i's
    end disk, in leg i's base frame, moment about the end-disk centre.
    """
    wrenches = np.asarray(result.leg_tip_wrenches, dtype=float)
    return {'layout': {'dim': [{'label': 'legs', 'size': 3, 'stride': 18},
                               {'label': 'wrench', 'size': 6, 'stride': 6}],
                       'data_offset': 0},
            'data': [float(value) for value in wrenches.ravel()]}


def solve_diagnostic_values(result: DeltaResult) -> dict:
    """Return the key/values that describe one solve."""
    return {'converged': bool(result.converged),
            'equilibrium_residual_norm': float(result.equilibrium_residual_norm),
            'platform_rotation_deg': float(np.degrees(result.platform_rotation_angle)),
            'iterations': int(result.iterations),
            'leg_solves': int(result.leg_solves),
            'solve_time_ms': 1e3 * float(result.solve_time_s)}


def output_messages(result: DeltaResult, stamp: Mapping[str, int], frame_id: str,
                    extra_values: Optional[Mapping[str, Any]] = None
                    ) -> List[Tuple[str, str, dict]]:
    """
    Return (topic, type, message) of everything published for one solve.

    A converged result gives the platform pose, the leg angles and the leg wrenches; every
    result gives a diagnostic (OK, or ERROR with the solver's message and no pose).
    """
    built = []
    if result.converged:
        built = [(PLATFORM_POSE_TOPIC, messages.POSE_TYPE,
                  platform_pose_message(result, stamp, frame_id)),
                 (LEG_ANGLES_TOPIC, messages.JOINT_STATE_TYPE,
                  leg_angles_message(result, stamp, frame_id)),
                 (LEG_WRENCHES_TOPIC, messages.FLOAT64_MULTI_ARRAY_TYPE,
                  leg_wrenches_message(result))]
    values = solve_diagnostic_values(result)
    values.update(extra_values or {})
    level = messages.OK if result.converged else messages.ERROR
    built.append((DIAGNOSTICS_TOPIC, messages.DIAGNOSTIC_ARRAY_TYPE,
                  messages.diagnostics_message(stamp, level, result.message, values,
                                               name=DIAGNOSTIC_NAME)))
    return built


def rejection_messages(stamp: Mapping[str, int], reason: str,
                       extra_values: Optional[Mapping[str, Any]] = None, *,
                       name: str = DIAGNOSTIC_NAME) -> List[Tuple[str, str, dict]]:
    """
    Return (topic, type, message) published for an input that was not used (ERROR).

    ``name`` is the status of the stage the input was for: ``DIAGNOSTIC_NAME`` (sliders,
    payload) or ``INVERSE_DIAGNOSTIC_NAME`` (a target), as ``INPUT_DIAGNOSTIC_NAMES`` says.
    """
    return messages.rejection_messages(stamp, reason, extra_values, name=name)

"""
What cdr_node does with one measured platform pose, without ROS: checks, the payload estimate.

A ``measured_platform_pose`` (geometry_msgs/PoseStamped) or ``measured_platform_pose_cov``
(PoseWithCovarianceStamped, covariance row-major 6x6 in x, y, z, rotation about x, y, z)
in the world frame (or with an empty frame_id) gives ``estimated_payload`` (WrenchStamped:
force at the platform origin and moment, in the world frame, stamped like the pose),
``estimated_payload_covariance`` (Float64MultiArray, 6x6 row-major, with a pose covariance
only) and a diagnostic, at the slider positions last received
(``DeltaRobot.estimate_payload``, cdr_translator/robot/payload_estimate.py).
"""

from typing import Callable, List, Mapping, Tuple

import numpy as np

from .pose_estimation import check_pose, estimate_messages, MeasuredPose
from .pose_estimation import MeasuredPoseProcessor
from .settings import CdrSettings
from ..estimation import WrenchEstimate
from ..robot.delta import DeltaRobot

#: Inputs: a measured platform pose, without and with its covariance.
MEASURED_PLATFORM_POSE_TOPIC = 'measured_platform_pose'
MEASURED_PLATFORM_POSE_COV_TOPIC = 'measured_platform_pose_cov'
#: Outputs: the estimated payload and its covariance.
ESTIMATED_PAYLOAD_TOPIC = 'estimated_payload'
ESTIMATED_PAYLOAD_COVARIANCE_TOPIC = 'estimated_payload_covariance'

#: DiagnosticStatus name of the robot's payload estimates.
PAYLOAD_DIAGNOSTIC_NAME = 'cdr_node: payload estimate'


class PayloadProcessor(MeasuredPoseProcessor):
    """
    cdr_node's measured platform poses: the payload at the latest sliders, warm along them.

    ``sliders()`` returns the slider positions (m) to estimate at: the node's last received.
    The robot is this processor's own, so that the estimates warm-start along themselves.
    """

    diagnostic_name = PAYLOAD_DIAGNOSTIC_NAME

    def __init__(self, settings: CdrSettings, sliders: Callable[[], np.ndarray]) -> None:
        """Build the robot of the estimates (the node's model and time limit)."""
        super().__init__()
        self.settings = settings
        self.sliders = sliders
        self.robot = DeltaRobot(settings.params, settings.geometry,
                                time_limit_s=settings.solve_time_limit_s)

    def check(self, measured: MeasuredPose) -> None:
        """
        Raise InputError for another frame, a non-finite value, a bad quaternion.

        The values too, although the estimate checks them: it names them as the robot's
        (platform_position, ...), a rejection as the measured pose's (position, ...).
        """
        check_pose(measured, self.settings.world_frame, self.robot.params.stack_height)

    def estimate(self, measured: MeasuredPose) -> WrenchEstimate:
        """Estimate the payload at the latest sliders, within the node's payload limits."""
        return self.robot.estimate_payload(measured.position, self.sliders(),
                                           measured.quaternion_xyzw,
                                           covariance=measured.covariance,
                                           max_force=self.settings.max_force,
                                           max_moment=self.settings.max_moment)

    def outputs(self, estimate: WrenchEstimate, stamp: Mapping[str, int],
                counts: Mapping[str, int]) -> List[Tuple[str, str, dict]]:
        """Return the estimated payload, its covariance and the diagnostic."""
        return estimate_messages(estimate, stamp, self.settings.world_frame, counts,
                                 wrench_topic=ESTIMATED_PAYLOAD_TOPIC,
                                 covariance_topic=ESTIMATED_PAYLOAD_COVARIANCE_TOPIC,
                                 name=PAYLOAD_DIAGNOSTIC_NAME)

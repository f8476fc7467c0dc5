"""
Measured end-disk poses in a replay: the wrench estimates translator_node would have published.

Each pose is handled as the node does (``pose_estimation.PoseProcessor``: the same checks,
the estimation solver warm-started along the stream, the same messages); both measured-pose
topics of one namespace share one processor, as they share one in the node. The input
and the outputs (``estimated_wrench``, ``estimated_wrench_covariance``, ``estimate_status``,
in the input's namespace; the aggregated /diagnostics: ``msg_tools.replay_diagnostics``) are
written with the input's log time; a pose's CSV row holds the estimate
(``replay_csv.pose_row``).
The summary counts every pose as estimated, flagged, failed or rejected.
"""

from typing import Any, Dict, Optional, Sequence, Tuple

from cdr_translator.interface import messages
from cdr_translator.interface.pose_estimation import pose_from_message, PoseProcessor
from cdr_translator.interface.settings import TranslatorSettings
from cdr_wire.mcap_log import McapLog
from cdr_wire.reader import Decoders, RawMessage
from msg_tools.replay_csv import csv_row, pose_row
from msg_tools.replay_summary import ReplaySummary
from msg_tools.replay_topics import output_topic, POSE_INPUTS


def pose_processors(topics: Sequence[str], settings: TranslatorSettings
                    ) -> Dict[str, PoseProcessor]:
    """Return the processor of each measured-pose topic: one per namespace."""
    by_namespace: Dict[str, PoseProcessor] = {}
    return {topic: by_namespace.setdefault(output_topic(topic, ''),
                                           PoseProcessor(settings.params, settings))
            for topic in topics}


def register_poses(log: McapLog, topics: Sequence[str]) -> None:
    """Register the measured-pose input topics in the output, as the node logs them."""
    for topic in topics:
        log.register(topic, POSE_INPUTS[topic.rsplit('/', 1)[-1]], qos='sensor_data')


def replay_pose(log: McapLog, raw: RawMessage, processor: PoseProcessor, decoders: Decoders,
                summary: ReplaySummary, index: int, table: Optional[Any] = None) -> None:
    """
    Write one measured pose and what the node publishes for it; count it in ``summary``.

    ``table``: the CSV writer (None: no CSV), which gets the pose's row.
    """
    summary.poses += 1
    log.write_serialized(raw.topic, POSE_INPUTS[raw.topic.rsplit('/', 1)[-1]], raw.data,
                         raw.log_time_ns, raw.publish_time_ns)
    try:
        message = decoders.decode(raw)
    except ValueError as error:
        summary.undecodable += 1
        summary.rejected_poses += 1
        summary.warn(f'message {index} on {raw.topic}: {error}')
        if table:
            table.writerow(csv_row({'index': index, 'topic': raw.topic,
                                    'log_time_ns': raw.log_time_ns, 'status': 'undecodable',
                                    'message': str(error)}))
        return
    outcome = processor.process(message)
    estimate = outcome.estimate
    if estimate is None:
        summary.rejected_poses += 1
    else:
        summary.estimate_times.add(estimate.estimate_time_s)
        if not estimate.converged:
            summary.failed += 1
        elif estimate.flagged:
            summary.flagged += 1
        else:
            summary.estimated += 1
        if estimate.flags:
            summary.count_reasons(estimate.flags)
    for name, type_name, values in outcome.outputs:
        log.write(output_topic(raw.topic, name), type_name, values, raw.log_time_ns,
                  raw.log_time_ns)
    if table:
        table.writerow(pose_row(index, raw, *_stamp_and_frame(message), estimate,
                                outcome.error))


def _stamp_and_frame(message: Any) -> Tuple[Optional[int], str]:
    """Return (header stamp in ns or None, frame id) of a measured pose message."""
    try:
        measured = pose_from_message(message)
        return messages.stamp_to_ns(measured.stamp), measured.frame_id
    except (ValueError, AttributeError, TypeError):
        return None, ''

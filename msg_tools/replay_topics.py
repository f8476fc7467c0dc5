"""
Which wrench topics of an MCAP a replay takes, and where their outputs go.

Without a choice every WrenchStamped channel is replayed but the nodes' estimates
(``ESTIMATE_OUTPUTS``, which a node's own log holds); each output lands in the
namespace of its input topic, as the node started in that namespace would publish it, so
two inputs in one namespace are refused (their outputs would be mixed). Measured end-disk
poses (``POSE_INPUTS``: a topic of that name and type, in any namespace) are replayed
beside them, as translator_node estimates the wrench from them.
"""

from typing import Dict, List, Optional, Sequence, Tuple

from cdr_translator.interface import messages, payload_estimation, pose_estimation
from cdr_wire.reader import McapSource
from msg_tools.errors import ReplayError


#: The measured-pose inputs a replay takes beside the wrenches: topic name -> type.
POSE_INPUTS = {name: pose_estimation.ESTIMATION_TOPIC_TYPES[name]
               for name in (pose_estimation.MEASURED_POSE_TOPIC,
                            pose_estimation.MEASURED_POSE_COV_TOPIC)}


#: WrenchStamped topics the nodes publish (estimates), never taken as wrench inputs unasked.
ESTIMATE_OUTPUTS = frozenset((pose_estimation.ESTIMATED_WRENCH_TOPIC,
                              payload_estimation.ESTIMATED_PAYLOAD_TOPIC))


def is_pose_input(topic: str, type_name: str) -> bool:
    """Tell whether ``topic`` of type ``type_name`` is a measured pose translator_node takes."""
    return POSE_INPUTS.get(topic.rsplit('/', 1)[-1]) == type_name


def output_topic(input_topic: str, name: str) -> str:
    """
    Return the node's output topic ``name`` in the namespace of ``input_topic``.

    The namespace is everything before the topic's last name: '/robot/wrench' and
    '/robot/wrench_filtered' both give '/robot/' (a remapped input, as the node would have
    been started in that namespace), '/wrench' gives '/'.
    """
    if name.startswith('/'):
        return name
    return input_topic.rsplit('/', 1)[0] + '/' + name


def select_topics(source: McapSource, requested: Optional[Sequence[str]]
                  ) -> Tuple[List[str], List[str], Optional[int], List[str]]:
    """
    Return (wrench topics, warnings, number of their messages if known, pose topics).

    Without ``requested``: every channel whose schema is WrenchStamped, estimates aside. A
    requested topic that is missing or has another schema is a warning; none usable is a
    ReplayError that lists what the file holds. The measured-pose topics are all those of
    the file, or those requested. One overview serves both: a damaged file is read once.
    """
    channels, schemas, counts, _ = source.channel_overview()
    types: Dict[str, str] = {}
    for channel in channels.values():
        schema = schemas.get(channel.schema_id)
        types[channel.topic] = schema.name if schema is not None else '(no schema)'
    poses = sorted(topic for topic, type_name in types.items()
                   if is_pose_input(topic, type_name) and (not requested or topic in requested))
    available = ', '.join(f'{topic} [{type_name}]' for topic, type_name in sorted(types.items()))
    warnings = []
    if requested:
        chosen = []
        for topic in requested:
            if topic not in types:
                warnings.append(f'topic {topic!r} is not in {source.path}')
            elif is_pose_input(topic, types[topic]):
                continue  # a measured pose: in ``poses``
            elif types[topic] != messages.WRENCH_TYPE:
                warnings.append(f'topic {topic!r} has schema {types[topic]!r}, not '
                                f'{messages.WRENCH_TYPE!r}: skipped')
            else:
                chosen.append(topic)
    else:
        chosen = sorted(topic for topic, type_name in types.items()
                        if type_name == messages.WRENCH_TYPE
                        and topic.rsplit('/', 1)[-1] not in ESTIMATE_OUTPUTS)
    if not chosen:
        damage = ('' if source.report.complete
                  else f'; the file is damaged: {source.report.describe()}')
        raise ReplayError('; '.join(warnings + [
            f'no {messages.WRENCH_TYPE} topic to replay in {source.path}; it holds: '
            f'{available or "no channels"}{damage}']))
    shared = _sharing_a_namespace(chosen)
    if shared:
        raise ReplayError(f'the wrench topics {" and ".join(shared)} are in one namespace, so '
                          'their outputs would be mixed on the same topics; replay one at a '
                          'time with --topic')
    total = None
    if counts is not None:
        total = sum(count for channel_id, count in counts.items()
                    if channel_id in channels and channels[channel_id].topic in chosen)
    return chosen, warnings, total, poses


def _sharing_a_namespace(topics: Sequence[str]) -> List[str]:
    """Return the first two of ``topics`` whose outputs would land on the same topics."""
    seen: Dict[str, str] = {}
    for topic in topics:
        namespace = output_topic(topic, '')
        if namespace in seen:
            return [seen[namespace], topic]
        seen[namespace] = topic
    return []

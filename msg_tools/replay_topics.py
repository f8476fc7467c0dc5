"""
Which wrench topics of an MCAP a replay takes, and where their outputs go.

Without a choice every WrenchStamped channel is replayed; each output lands in the
namespace of its input topic, as the node started in that namespace would publish it, so
two inputs in one namespace are refused (their outputs would be mixed).
"""

from typing import Dict, List, Optional, Sequence, Tuple

from cdr_translator.interface import messages
from msg_tools.errors import ReplayError
from msg_tools.reader import McapSource


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
                  ) -> Tuple[List[str], List[str], Optional[int]]:
    """
    Return (topics to replay, warnings, number of their messages if known).

    Without ``requested``: every channel whose schema is WrenchStamped. A requested topic
    that is missing or has another schema is a warning; none usable is a ReplayError that
    lists what the file holds.
    """
    channels, schemas, counts, _ = source.channel_overview()
    types: Dict[str, str] = {}
    for channel in channels.values():
        schema = schemas.get(channel.schema_id)
        types[channel.topic] = schema.name if schema is not None else '(no schema)'
    available = ', '.join(f'{topic} [{type_name}]' for topic, type_name in sorted(types.items()))
    warnings = []
    if requested:
        chosen = []
        for topic in requested:
            if topic not in types:
                warnings.append(f'topic {topic!r} is not in {source.path}')
            elif types[topic] != messages.WRENCH_TYPE:
                warnings.append(f'topic {topic!r} has schema {types[topic]!r}, not '
                                f'{messages.WRENCH_TYPE!r}: skipped')
            else:
                chosen.append(topic)
    else:
        chosen = sorted(topic for topic, type_name in types.items()
                        if type_name == messages.WRENCH_TYPE)
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
    return chosen, warnings, total


def _sharing_a_namespace(topics: Sequence[str]) -> List[str]:
    """Return the first two of ``topics`` whose outputs would land on the same topics."""
    seen: Dict[str, str] = {}
    for topic in topics:
        namespace = output_topic(topic, '')
        if namespace in seen:
            return [seen[namespace], topic]
        seen[namespace] = topic
    return []

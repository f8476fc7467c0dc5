"""
``--help`` of both nodes, written from the declarations the node itself uses.

The parameters are the node's specs (cdr_translator.interface.settings) with the shipped
defaults and their ROS types (cdr_translator.params.params_file), the topics the node's own
topic -> message class tables, the exit codes ``spin.run``'s.
"""

from typing import Any, Iterable, List, Mapping, Sequence, Tuple

from .parameters import node_arguments
from ..console import EXIT_INTERRUPTED
from ..interface.settings import ParameterSpec
from ..params.params_file import declared_type

__all__ = ['EXIT_CANNOT_START', 'EXIT_CODES', 'HELP_FLAGS', 'help_text', 'wants_help']

#: Exit code of a node that cannot start: bad parameters or params file, unwritable log.
EXIT_CANNOT_START = 2

#: Every exit code of a node, with its meaning.
EXIT_CODES = (
    (0, 'stopped by SIGINT or SIGTERM once running (MCAP log finalized), or --help'),
    (EXIT_CANNOT_START, 'cannot start: a missing or unparsable --params-file, a bad '
     '-p name:=value, a parameter out of range, an MCAP log that cannot be written'),
    (EXIT_INTERRUPTED, 'Ctrl-C (SIGINT) during start-up'),
)

#: The node's own arguments asking for the help (ROS's come after --ros-args).
HELP_FLAGS = frozenset({'-h', '--help'})


def wants_help(arguments: Sequence[str]) -> bool:
    """Tell whether a node's command line asks for ``--help`` (outside ``--ros-args``)."""
    return bool(HELP_FLAGS & set(node_arguments(arguments)))


def _columns(rows: Iterable[Tuple[str, ...]]) -> List[str]:
    """Align rows of cells into lines, two spaces between columns, none trailing."""
    rows = list(rows)
    widths = [max(len(row[column]) for row in rows) for column in range(len(rows[0]))]
    return ['  ' + '  '.join(cell.ljust(width) for cell, width in zip(row, widths)).rstrip()
            for row in rows]


def help_text(name: str, summary: str, specs: Mapping[str, ParameterSpec],
              defaults: Mapping[str, Any], subscribed: Mapping[str, str],
              published: Mapping[str, str]) -> str:
    """
    Return the ``--help`` text of node ``name``.

    ``specs`` and ``defaults`` (its parameters and their shipped values), ``subscribed``
    and ``published`` (topic -> ROS type name); one line per parameter and per topic.
    """
    parameters = [('name', 'type', 'default', 'unit', 'meaning')]
    parameters += [(key, declared_type(defaults[key]), repr(defaults[key]), spec.unit or '-',
                    spec.meaning + (' (read-only)' if spec.read_only else ''))
                   for key, spec in specs.items()]
    lines = [f'usage: {name} [-h] [--ros-args [--params-file FILE] [-p NAME:=VALUE] ...]',
             '', summary, '',
             f'Parameters (the {name}: section of config/translator.yaml; set them with '
             '--ros-args --params-file FILE or -p NAME:=VALUE):']
    lines += _columns(parameters)
    lines += ['', 'Subscribed topics:'] + _columns(sorted(subscribed.items()))
    lines += ['', 'Published topics:'] + _columns(sorted(published.items()))
    lines += ['', 'Exit codes:'] + _columns((str(code), meaning)
                                            for code, meaning in EXIT_CODES)
    return '\n'.join(lines)

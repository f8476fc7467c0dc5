"""
The command-line options that choose the translator's model level and its error budget.

``python -m cdr_translator solve`` and ``python -m msg_tools replay`` take the same
``--fidelity``, ``--max-position-error`` and ``--max-angle-error`` (built here, once); each
sets the translator_node parameter of the same name (``FIDELITY_FLAGS``), so a replay answers
as a node run with that parameter would.
"""

import argparse
from typing import Any, Dict, Tuple

__all__ = ['add_fidelity_arguments', 'FIDELITY_CHOICES', 'FIDELITY_FLAGS', 'fidelity_parameters']

#: The levels a command line offers (docs/howto/fidelity.md); 'linear' is a level the
#: params file can choose for a node's batches, not one a single solve is asked for.
FIDELITY_CHOICES = ('full', 'rod', 'cc', 'auto')

#: Each option and the translator_node parameter it sets.
FIDELITY_FLAGS: Tuple[Tuple[str, str], ...] = (
    ('--fidelity', 'fidelity'),
    ('--max-position-error', 'max_position_error'),
    ('--max-angle-error', 'max_angle_error'),
)


def add_fidelity_arguments(parser: Any, from_params_file: bool = False) -> None:
    """
    Add ``--fidelity`` and the error budget of ``--fidelity auto`` to ``parser``.

    ``parser``: an ``argparse.ArgumentParser`` or one of its argument groups.

    ``from_params_file``: the options default to None, meaning the params file's
    ``fidelity``, ``max_position_error`` and ``max_angle_error`` (replay); otherwise to
    full with no budget (solve).
    """
    defaults: Dict[str, Any] = (dict.fromkeys(('fidelity', 'position', 'angle'))
                                if from_params_file else
                                {'fidelity': 'full', 'position': 0.0, 'angle': 0.0})
    default_text = ("default: the params file's {key}" if from_params_file
                    else 'default: %(default)s')
    parser.add_argument('--fidelity', choices=FIDELITY_CHOICES, default=defaults['fidelity'],
                        help='model level (docs/howto/fidelity.md); auto: the cheapest level '
                             'within --max-position-error and --max-angle-error (both needed; '
                             'without them auto answers at full) ('
                             + default_text.format(key='fidelity') + ')')
    parser.add_argument('--max-position-error', type=float, default=defaults['position'],
                        metavar='M', help='error budget of --fidelity auto: end-disk '
                                          'position, m (' + default_text.format(
                                              key='max_position_error') + ')')
    parser.add_argument('--max-angle-error', type=float, default=defaults['angle'],
                        metavar='DEG', help='error budget of --fidelity auto: bending angles '
                                            'and end-disk orientation, deg (' +
                                            default_text.format(key='max_angle_error') + ')')


def fidelity_parameters(args: argparse.Namespace) -> Dict[str, Tuple[str, Any]]:
    """Return {translator_node parameter: (option, value)} of the level options given."""
    given: Dict[str, Tuple[str, Any]] = {}
    for flag, key in FIDELITY_FLAGS:
        value = getattr(args, flag[2:].replace('-', '_'))
        if value is not None:
            given[key] = (flag, value)
    return given

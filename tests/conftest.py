"""Shared fixtures: the shipped parameters and solvers built from them."""

from typing import Any, Callable

from cdr_translator import TranslatorParams, TranslatorSolver
from cdr_translator.interface import messages
import pytest

#: The header stamp of the messages built by the fixtures below.
STAMP = {'sec': 1_700_000_000, 'nanosec': 123_456_789}


@pytest.fixture(scope='session')
def params() -> TranslatorParams:
    """Parameters of config/translator.yaml."""
    return TranslatorParams.from_yaml()


@pytest.fixture(scope='session')
def solver(params) -> TranslatorSolver:
    """Solver shared by tests that reset() it or do not care about warm starts."""
    return TranslatorSolver(params)


@pytest.fixture(scope='module')
def solved(solver):
    """Solve the paper's 12 N case (converged)."""
    solver.reset()
    result = solver.solve([12.0, 0.0, 0.0])
    assert result.converged
    return result


@pytest.fixture
def all_outputs(solved, params):
    """(topic, type, dict) of a wrench and of every output the node builds for ``solved``."""
    wrench = messages.wrench_message([12.0, 0.0, 0.0], [0.0, 0.0, 0.0], 'base', STAMP)
    return [(messages.WRENCH_TOPIC, messages.WRENCH_TYPE, wrench)] + messages.output_messages(
        solved, STAMP, 'base', backbones_params=params)


def _plain(value: Any) -> Any:
    """Turn a decoded mcap_ros2 message into nested dicts/lists, like the input dicts."""
    if hasattr(value, '__slots__') and not isinstance(value, (int, float, str)):
        return {name: _plain(getattr(value, name)) for name in value.__slots__}
    if isinstance(value, (list, tuple)):
        return [_plain(item) for item in value]
    return value


@pytest.fixture
def plain_message() -> Callable[[Any], Any]:
    """Return the function that turns a decoded message into nested dicts and lists."""
    return _plain

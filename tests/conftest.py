"""Shared fixtures: the shipped parameters and solvers built from them."""

from cdr_translator import TranslatorParams, TranslatorSolver
import pytest


@pytest.fixture(scope='session')
def params() -> TranslatorParams:
    """Parameters of config/translator.yaml."""
    return TranslatorParams.from_yaml()


@pytest.fixture(scope='session')
def solver(params) -> TranslatorSolver:
    """Solver shared by tests that reset() it or do not care about warm starts."""
    return TranslatorSolver(params)

"""The robot's geometry: impossible values are ParameterErrors, implausible ones warn."""

from cdr_translator import ParameterError, PlausibilityWarning
from cdr_translator.robot import DeltaParams, DeltaRobot
import pytest


def _geometry(**changes):
    """Return the shipped robot geometry's fields with some changed."""
    values = dict(DeltaParams.from_yaml().__dict__)
    values.update(changes)
    return values


def test_lengths_in_millimetres_warn_naming_the_key():
    """A base radius of 155 m (155 mm typed as metres) warns, naming the key."""
    with pytest.warns(PlausibilityWarning, match='base_radius is 155.0 m'):
        geometry = DeltaParams(**_geometry(base_radius=155.0))
    assert geometry.implausibilities() == [
        'base_radius is 155.0 m, a length of 1 m or more: millimetres typed as metres?']


def test_legs_that_cannot_reach_the_platform_are_refused():
    """Radii further apart than a leg is long name both keys and the rule."""
    with pytest.warns(PlausibilityWarning):
        geometry = DeltaParams(**_geometry(base_radius=155.0))
    with pytest.raises(ParameterError, match='base_radius.*platform_radius.*cannot reach'):
        DeltaRobot(geometry=geometry)

"""The Continuum Delta Robot: three translator legs between sliders and a moving platform."""

from .delta import DeltaResult, DeltaRobot
from .params import DeltaParams

__all__ = ['DeltaParams', 'DeltaResult', 'DeltaRobot']

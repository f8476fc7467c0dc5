"""The Continuum Delta Robot: three translator legs between sliders and a moving platform."""

from .delta import DeltaRobot
from .params import DeltaParams
from .payload_estimate import PayloadEstimate
from .result import DeltaResult

__all__ = ['DeltaParams', 'DeltaResult', 'DeltaRobot', 'PayloadEstimate']

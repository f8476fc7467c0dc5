"""
The translator's parameters: geometry, material, discretization and accuracy targets.

``TranslatorParams`` and ``Accuracy`` (translator_params) are read from the YAML in
config/ with ROS 2 params-file semantics (params_file), the one source of truth of every
entry point; paper holds the paper's Table II for the comparisons.
"""

from .translator_params import Accuracy, DEFAULT_PARAMS_PATH, TranslatorParams

__all__ = ['Accuracy', 'DEFAULT_PARAMS_PATH', 'TranslatorParams']

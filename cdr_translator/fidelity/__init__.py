"""
Fidelity levels of the translator model and the error budget that chooses among them.

``FidelitySolver`` (fidelity.solver) solves with the full model or a reduced one:
'rod' (fidelity.equivalent_rod), 'cc' (fidelity.cc), 'linear' (fidelity.linear), each
behind one protocol (fidelity.level), or picks the cheapest level whose validated error
(fidelity.validation) meets a budget ('auto': a policy over the levels, fidelity.auto).
"""

from .admission import LEVEL_COST_ORDER
from .solver import FIDELITIES, FidelitySolver, LEVELS
from .validation import pose_errors, reference_solver, Validation
from ..solve.batch import BatchResult

__all__ = ['BatchResult', 'FIDELITIES', 'FidelitySolver', 'LEVEL_COST_ORDER', 'LEVELS',
           'Validation', 'pose_errors', 'reference_solver']

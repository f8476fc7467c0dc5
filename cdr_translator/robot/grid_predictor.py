"""
Predictors of the chain's continuation along equal input steps: an atlas's slider grid.

An atlas walks a grid in serpentine order (robot/samples.py), each sample one grid step from
the last, and linearizes every solution exactly (its compliance): the tangent
t_k = dx/du du at x_k is then one substitution with a factorization made anyway. The
first-order predictor x_k + t_k misses the solution by the path's curvature, of second order
in the step; at the atlas's steps (a grid of 4 or 6 over the stroke) the Newton correction
from there rebuilt the factorization four times a sample. Two predictors of higher order
use the tangents and solutions the grid walked before:

* along a grid line (the last solve took the same step from x_(k-1)): the cubic Hermite
  polynomial through x_(k-1), x_k and their tangents, one step on, error of fourth order;
* elsewhere (a turn onto the next line, the first step along a line): a solve that took the
  same step (or its opposite) from a start nearby left its curvature,
  e = x_end - x_start - t_start (half the second derivative along the step, to second
  order, whichever way it was taken), and x_k + t_k + e misses by third order.
"""

from dataclasses import dataclass
from typing import List, Optional

import numpy as np

from .chain import ChainState, difference

#: Two input changes are the same step when they differ by at most this fraction of their
#: size: grid steps from np.linspace differ by rounding.
SAME_STEP = 1e-9

#: Tangents kept: two lines of a grid of 32, where the turns' curvatures come from.
KEPT = 64

#: A solve's curvature serves starts at most this many of its steps from its own start.
NEAR = 2.5


@dataclass
class Tangent:
    """A solve from ``start`` (at ``inputs``) by ``inputs_change``; its tangent and end."""

    start: ChainState
    inputs: np.ndarray
    inputs_change: np.ndarray
    step: np.ndarray  # t = dx/du du at start, flat and scaled (CoupledNewton.correction's)
    end: Optional[ChainState] = None  # the solution reached, once converged


def same_step(first: np.ndarray, second: np.ndarray) -> bool:
    """Whether two input changes are equal within SAME_STEP of the second's size."""
    return bool(np.linalg.norm(first - second) <= SAME_STEP * np.linalg.norm(second))


class GridPredictor:
    """The tangents of the last solves, and the predictors they give (module docstring)."""

    def __init__(self, x_scale: np.ndarray) -> None:
        """Predict in the flat unknowns scaled by ``x_scale`` (chain.difference's); none kept."""
        self.x_scale = x_scale
        self.tangents: List[Tangent] = []
        self._current: Optional[Tangent] = None

    def reset(self) -> None:
        """Forget every tangent."""
        self.tangents = []
        self._current = None

    def predict(self, state: ChainState, inputs: np.ndarray, inputs_change: np.ndarray,
                tangent: np.ndarray) -> Optional[np.ndarray]:
        """
        Keep the tangent of a solve starting at solution ``state``; return its predicted step.

        ``tangent`` is dx/du ``inputs_change`` at ``state`` from an exact factorization
        there. The step (flat, scaled) is the Hermite or the curvature predictor's, None
        when the tangents kept give neither.
        """
        last = self.tangents[-1] if self.tangents else None
        self._current = Tangent(state, inputs.copy(), inputs_change.copy(), tangent)
        self.tangents = [*self.tangents[1 - KEPT:], self._current]
        if (last is not None and last.end is state
                and same_step(last.inputs_change, inputs_change)):
            back = difference(last.start, state, self.x_scale) + tangent
            return tangent + 5.0 * back + 2.0 * (last.step - tangent)
        ended = [kept for kept in self.tangents[:-1] if kept.end is not None]
        if not ended:
            return None
        changes = np.array([kept.inputs_change for kept in ended])
        size = float(np.linalg.norm(inputs_change))
        same = np.minimum(np.linalg.norm(changes - inputs_change, axis=1),
                          np.linalg.norm(changes + inputs_change, axis=1)) <= SAME_STEP * size
        distances = np.where(same, np.linalg.norm(
            np.array([kept.inputs for kept in ended]) - inputs, axis=1), np.inf)
        nearest = int(np.argmin(distances))
        if not distances[nearest] <= NEAR * size:
            return None
        curvature = ended[nearest]
        assert curvature.end is not None  # chosen for it
        return (tangent + difference(curvature.end, curvature.start, self.x_scale)
                - curvature.step)

    def reached(self, end: ChainState) -> None:
        """Record where the solve whose tangent ``predict`` kept converged."""
        if self._current is not None:
            self._current.end = end
            self._current = None

    def abandon(self) -> None:
        """Forget the solve whose tangent ``predict`` kept: it did not converge."""
        self._current = None

"""
What the inverse statics keeps between solves along a path: dp/dq by secants, the sliders.

The slider-to-platform map p(q) is smooth and, over a millimetre, nearly linear. Its
slope dp/dq is kept as a matrix B that every observed pair of forward solves corrects by
Broyden's good update, B <- B + (dp - B dq) dq^T / (dq . dq) (Kelley, "Solving Nonlinear
Equations with Newton's Method", SIAM 2003, Sec. 1.11): exact along the step just taken,
unchanged across it. The exact slope (``DeltaResult.input_sensitivity``: three leg
Jacobians) replaces B only where the secant iteration stalls. The solved sliders of the
last solves predict the next target's by polynomial extrapolation along the path.
"""

import math
from typing import List, Optional, Tuple

import numpy as np

#: Highest degree of the path predictor (the last PREDICTOR_DEGREE solves' steps).
PREDICTOR_DEGREE = 5

#: The polynomial predictor is used when the target change it does not extrapolate is at
#: most this fraction of the whole target change (else the targets do not follow a path).
EXTRAPOLATE_WITHIN = 0.5

#: The backward-difference weights of each degree m: w_j = (-1)^j C(m, j + 1), j < m.
WEIGHTS = {degree: np.array([(-1) ** j * math.comb(degree, j + 1) for j in range(degree)],
                            dtype=float)
           for degree in range(2, PREDICTOR_DEGREE + 1)}

#: WEIGHTS as rows, degree 2 first, padded with zeros to PREDICTOR_DEGREE columns: every
#: degree's extrapolation in one product.
WEIGHT_ROWS = np.array([np.pad(WEIGHTS[degree], (0, PREDICTOR_DEGREE - degree))
                        for degree in range(2, PREDICTOR_DEGREE + 1)])

#: A slider step shorter than this (m) updates no secant: the forward solves' positions
#: are good to about 1e-11 m, which would be a relative error above 1e-4 in the slope.
SECANT_MIN_STEP = 1e-7


class SliderPath:
    """The slope B ~ dp/dq, the last observed (q, p), and the last solves' solutions."""

    def __init__(self) -> None:
        """No slope, no path yet."""
        self.slope: Optional[np.ndarray] = None
        #: the sliders and platform position of the latest forward solve seen
        self.observed: Optional[Tuple[np.ndarray, np.ndarray]] = None
        #: (target, sliders) of the last solves, latest last, under ``load``
        self.points: List[Tuple[np.ndarray, np.ndarray]] = []
        self.load: Optional[np.ndarray] = None
        #: the points' target and slider steps, latest first (row j: point k - j minus
        #: point k - j - 1), made when a point is recorded
        self._target_steps = np.zeros((0, 3))
        self._slider_steps = np.zeros((0, 3))

    def observe(self, sliders: np.ndarray, position: np.ndarray) -> None:
        """Take a forward solve's (q, p): the secant from the one observed before updates B."""
        if self.observed is not None and self.slope is not None:
            step = sliders - self.observed[0]
            length = float(step @ step)
            if length >= SECANT_MIN_STEP ** 2:
                miss = position - self.observed[1] - self.slope @ step
                self.slope = self.slope + np.outer(miss, step) / length
        self.observed = (sliders.copy(), position.copy())

    def restart(self, slope: np.ndarray, sliders: np.ndarray, position: np.ndarray) -> None:
        """Take an exact (or freshly modelled) slope at (q, p): B = slope."""
        self.slope = np.array(slope, dtype=float)
        self.observed = (sliders.copy(), position.copy())

    def step(self, error: np.ndarray) -> np.ndarray:
        """Return the slider change B^-1 (-error) (LinAlgError when B is singular)."""
        if self.slope is None:
            raise np.linalg.LinAlgError('no slope yet')
        return np.asarray(np.linalg.solve(self.slope, -error))

    def record(self, target: np.ndarray, sliders: np.ndarray, error: np.ndarray,
               load: np.ndarray) -> None:
        """
        Add a solve's answer to the path (``error`` = p - target there, within tolerance).

        Its sliders enter corrected to first order, q - B^-1 error: the extrapolation
        amplifies the points' errors (weights up to 7 in sum), the correction makes them
        about the slope's relative error times ``error``.
        """
        try:
            corrected = sliders + self.step(error)
        except np.linalg.LinAlgError:
            corrected = sliders.copy()
        if self.load is None or not np.array_equal(load, self.load):
            self.points = []
        self.load = load.copy()
        self.points = [*self.points[-PREDICTOR_DEGREE:], (target.copy(), corrected)]
        targets = np.array([point[0] for point in self.points])
        sliders = np.array([point[1] for point in self.points])
        self._target_steps = (targets[1:] - targets[:-1])[::-1]
        self._slider_steps = (sliders[1:] - sliders[:-1])[::-1]

    def predict(self, target: np.ndarray, load: np.ndarray) -> Optional[np.ndarray]:
        """
        Sliders predicted for ``target``, or None without a previous solve or slope.

        From the last solve's sliders q_k: the polynomial of degree m (2 to
        PREDICTOR_DEGREE) through the last m steps extrapolates q_k + sum_j w_j dq_(k-j) at
        targets t_k + sum_j w_j dt_(k-j), w_j = (-1)^j C(m, j + 1) (backward differences,
        as robot/continuation.py extrapolates the chain), and B^-1 takes the rest of the
        target change to first order. The degree is the one leaving the smallest rest (the
        highest among equals); none when even that rest is more than EXTRAPOLATE_WITHIN of
        the whole change, or the load changed: then first order, q_k + B^-1 (t - t_k).
        """
        if not self.points or self.slope is None:
            return None
        last_target, last_sliders = self.points[-1]
        change = target - last_target
        rest, extrapolated = change, np.zeros(3)
        steps = len(self._target_steps)
        if steps >= 2 and self.load is not None and np.array_equal(load, self.load):
            # every degree's rest at once: row m - 2 is degree m's (rows past the steps
            # known are not looked at)
            weights = WEIGHT_ROWS[:steps - 1, :steps]
            lefts = change - weights @ self._target_steps[:PREDICTOR_DEGREE]
            sizes = np.sqrt(np.einsum('ij,ij->i', lefts, lefts)).tolist()
            smallest, whole, chosen = math.inf, math.sqrt(float(change @ change)), -1
            for row, size in enumerate(sizes):
                if size <= smallest + 1e-9 * whole:  # equal within rounding: the higher
                    chosen = row
                smallest = min(smallest, size)
            if smallest <= EXTRAPOLATE_WITHIN * whole:
                rest = lefts[chosen]
                extrapolated = weights[chosen] @ self._slider_steps[:PREDICTOR_DEGREE]
        try:
            return last_sliders + extrapolated + self.step(-rest)
        except np.linalg.LinAlgError:
            return last_sliders + extrapolated

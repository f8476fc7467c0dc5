"""
Model parameters (and a tracker frame) fitted to measured end-disk poses.

Each sample is a wrench applied in {pe} and the end-disk pose a tracker measured under it,
with the 6 x 6 covariance of that measurement (pose_error.py: frames and conventions). The
fit is weighted least squares on the whitened pose errors, ``sum_i |W_i e_i(p)|^2`` with
``W_i`` the inverse Cholesky factor of the i-th covariance, by Levenberg-Marquardt
(scipy's MINPACK ``lm``). The model is the full Cosserat solve of every recorded wrench
(``TranslatorSolver.solve_many``, warm-started along the recording) at a fixed
discretization: the automatic refinement is off, so that the predicted poses are smooth in
the parameters, and the largest discretization-error estimate is reported instead.

Unknowns are scaled to one "unit" each: log(p / p0) for the positive model keys (a unit is
a factor e), (nu - nu0) / 0.5 for ``poisson_ratio``, 0.1 m for a frame translation and
0.5 rad for a frame rotation. Derivatives of the model keys are forward differences
(1e-6 units; the solver's residual tolerance is six orders below their effect), those of
the frame exact to rounding (forward differences of a closed form).

Before any fit, the weighted Jacobian at the start decides whether the request can be
answered: its rank, its condition number (columns scaled to unit length, so that it
measures how collinear the parameters' effects are, not their units) and each unknown's
predicted standard error. A rank deficit, a condition number above MAX_CONDITION or a
predicted standard error above one unit is refused (UnidentifiableError), never fitted.
"""

from dataclasses import dataclass, field
import math
import time
from typing import Dict, List, Mapping, Optional, Sequence, Tuple

import numpy as np
from scipy.optimize import least_squares

from . import pose_error
from .fit_parameters import FitParameters, SI_UNITS
from ..params.translator_params import Accuracy, TranslatorParams
from ..solve.solver import TranslatorSolver

__all__ = ['FitResult', 'MAX_CONDITION', 'MAX_REDUCED_CHI_SQUARE', 'PoseSamples',
           'UnidentifiableError', 'fit_poses']

#: Largest condition number of the column-scaled weighted Jacobian that is fitted. Past it
#: the effects of the unknowns are so nearly collinear (a condition index of 100 is the
#: "strong dependence" of Belsley, Kuh & Welsch, Regression Diagnostics, 1980, Ch. 3) that
#: the data fix only a combination of them: youngs_modulus and backbone_diameter under
#: lateral loads (both enter as E d^4) give 194.
MAX_CONDITION = 100.0
#: Farthest a trial may move a model key from its start (units: a factor e for a positive
#: key); a trial beyond counts as failed, unsolved, so that a fit far from its data does not
#: wander into models whose solves take long or fail. A fit ending at it is not converged.
MAX_UNITS = 1.0
#: Time limit of each solve of a fit (s): a trial whose solves stall counts as failed.
SOLVE_TIME_LIMIT_S = 2.0
#: Reduced chi-square above which a fit is warned about (residuals twice the deviations).
POOR_FIT = 4.0
#: Reduced chi-square above which a converged fit does not explain its measurements, so is
#: not a success (``FitResult.explains_measurements`` False): residuals five times the
#: measurement standard deviations. The estimates and standard errors of such a fit
#: describe the model's misfit, not the prototype; a chance excess this large has a
#: probability far below 1e-9 at any number of samples.
MAX_REDUCED_CHI_SQUARE = 25.0
#: Forward-difference step of the model keys (in units).
DIFFERENCE_STEP = 1e-6
#: Whitened error given to a sample whose solve failed at a trial point (LM rejects the step).
FAILED_ERROR = 1e3
#: Chord Gauss-Newton steps of one cross-validation refit, at most; and its step tolerance.
CV_ITERATIONS, CV_TOLERANCE = 8, 1e-7


@dataclass(frozen=True)
class PoseSamples:
    """Wrenches (N, 6) in {pe} and the poses measured under them in the tracker frame."""

    wrenches: np.ndarray
    positions: np.ndarray
    rotations: np.ndarray
    covariances: np.ndarray

    def __post_init__(self) -> None:
        """Check the shapes; ValueError saying which one is wrong."""
        count = len(self.wrenches)
        for name, shape in (('wrenches', (count, 6)), ('positions', (count, 3)),
                            ('rotations', (count, 3, 3)), ('covariances', (count, 6, 6))):
            if np.shape(getattr(self, name)) != shape:
                raise ValueError(f'{name} must have shape {shape}, got '
                                 f'{np.shape(getattr(self, name))}')

    def subset(self, rows: np.ndarray) -> 'PoseSamples':
        """Return the samples of ``rows``."""
        return PoseSamples(self.wrenches[rows], self.positions[rows], self.rotations[rows],
                           self.covariances[rows])


class UnidentifiableError(ValueError):
    """The recordings cannot determine the requested unknowns; ``reason`` says why."""

    def __init__(self, reason: str, rank: int, condition_number: float,
                 predicted_standard_errors: Mapping[str, float]) -> None:
        """Keep the reason and the numbers it rests on."""
        super().__init__(reason)
        self.reason = reason
        self.rank = rank
        self.condition_number = condition_number
        self.predicted_standard_errors = dict(predicted_standard_errors)


@dataclass
class FitResult:
    """
    A fit: estimates with standard errors, residual statistics, cross-validation.

    ``values``, ``initial`` and ``standard_errors`` are keyed by the fitted names (model keys
    in SI units, then the frame's six numbers, pose_error.FRAME_NAMES). Standard errors are
    those of the linearized model at the optimum, scaled by the reduced chi-square; NaN
    (not assessed) for a fit that did not converge, whose ``values`` are its last trial.
    Errors are predicted - measured in the tracker frame: position (m) and rotation (rad),
    (N, 6), at the initial and at the fitted values. ``message`` says why the fit stopped
    (why it did not converge, when it did not). ``cross_validation_skipped`` says why no
    cross-validation was made ('' when ``cross_validation_folds`` folds were held out).
    """

    names: Tuple[str, ...]
    initial: Dict[str, float]
    values: Dict[str, float]
    standard_errors: Dict[str, float]
    correlation: np.ndarray
    converged: bool
    message: str
    samples: int
    condition_number: float
    rank: int
    chi_square: float
    degrees_of_freedom: int
    errors_initial: np.ndarray
    errors: np.ndarray
    predicted_positions: np.ndarray
    measured_positions: np.ndarray
    cross_validation_folds: int = 0
    cross_validated_errors: np.ndarray = field(default_factory=lambda: np.zeros((0, 6)))
    cross_validation_skipped: str = ''
    max_discretization_error_m: float = math.nan
    model_passes: int = 0
    fit_time_s: float = 0.0
    cross_validation_time_s: float = 0.0

    @property
    def reduced_chi_square(self) -> float:
        """Chi-square per degree of freedom (about 1 when the covariances are right)."""
        return self.chi_square / self.degrees_of_freedom if self.degrees_of_freedom else math.nan

    @property
    def explains_measurements(self) -> Optional[bool]:
        """
        Tell whether the residuals are within MAX_REDUCED_CHI_SQUARE of the covariances.

        None (not assessed) without a degree of freedom or for a fit that did not converge.
        """
        if not self.converged or not self.degrees_of_freedom:
            return None
        return bool(self.reduced_chi_square <= MAX_REDUCED_CHI_SQUARE)

    @property
    def warnings(self) -> List[str]:
        """Say what makes the fit doubtful though it converged (empty when nothing does)."""
        texts = []
        if self.reduced_chi_square > POOR_FIT:
            texts.append(f'the residuals are {math.sqrt(self.reduced_chi_square):.3g} times '
                         'the measurement standard deviations: a key left out, a wrong '
                         'tracker frame, or covariances too small')
        if self.max_discretization_error_m > 0.1 * rms_position(self.errors):
            texts.append(f'the discretization error estimate '
                         f'({self.max_discretization_error_m:.2g} m) is not small against '
                         'the residuals: raise steps_per_segment')
        return texts


def rms_position(errors: np.ndarray) -> float:
    """Root mean square of the position error's length (m) over samples."""
    return float(np.sqrt(np.mean(np.sum(errors[:, :3] ** 2, axis=1)))) if len(errors) else \
        math.nan


def rms_angle_deg(errors: np.ndarray) -> float:
    """Root mean square of the rotation error's angle (deg) over samples."""
    return math.degrees(float(np.sqrt(np.mean(np.sum(errors[:, 3:] ** 2, axis=1))))) if len(
        errors) else math.nan


class PoseModel:
    """Predicted poses of the recorded wrenches at trial unknowns, whitened errors, Jacobian."""

    def __init__(self, samples: PoseSamples, unknowns: FitParameters,
                 params: TranslatorParams) -> None:
        """Set up for ``samples`` (their covariances must be positive definite)."""
        self.samples = samples
        self.unknowns = unknowns
        self.params = params
        self.weights = pose_error.whitening(samples.covariances)
        self.passes = 0
        self.max_error_estimate_m = 0.0
        self._cache: Dict[bytes, Tuple[np.ndarray, np.ndarray, np.ndarray]] = {}

    def base_poses(self, model_x: np.ndarray) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return positions, rotations in {pe} and the converged mask at model unknowns."""
        key = np.asarray(model_x, dtype=float).tobytes()
        if key not in self._cache:
            self._cache[key] = self._solve(model_x)
            if len(self._cache) > 16:
                self._cache.pop(next(iter(self._cache)))
        return self._cache[key]

    def _solve(self, model_x: np.ndarray) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Solve every wrench at the model keys of ``model_x`` (one pass)."""
        count = len(self.samples.wrenches)
        failed = np.zeros((count, 3)), np.tile(np.eye(3), (count, 1, 1)), np.zeros(
            count, dtype=bool)
        if np.any(np.abs(model_x) > MAX_UNITS):
            return failed
        try:
            params = self.params.with_changes(**self.unknowns.model_values(model_x))
        except ValueError:   # a trial outside the keys' valid ranges: every sample fails
            return failed
        self.passes += 1
        solver = TranslatorSolver(params, accuracy=Accuracy(0.0, 0.0),
                                  time_limit_s=SOLVE_TIME_LIMIT_S)
        batch = solver.solve_many(self.samples.wrenches[:, :3], self.samples.wrenches[:, 3:])
        converged = batch.converged.astype(bool) & np.all(
            np.isfinite(batch.end_disk_quaternion_xyzw), axis=1)
        quaternions = np.where(converged[:, None], batch.end_disk_quaternion_xyzw,
                               [0.0, 0.0, 0.0, 1.0])
        estimates = batch.error_estimate_m[converged]
        if np.any(np.isfinite(estimates)):
            self.max_error_estimate_m = max(self.max_error_estimate_m,
                                            float(np.nanmax(estimates)))
        return (np.nan_to_num(batch.end_disk_position), pose_error.rotations_from_quaternions(
            quaternions), converged)

    def errors(self, x: np.ndarray) -> Tuple[np.ndarray, np.ndarray]:
        """Return the (N, 6) pose errors at unknowns ``x`` and the converged mask."""
        positions, rotations, converged = self.base_poses(self.unknowns.model_part(x))
        positions, rotations = pose_error.to_tracker(positions, rotations,
                                                     self.unknowns.frame_values(x))
        return pose_error.pose_errors(positions, rotations, self.samples.positions,
                                      self.samples.rotations), converged

    def residuals(self, x: np.ndarray) -> np.ndarray:
        """Return the whitened errors, flattened (6 N); a failed sample gets FAILED_ERROR."""
        errors, converged = self.errors(x)
        whitened = np.einsum('nij,nj->ni', self.weights, errors)
        whitened[~converged] = FAILED_ERROR
        return whitened.ravel()

    def jacobian(self, x: np.ndarray) -> np.ndarray:
        """Return d residuals / d x (6 N, n): forward differences, one pass per model key."""
        x = np.asarray(x, dtype=float)
        base = self.residuals(x)
        columns = []
        for index in range(len(x)):
            step = DIFFERENCE_STEP if index < self.unknowns.model_count else 1e-7
            shifted = x.copy()
            shifted[index] += step
            columns.append((self.residuals(shifted) - base) / step)
        return np.stack(columns, axis=1)

    def predicted_positions(self, x: np.ndarray) -> np.ndarray:
        """Return the predicted end-disk positions (N, 3) in the tracker frame at ``x``."""
        positions, rotations, _ = self.base_poses(self.unknowns.model_part(x))
        return pose_error.to_tracker(positions, rotations, self.unknowns.frame_values(x))[0]


def identifiability(jacobian: np.ndarray, names: Sequence[str]
                    ) -> Tuple[int, float, Dict[str, float], str]:
    """
    Return rank, condition number, predicted standard errors (units) and a refusal ('' none).

    The condition number is that of the Jacobian with unit-length columns; the predicted
    standard errors are those of the unit-weight linearization (the covariances taken as
    given), infinite for a rank-deficient Jacobian.
    """
    norms = np.linalg.norm(jacobian, axis=0)
    count = len(names)
    if jacobian.shape[0] <= count:
        return 0, math.inf, {name: math.inf for name in names}, (
            f'{jacobian.shape[0] // 6} samples give {jacobian.shape[0]} numbers, not more than '
            f'the {count} unknowns')
    dead = [name for name, norm in zip(names, norms) if not norm > 0.0]
    scaled = jacobian / np.where(norms > 0.0, norms, 1.0)
    singular = np.linalg.svd(scaled, compute_uv=False)
    rank = int(np.sum(singular > singular[0] * 1e-12)) if singular[0] > 0 else 0
    condition = float(singular[0] / singular[-1]) if singular[-1] > 0 and not dead else math.inf
    if rank < count:
        errors = {name: math.inf for name in names}
    else:
        inverse = np.linalg.inv(scaled.T @ scaled)
        errors = {name: float(math.sqrt(max(inverse[i, i], 0.0)) / norms[i])
                  for i, name in enumerate(names)}
    reasons = []
    if dead:
        reasons.append(f'{", ".join(dead)} {"does" if len(dead) == 1 else "do"} not change '
                       'the predicted poses of these wrenches at all')
    if rank < count or condition > MAX_CONDITION:
        reasons.append(f'the weighted Jacobian at the start has rank {rank} of {count} and '
                       f'condition number {condition:.3g} (at most {MAX_CONDITION:.0e} is '
                       f'fitted){collinear_text(scaled, names)}')
    weak = [f'{name} ({error:.3g} units)' for name, error in errors.items()
            if math.isfinite(error) and error > 1.0]
    if weak:
        reasons.append('predicted standard error above one unit (the noise hides the effect): '
                       + ', '.join(weak))
    return rank, condition, errors, '; '.join(reasons)


def collinear_text(scaled: np.ndarray, names: Sequence[str]) -> str:
    """Name the unknowns of the weakest direction of the column-scaled Jacobian."""
    if len(names) < 2:
        return ''
    direction = np.linalg.svd(scaled, full_matrices=False)[2][-1]
    parts = [f'{weight:+.2f} {name}' for weight, name in sorted(
        zip(direction, names), key=lambda item: -abs(item[0])) if abs(weight) >= 0.1]
    return f'; nearly no effect along {" ".join(parts)} (column-scaled)'


def fit_poses(samples: PoseSamples, params: TranslatorParams, names: Sequence[str],
              fit_frame: bool = False, frame: Optional[Sequence[float]] = None,
              folds: int = 5, max_evaluations: int = 60) -> FitResult:
    """
    Fit model keys ``names`` (and with ``fit_frame`` the tracker frame) to ``samples``.

    ``params`` gives the starting values of the model keys and every other key. ``frame``
    is the tracker frame's pose in {pe} when it is not fitted (default: the base frame);
    when it is fitted, the start is the rigid registration of the measured poses to the
    poses predicted at ``params`` (pose_error.register). Raises ValueError for a bad
    request (unknown names, samples whose solve fails at the start, none left) and
    UnidentifiableError when the samples cannot determine the unknowns. ``folds``-fold
    cross-validation (contiguous blocks of samples) refits on all folds but one and
    predicts that one; when it cannot be made (0 or 1 fold, too few samples, no
    convergence), ``cross_validation_skipped`` says why.
    """
    started = time.perf_counter()
    unknowns = FitParameters(params, names, fit_frame,
                             np.zeros(6) if frame is None else pose_error.check_frame(frame))
    model = PoseModel(samples, unknowns, params)
    x0 = unknowns.start()
    positions, rotations, converged = model.base_poses(unknowns.model_part(x0))
    if not converged.all():
        failed = np.flatnonzero(~converged)
        raise ValueError(f'{len(failed)} of {len(converged)} wrenches do not solve at the '
                         f'starting parameters (first: sample {int(failed[0])}, wrench '
                         f'{samples.wrenches[failed[0]].tolist()})')
    if fit_frame:
        x0 = unknowns.with_frame(x0, pose_error.register(
            positions, rotations, samples.positions, samples.rotations))
    jacobian = model.jacobian(x0)
    rank, condition, predicted, reason = identifiability(jacobian, unknowns.names)
    if reason:
        raise UnidentifiableError(f'unidentifiable from these samples: {reason}', rank,
                                  condition, predicted)
    errors_initial, _ = model.errors(x0)
    solution = least_squares(model.residuals, x0, jac=model.jacobian, method='lm',
                             xtol=1e-10, ftol=1e-12, gtol=1e-12, max_nfev=max_evaluations)
    x = solution.x
    errors, converged = model.errors(x)
    jacobian = model.jacobian(x)
    residuals = model.residuals(x)
    dof = len(residuals) - len(x)
    chi_square = float(residuals @ residuals)
    scale = chi_square / dof if dof > 0 else 1.0
    covariance = np.linalg.pinv(jacobian.T @ jacobian) * scale
    deviations = np.sqrt(np.clip(np.diag(covariance), 0.0, None))
    correlation = covariance / np.outer(np.where(deviations > 0, deviations, 1.0),
                                        np.where(deviations > 0, deviations, 1.0))
    edge = unknowns.at_edge(x) + [name for name, value in zip(unknowns.model_names, x)
                                  if abs(value) > 0.99 * MAX_UNITS]
    ok = bool(solution.success) and bool(converged.all()) and not edge
    message = solution.message if ok else (
        solution.message if not solution.success else
        'some wrenches do not solve at the last trial values' if not converged.all() else
        f'{", ".join(edge)} ran to the end of its valid range or {MAX_UNITS:g} unit from its '
        'start (the chosen keys cannot explain the measurements, or the start is too far)')
    if not ok:   # the linearization at a trial point that is no optimum assesses nothing
        deviations = np.full(len(x), math.nan)
        correlation = np.full_like(correlation, math.nan)
    result = FitResult(
        names=tuple(unknowns.names), initial=unknowns.physical(x0), values=unknowns.physical(x),
        standard_errors=unknowns.physical_errors(x, deviations), correlation=correlation,
        converged=ok, message=message, samples=len(samples.wrenches),
        condition_number=condition, rank=rank, chi_square=chi_square, degrees_of_freedom=dof,
        errors_initial=errors_initial, errors=errors,
        predicted_positions=model.predicted_positions(x),
        measured_positions=samples.positions.copy())
    result.fit_time_s = time.perf_counter() - started
    result.cross_validation_skipped = cross_validation_obstacle(
        ok, folds, len(samples.wrenches), len(x))
    if not result.cross_validation_skipped:
        started = time.perf_counter()
        result.cross_validated_errors, result.cross_validation_folds = cross_validate(
            model, x, jacobian, folds)
        result.cross_validation_time_s = time.perf_counter() - started
    result.model_passes = model.passes
    result.max_discretization_error_m = model.max_error_estimate_m
    return result


def cross_validation_obstacle(converged: bool, folds: int, samples: int, unknowns: int
                              ) -> str:
    """
    Say why ``folds``-fold cross-validation of a fit cannot be made ('' when it can).

    It needs a converged fit, 2 folds or more (one fold holds nothing out) and samples
    enough that each training set (all blocks but one, ``min(folds, samples)`` blocks) gives
    more numbers (6 per sample) than ``unknowns``.
    """
    if not converged:
        return 'the fit did not converge'
    if folds < 2:
        return ('not asked for (0 folds)' if folds == 0 else
                f'{folds} fold holds nothing out (2 or more are needed)')
    used = min(folds, samples)
    smallest_training = samples - -(-samples // used) if used else 0
    if used < 2 or 6 * smallest_training <= unknowns:
        return (f'{samples} sample{"s" if samples != 1 else ""} cannot be split into '
                f'training and held-out folds that determine {unknowns} unknown'
                f'{"s" if unknowns != 1 else ""}')
    return ''


def cross_validate(model: PoseModel, x: np.ndarray, jacobian: np.ndarray, folds: int
                   ) -> Tuple[np.ndarray, int]:
    """
    Return the held-out errors (N, 6) of ``folds``-fold cross-validation, and the folds used.

    Each fold's refit starts at the full fit ``x`` and takes chord Gauss-Newton steps with
    the full fit's Jacobian restricted to the training samples until a step is below
    CV_TOLERANCE units (CV_ITERATIONS at most): the training optimum, without a Jacobian
    per fold.
    """
    count = len(model.samples.wrenches)
    folds = min(folds, count)
    held_out = np.zeros((count, 6))
    rows = jacobian.reshape(count, 6, -1)
    for block in np.array_split(np.arange(count), folds):
        training = np.setdiff1d(np.arange(count), block)
        train_jacobian = rows[training].reshape(-1, jacobian.shape[1])
        trial = x.copy()
        for _ in range(CV_ITERATIONS):
            residuals = model.residuals(trial).reshape(count, 6)[training].ravel()
            step = np.linalg.lstsq(train_jacobian, -residuals, rcond=None)[0]
            trial = trial + step
            if np.abs(step).max() < CV_TOLERANCE:
                break
        held_out[block] = model.errors(trial)[0][block]
    return held_out, folds


def fit_summary(result: FitResult) -> List[str]:
    """Return the text lines of a fit's report: estimates, correlations, residuals."""
    last = 'fitted' if result.converged else 'last trial'
    lines = [f'{"parameter (SI unit)":<24} {"initial":>13} {last:>13} {"std error":>13}']
    for name in result.names:
        error = result.standard_errors[name]
        named = f'{name} ({SI_UNITS[name]})'
        lines.append(f'{named:<24} {result.initial[name]:>13.6g} {result.values[name]:>13.6g} '
                     + (f'{error:>13.3g}' if math.isfinite(error) else f'{"not assessed":>13}'))
    if len(result.names) > 1 and result.converged:
        lines.append('correlations: ' + ', '.join(
            f'{result.names[i]}/{result.names[j]} {result.correlation[i, j]:+.3f}'
            for i in range(len(result.names)) for j in range(i + 1, len(result.names))))
    lines.append(
        f'rms error: position {rms_position(result.errors_initial) * 1e3:.4g} mm -> '
        f'{rms_position(result.errors) * 1e3:.4g} mm, angle '
        f'{rms_angle_deg(result.errors_initial):.4g} deg -> {rms_angle_deg(result.errors):.4g}'
        f' deg; reduced chi-square {result.reduced_chi_square:.4g} ({result.degrees_of_freedom}'
        ' dof)')
    lines += [f'warning: {text}' for text in result.warnings]
    if result.cross_validation_folds:
        lines.append(f'{result.cross_validation_folds}-fold cross-validated rms error: '
                     f'position {rms_position(result.cross_validated_errors) * 1e3:.4g} mm, '
                     f'angle {rms_angle_deg(result.cross_validated_errors):.4g} deg')
    else:
        lines.append(f'cross-validation not done: {result.cross_validation_skipped}')
    return lines

"""
The wrench from a measured pose: a maximum-a-posteriori estimate with the exact compliance.

Deflection-based force sensing runs the forward model backwards: the load on a continuum
robot is the one whose equilibrium has the pose a tracker sees (Rucker & Webster,
"Deflection-based force sensing for continuum robots: a probabilistic approach", IROS
2011; Black, Till & Rucker, IEEE T-RO 34(1), 2018, for parallel continuum robots). A pose
does not see every wrench direction alike: a lateral force of 1 N moves the end disk about
6 mm, an axial force of 3 N about 0.6 um, so at a tracker's 0.1-0.5 mm the axial force is
not observed at all, and a force and a moment that bend the joints alike are hard to tell
apart. Rucker & Webster's answer is a prior on the load: the estimate minimizes

    |W (y(w) - y_m)|^2 + |L (w_f - mu)|^2,

the pose error y(w) - y_m (position difference and the rotation vector log(R R_m^T), both
in the base frame: the twist convention of the compliance C, cdr_translator/analysis/compliance.py)
whitened by the pose covariance (W^T W = Sigma^-1), plus the estimated components w_f
against a Gaussian prior N(mu, P) (L^T L = P^-1; with some components held, the prior's
conditional on the held values). Directions the pose cannot see come back at the prior
with the prior's spread; the posterior covariance (J^T J)^-1, J the whitened derivative
[W C_b; L], says which.

Each iterate is a forward solve with the compliance (implicit differentiation, exact to
rounding), so the Gauss-Newton step uses the exact derivative of the position and, at a
matched pose, of the rotation. Steps are Levenberg-Marquardt steps within a trust radius
in length-scaled units (moments as the force that makes them at the stack height H), the
radius growing after steps the linearization predicted well and shrinking after steps
that do not lower the cost (Nocedal & Wright, Numerical Optimization, 2006, Ch. 4 and
10.3). The estimate has converged when the Gauss-Newton step would lower the whitened
cost by less than CONVERGED_CHI2 (a tenth of a posterior standard deviation). Along a
stream each estimate starts from the last converged one (its solve and compliance reused:
the first step needs no solve), and one that cannot converge gives up after MAX_SOLVES
forward solves.

Without a pose covariance the pose is taken as exact (a standard deviation of
EXACT_POSE_SD_M): the estimate then matches the pose to the forward solve's rounding, and
its accuracy is not assessed (``accuracy_met`` None), since nothing says how far the
measurement may be off. With one, ``accuracy_met`` compares the posterior standard
deviations with their targets, and the estimate is flagged when its normalized pose
residual fails a chi-square test, when its spread exceeds both the load it reports and the
target, past buckling, near a bifurcation, or when another wrench matches as well.

Never an exception for a pose the model cannot match: a result flagged by ``converged``,
``accuracy_met`` and ``flags``, with a message. Bad input (non-finite, wrong shape, a
non-unit quaternion, a covariance that is not symmetric positive semidefinite, an unknown
component name) raises InputError, a ValueError naming it.
"""

from .problem import (Components, Curvature, DEFAULT_PRIOR_FORCE_SD, DEFAULT_PRIOR_MOMENT_SD,
                      DEFAULT_TARGET_FORCE_SD, DEFAULT_TARGET_MOMENT_SD, diagonal_prior,
                      estimated_components, Evaluation, measured_target, Search, Target)
from .search import estimate_along, LOAD_LIMIT, search
from .verdict import estimate_from
from .wrench_estimate import (COMPONENT_CHOICES, COMPONENT_NAMES, CONDITION_LIMIT, json_safe,
                              observability, TRANSLATOR_WRENCH_LABELS, WrenchEstimate)

__all__ = ['COMPONENT_CHOICES', 'COMPONENT_NAMES', 'Components', 'CONDITION_LIMIT', 'Curvature',
           'DEFAULT_PRIOR_FORCE_SD', 'DEFAULT_PRIOR_MOMENT_SD', 'DEFAULT_TARGET_FORCE_SD',
           'DEFAULT_TARGET_MOMENT_SD', 'diagonal_prior', 'estimate_along', 'estimate_from',
           'estimated_components', 'Evaluation', 'json_safe', 'LOAD_LIMIT',
           'measured_target', 'observability', 'search', 'Search', 'Target',
           'TRANSLATOR_WRENCH_LABELS', 'WrenchEstimate']

"""
The boundary-value problem of one leg: the Cosserat-rod kernels and the shooting residual.

layout fixes the unknowns and the state vector; rod integrates one rod segment; shooting
and tangent give the residual and its exact Jacobian; multiple_shooting_kernels the node
kernels of the lifted (multiple-shooting) form for cold solves; chord the
compiled chord and Broyden steps; problem ties them to a TranslatorParams as ``Problem``.
Nothing here knows a solver: these are plain functions over arrays.
"""

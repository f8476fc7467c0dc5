"""
What a solution is worth: stability, compliance and primary mobility, the error estimate.

stability judges an equilibrium by its stiffness; compliance computes the end-disk
compliance by implicit differentiation and its screw-theory analysis (paper Section IV);
accuracy estimates the discretization error against a finer solve. They take a Problem
and arrays, never a solver.
"""

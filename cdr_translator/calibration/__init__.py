"""
Parameters from recorded runs: pose errors against a tracker, and the parameter fit.

pose_error turns tracker frames and measured poses into whitened errors; fit_parameters
names what can be fitted; pose_fit fits them by least squares over forward solves.
"""

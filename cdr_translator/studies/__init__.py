"""Analyses that solve many times: the hard-case suite and finite-difference checks."""

"""Benchmarks of cdr_translator: they print figures, they never assert timings."""

"""Offline MCAP tools for cdr_translator runs (replay, synth, info) without a ROS runtime."""

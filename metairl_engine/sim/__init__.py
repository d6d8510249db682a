"""Simulators: benchmark worlds with known rewards (terrain) and synthetic patients that produce COP recordings.

Not the method: they generate data to test and benchmark it, and are never imported by the fit.
"""

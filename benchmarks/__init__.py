"""Benchmarks of the engine and the service, each run as ``python -m benchmarks.<name>``."""

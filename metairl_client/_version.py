"""The client distribution's version (also in metairl_client/pyproject.toml)."""

__version__ = "0.1.0"

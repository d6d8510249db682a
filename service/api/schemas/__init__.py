"""Pydantic request and response bodies of the API, one module per resource (names follow docs/api.md).

A response is built from its row by ``XOut.of(row)``, the one way a row becomes a response.
"""

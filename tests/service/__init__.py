"""Tests of the HTTP API and its data layer, run on SQLite and on PostgreSQL."""

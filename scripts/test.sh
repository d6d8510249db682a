#!/usr/bin/env bash
# README command 2: set up .venv/ and run lint, types and the whole test suite.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$root/scripts/bootstrap.sh"
cd "$root"
echo "== ruff"; .venv/bin/ruff check .
echo "== ruff format"; .venv/bin/ruff format --check .
echo "== mypy"; .venv/bin/mypy metairl_engine service worker metairl_client metairl_cli tests benchmarks
echo "== pytest"; .venv/bin/pytest -q "$@"

#!/usr/bin/env bash
# README command 2: set up .venv/ and run lint, types and the whole test suite.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$root/scripts/bootstrap.sh"
cd "$root"
echo "== ruff"; .venv/bin/ruff check .
echo "== ruff format"; .venv/bin/ruff format --check .
echo "== mypy"; .venv/bin/mypy metairl_engine service worker metairl_client metairl_cli tests benchmarks
# Two test processes (pytest-xdist), each module's tests kept in one of them so that a module's servers and
# workers start once: the suite spends much of its time waiting on workers, servers and the browser, and on a
# 2-core machine it took 18 min this way against 26.5 min in one process. `-n 0` runs it in one process.
echo "== pytest"; .venv/bin/pytest -q -n 2 --dist loadscope "$@"

#!/usr/bin/env bash
# Create .venv/ in the repo root and install the project into it (idempotent, skipped when up to date).
# torch==2.13.0 goes in first so that pip takes the CPU wheel and never resolves CUDA builds.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
py="${PYTHON:-python3}"
if [[ ! -x .venv/bin/python ]]; then
  echo "metairl: creating .venv/ with $($py --version)"
  "$py" -m venv .venv
fi
stamp=".venv/.metairl-installed"
want="$(sha256sum pyproject.toml | cut -d' ' -f1)"
if [[ ! -f "$stamp" || "$(cat "$stamp")" != "$want" ]]; then
  echo "metairl: installing torch==2.13.0 (CPU) and the project into .venv/"
  .venv/bin/python -m pip install --quiet --upgrade pip
  .venv/bin/python -m pip install --quiet "torch==2.13.0"
  .venv/bin/python -m pip install --quiet -e ".[dev]"
  echo "$want" > "$stamp"
fi

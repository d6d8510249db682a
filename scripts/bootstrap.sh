#!/usr/bin/env bash
# Create .venv/ in the repo root and install the project into it (idempotent, skipped when up to date).
# torch==2.13.0 goes in first, as its CPU wheel: on Linux PyPI's torch is the CUDA build with ~3 GB of nvidia
# wheels, so the CPU one (2.13.0+cpu) is taken from pip's configured indexes if they have it (a mirror, a
# wheelhouse), else from PyTorch's CPU index. macOS wheels on PyPI are CPU builds already.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
py="${PYTHON:-python3}"
if ! "$py" -c 'import sys; sys.exit(sys.version_info < (3, 11))' 2>/dev/null; then
  echo "metairl: needs Python 3.11 or later; $py is $("$py" --version 2>&1). Set PYTHON=python3.11 (or later)." >&2
  exit 1
fi
torch_index="${TORCH_INDEX_URL:-https://download.pytorch.org/whl/cpu}"
if [[ ! -x .venv/bin/python ]]; then
  echo "metairl: creating .venv/ with $($py --version)"
  "$py" -m venv .venv
fi
stamp=".venv/.metairl-installed"
want="$(sha256sum pyproject.toml | cut -d' ' -f1)"
if [[ ! -f "$stamp" || "$(cat "$stamp")" != "$want" ]]; then
  echo "metairl: installing torch==2.13.0 (CPU) and the project into .venv/"
  .venv/bin/python -m pip install --quiet --upgrade pip
  if [[ "$(uname -s)" == Linux ]]; then
    .venv/bin/python -m pip install --quiet "torch==2.13.0+cpu" 2>/dev/null \
      || .venv/bin/python -m pip install --quiet "torch==2.13.0+cpu" --index-url "$torch_index"
  else
    .venv/bin/python -m pip install --quiet "torch==2.13.0"
  fi
  .venv/bin/python -m pip install --quiet -e ".[dev]"
  echo "$want" > "$stamp"
fi

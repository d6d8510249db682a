#!/usr/bin/env bash
# README command 1: set up .venv/ and start the whole service (API + one worker) on embedded defaults.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$root/scripts/bootstrap.sh"
cd "$root"
exec .venv/bin/metairl serve "$@"

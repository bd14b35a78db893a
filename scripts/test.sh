#!/usr/bin/env bash
# The test command: set up (idempotent), lint, then run the whole test suite.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
.venv/bin/ruff check .
.venv/bin/ruff format --check .
# RLlib's tests run in their own environment (gymnasium 1.2.2), the rest on the newest.
if [ $# -eq 0 ] && [ -x .venv-rllib/bin/python ]; then
  .venv-rllib/bin/python -m pytest -q tests/test_rllib.py
fi
exec .venv/bin/python -m pytest "$@"

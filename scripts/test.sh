#!/usr/bin/env bash
# The test command: set up (idempotent), lint, then run the whole test suite in two tiers.
#
#   bash scripts/test.sh             # everything (CI runs exactly this, through .ci/run)
#   bash scripts/test.sh ARGS...     # the whole set-up and lint, then `pytest ARGS`
#
# 1. Debian packages and .venv; ruff; then the fast tier: every test that needs neither the
#    real stack nor much time (the preCICE test double's, the docs', the library's logic).
#    A failure there stops the run before the real stack is built.
# 2. The real stack and .venv-rllib; RLlib's tests (in .venv-rllib); then the rest: the
#    real-stack and slow tests, and every fast-tier test that skipped, run again now that
#    the stack is there. The two tiers together are the whole suite (conftest.py).
#
# The sessions run on $GYMPRECICE_TEST_WORKERS processes (default 2, pytest-xdist; 1: none),
# each test to whichever worker is free (conftest.py's groups keep a Ray cluster's tests, and
# those sharing a module-wide fixture, together). Each session's durations go to
# $GYMPRECICE_TEST_OUT (JSON, see scripts/suite_report.py).
set -euo pipefail
cd "$(dirname "$0")/.."

PYTEST=(.venv/bin/python -m pytest)
# One math thread per process: the two workers and the solvers already fill both cores,
# and PyTorch's second thread only spins against them (a tiny SAC update took 5.5 CPU-s
# on two threads and 0.3 on one). Real solvers run one MPI rank each, without OpenMP.
export OMP_NUM_THREADS="${OMP_NUM_THREADS:-1}"
lint() {
  .venv/bin/ruff check .
  .venv/bin/ruff format --check .
}

if [ $# -gt 0 ]; then
  bash scripts/setup.sh
  lint
  exec "${PYTEST[@]}" "$@"
fi

OUT="${GYMPRECICE_TEST_OUT:-build/tests}"
WORKERS="${GYMPRECICE_TEST_WORKERS:-2}"
PARALLEL=()
if [ "$WORKERS" != 1 ]; then PARALLEL=(-n "$WORKERS" --dist loadgroup); fi
mkdir -p "$OUT"
rm -f "$OUT"/durations-*.json "$OUT/skipped-in-fast-tier.txt"
export GYMPRECICE_TIER_SKIPPED="$OUT/skipped-in-fast-tier.txt"

bash scripts/setup.sh base
lint
GYMPRECICE_TIER=fast GYMPRECICE_DURATIONS="$OUT/durations-1-fast.json" \
  "${PYTEST[@]}" ${PARALLEL[@]+"${PARALLEL[@]}"}

bash scripts/setup.sh stack
# RLlib's tests run in their own environment (gymnasium 1.2.2), the rest on the newest.
status=0
if [ -x .venv-rllib/bin/python ]; then
  GYMPRECICE_DURATIONS="$OUT/durations-2-rllib.json" \
    .venv-rllib/bin/python -m pytest -q tests/test_rllib.py tests/test_rllib_multiagent.py || status=$?
fi
GYMPRECICE_TIER=rest GYMPRECICE_DURATIONS="$OUT/durations-3-rest.json" \
  "${PYTEST[@]}" ${PARALLEL[@]+"${PARALLEL[@]}"} || status=$?
exit "$status"

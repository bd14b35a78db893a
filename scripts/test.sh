#!/usr/bin/env bash
# The test command: set up (idempotent), lint, then run the whole test suite in two tiers.
#
#   bash scripts/test.sh             # everything (CI runs exactly this, through .ci/run)
#   bash scripts/test.sh ARGS...     # the whole set-up and lint, then `pytest ARGS`
#
# 1. Debian packages and .venv; ruff; then the fast tier: every test that needs neither the
#    real stack nor much time (the preCICE test double's, the docs', the library's logic).
#    A failure there stops the run before the real stack is built.
# 2. The real stack and .venv-rllib; then the rest: the
#    real-stack and slow tests, and every fast-tier test that skipped, run again now that
#    the stack is there. The two tiers together are the whole suite (conftest.py). The
#    rest's tests that mostly wait (a Ray cluster's, those marked `waits`), then RLlib's,
#    run in sessions of their own beside the others.
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
# The rest's tests that mostly wait: those that start a Ray cluster (for nodes, heartbeats,
# restarted actors) and those marked `waits` (for timeouts and signals), one after another,
# then RLlib's in their own environment (gymnasium 1.2.2, .venv-rllib): two Ray clusters at
# once would compete for the same ports.
waiting_sessions() {
  local failed=0
  GYMPRECICE_TIER=waiting GYMPRECICE_DURATIONS="$OUT/durations-4-waiting.json" \
    "${PYTEST[@]}" || failed=$?
  if [ -x .venv-rllib/bin/python ]; then
    GYMPRECICE_DURATIONS="$OUT/durations-2-rllib.json" \
      .venv-rllib/bin/python -m pytest -q tests/test_rllib.py tests/test_rllib_multiagent.py ||
      failed=$?
  fi
  return "$failed"
}
status=0
if [ "$WORKERS" != 1 ]; then
  # They run beside the rest's other tests, which have the workers; their output is shown
  # once they end.
  waiting_sessions >"$OUT/waiting-sessions.log" 2>&1 &
  waiting_pid=$!
  # they never outlive this script: stopped with it, or when it ends early
  stop_waiting_sessions() {
    pkill -TERM -P "$waiting_pid" 2>/dev/null || true # the session's pytest, then the shell
    kill "$waiting_pid" 2>/dev/null || true
  }
  trap stop_waiting_sessions EXIT
  trap 'exit 143' TERM
  trap 'exit 130' INT
  GYMPRECICE_TIER=local GYMPRECICE_DURATIONS="$OUT/durations-3-rest.json" \
    "${PYTEST[@]}" ${PARALLEL[@]+"${PARALLEL[@]}"} || status=$?
  waiting_status=0
  wait "$waiting_pid" || waiting_status=$?
  echo "== the rest's tests that mostly wait, then RLlib's (sessions beside the others) =="
  cat "$OUT/waiting-sessions.log"
  if [ "$waiting_status" != 0 ]; then status=$waiting_status; fi
else
  waiting_sessions || status=$?
  GYMPRECICE_TIER=local GYMPRECICE_DURATIONS="$OUT/durations-3-rest.json" \
    "${PYTEST[@]}" || status=$?
fi
exit "$status"

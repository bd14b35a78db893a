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

# The test sessions never outlive this script: on any exit, each is stopped with every
# process under it. Each tree is frozen before it is told to stop, so that no parent sees
# a child end and starts another in its place; what is still there 10 s later (a Ray
# driver's own SIGTERM handler can hang) is killed.
BACKGROUND=()
tree() {
  local child
  echo "$1"
  for child in $(pgrep -P "$1" 2>/dev/null); do tree "$child"; done
}
stop_background() {
  local pid pids=() left=()
  for pid in ${BACKGROUND[@]+"${BACKGROUND[@]}"}; do
    mapfile -t -O "${#pids[@]}" pids < <(tree "$pid")
  done
  [ ${#pids[@]} -gt 0 ] || return 0
  kill -STOP "${pids[@]}" 2>/dev/null || true
  kill -TERM "${pids[@]}" 2>/dev/null || true
  kill -CONT "${pids[@]}" 2>/dev/null || true
  for _ in $(seq 20); do
    left=()
    for pid in "${pids[@]}"; do
      if kill -0 "$pid" 2>/dev/null; then mapfile -t -O "${#left[@]}" left < <(tree "$pid"); fi
    done
    [ ${#left[@]} -gt 0 ] || return 0
    sleep 0.5
  done
  kill -KILL "${left[@]}" 2>/dev/null || true
}
trap stop_background EXIT
trap 'exit 143' TERM
trap 'exit 130' INT
# A test session runs as a job this script waits for: bash runs a trap only between two
# commands, so a TERM would otherwise wait for the whole session to end.
session() {
  local pid status=0
  "$@" &
  pid=$!
  BACKGROUND+=("$pid")
  wait "$pid" || status=$?
  unset 'BACKGROUND[${#BACKGROUND[@]}-1]'
  return "$status"
}

bash scripts/setup.sh base
lint
GYMPRECICE_TIER=fast GYMPRECICE_DURATIONS="$OUT/durations-1-fast.json" \
  session "${PYTEST[@]}" ${PARALLEL[@]+"${PARALLEL[@]}"}

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
  BACKGROUND+=("$waiting_pid")
  GYMPRECICE_TIER=local GYMPRECICE_DURATIONS="$OUT/durations-3-rest.json" \
    session "${PYTEST[@]}" ${PARALLEL[@]+"${PARALLEL[@]}"} || status=$?
  waiting_status=0
  wait "$waiting_pid" || waiting_status=$?
  BACKGROUND=()
  echo "== the rest's tests that mostly wait, then RLlib's (sessions beside the others) =="
  cat "$OUT/waiting-sessions.log"
  if [ "$waiting_status" != 0 ]; then status=$waiting_status; fi
else
  session waiting_sessions || status=$?
  GYMPRECICE_TIER=local GYMPRECICE_DURATIONS="$OUT/durations-3-rest.json" \
    session "${PYTEST[@]}" || status=$?
fi
exit "$status"

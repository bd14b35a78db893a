#!/usr/bin/env bash
# Build what a release would publish, check it, and test it as a pip user gets it. Publishes
# nothing.
#
#   bash scripts/release.sh        # after bash scripts/setup.sh (it uses .venv)
#
# 1. For each of the six distributions, an sdist and a wheel built *from that sdist*
#    (python -m build), so a file missing from the sdist fails here, into dist/.
# 2. twine check --strict: the metadata and the README render as the index will show them.
# 3. tests/test_wheels.py on exactly these wheels: installed with pip alone, pip's own
#    configuration isolated, into fresh virtual environments, and used from outside the
#    repository (the install sets and commands are in the test's docstrings; about 5 min).
#
# Variables: PYTHON (default .venv/bin/python).
set -euo pipefail
cd "$(dirname "$0")/.."

PYTHON="${PYTHON:-.venv/bin/python}"
DISTRIBUTIONS=(gymprecice-core gymprecice-openfoam gymprecice-dealii gymprecice-fenics
  gymprecice-lab gymprecice-tutorials)

rm -rf dist
mkdir -p dist
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

"$PYTHON" -m build --version >/dev/null 2>&1 || "$PYTHON" -m pip install -q build
# twine in a virtual environment of its own where $PYTHON lacks it (it only reads files)
TWINE=("$PYTHON" -m twine)
if ! "$PYTHON" -m twine --version >/dev/null 2>&1; then
  "$PYTHON" -m venv "$work/twine"
  "$work/twine/bin/python" -m pip install -q --disable-pip-version-check twine
  TWINE=("$work/twine/bin/python" -m twine)
fi
for dist in "${DISTRIBUTIONS[@]}"; do
  # a clean copy: an editable install's egg-info and setuptools' build/ stay behind
  cp -r "packages/$dist" "$work/$dist"
  rm -rf "$work/$dist/build"
  find "$work/$dist" \( -name '*.egg-info' -o -name __pycache__ \) -prune -exec rm -rf {} +
  # --no-isolation: the build backend (setuptools >= 77) comes from this environment, so
  # the release builds offline; the wheel is built from the sdist
  "$PYTHON" -m build --no-isolation --outdir dist "$work/$dist" >"$work/$dist.log" 2>&1 || {
    cat "$work/$dist.log" >&2
    echo "release: building $dist failed" >&2
    exit 1
  }
  echo "release: built $dist: $(cd dist && ls "${dist//-/_}"-* | tr '\n' ' ')"
done

"${TWINE[@]}" check --strict dist/*

GYMPRECICE_WHEELHOUSE="$PWD/dist" "$PYTHON" -m pytest -q -p no:cacheprovider tests/test_wheels.py
echo "release: dist/ holds $(find dist -name '*.whl' | wc -l) wheels and" \
  "$(find dist -name '*.tar.gz' | wc -l) sdists, checked and tested; nothing was published"

#!/usr/bin/env bash
# Set up a development environment on a fresh Debian machine: system solvers + .venv.
#
#   bash scripts/setup.sh            # everything the tests need
#
# Installs (when missing and when allowed to): Debian's OpenFOAM v1912 and deal.II, which the
# tests run for real; then a virtual environment in .venv with the four distributions
# editable. torch is installed *pinned* before stable-baselines3 so pip takes the CPU build
# instead of resolving an unpinned torch with several GB of CUDA packages.
# preCICE itself is in no package registry: see README ("Real preCICE and the adapters");
# where pkg-config finds one, pyprecice is built against it.
set -euo pipefail
cd "$(dirname "$0")/.."

TORCH_VERSION="${GYMPRECICE_TORCH_VERSION:-2.13.0}"
PYTHON="${PYTHON:-python3}"

apt_install() {
  local missing=()
  for pkg in "$@"; do dpkg -s "$pkg" >/dev/null 2>&1 || missing+=("$pkg"); done
  [ ${#missing[@]} -eq 0 ] && return 0
  local sudo=""
  if [ "$(id -u)" -ne 0 ]; then
    if command -v sudo >/dev/null 2>&1; then sudo="sudo"; else
      echo "setup: cannot install ${missing[*]} (not root, no sudo); tests that need them will be skipped" >&2
      return 0
    fi
  fi
  echo "setup: installing ${missing[*]} from Debian"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
}

if command -v apt-get >/dev/null 2>&1 && [ "${GYMPRECICE_SKIP_APT:-0}" != "1" ]; then
  apt_install openfoam libdeal.ii-dev libopenmpi-dev
fi

if [ ! -x .venv/bin/python ]; then
  "$PYTHON" -m venv .venv
fi
PIP=".venv/bin/python -m pip"
$PIP install -q --disable-pip-version-check --upgrade pip >/dev/null
if ! .venv/bin/python -c "import torch" >/dev/null 2>&1; then
  $PIP install -q --disable-pip-version-check "torch==${TORCH_VERSION}"
fi
$PIP install -q --disable-pip-version-check \
  -e packages/gymprecice-core \
  -e packages/gymprecice-openfoam \
  -e packages/gymprecice-dealii \
  -e "packages/gymprecice-tutorials[train]" \
  pytest pytest-timeout "ruff==0.17.6" build mpi4py
# pyprecice compiles against an installed preCICE (in no package registry: README, "Real
# preCICE and the adapters"); take it whenever pkg-config finds one.
if command -v pkg-config >/dev/null 2>&1 && pkg-config --exists libprecice \
  && ! .venv/bin/python -c "import precice" >/dev/null 2>&1; then
  $PIP install -q --disable-pip-version-check -e "packages/gymprecice-core[precice]" \
    || echo "setup: pyprecice did not build against preCICE $(pkg-config --modversion libprecice); the tests that need it will be skipped" >&2
fi
echo "setup: done (.venv ready)"

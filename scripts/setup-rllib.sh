#!/usr/bin/env bash
# A second virtual environment, .venv-rllib, for RLlib: ray[rllib] 2.60 pins gymnasium 1.2.2,
# older than the Gymnasium of .venv, so it cannot share .venv. tests/test_rllib.py runs here
# (it skips in .venv), and so does tests/test_rllib_multiagent.py, RLlib's multi-agent API on
# a PettingZoo env (PettingZoo 1.27 asks only gymnasium>=1.0, the version .venv has too).
#
#   bash scripts/setup-rllib.sh      # idempotent: a second run takes seconds
#
# torch is installed *pinned* first, with pip, so pip takes the CPU build instead of
# resolving an unpinned torch with several GB of CUDA packages; uv installs the rest.
set -euo pipefail
cd "$(dirname "$0")/.."
# shellcheck source=scripts/venv-install.sh
source scripts/venv-install.sh

TORCH_VERSION="${GYMPRECICE_TORCH_VERSION:-2.13.0}"
RAY_VERSION="${GYMPRECICE_RLLIB_RAY_VERSION:-2.60.0}"
PETTINGZOO_VERSION="${GYMPRECICE_PETTINGZOO_VERSION:-1.27.0}"
PYTHON="${PYTHON:-python3}"
VENV=.venv-rllib
START=$SECONDS

if [ ! -x "$VENV/bin/python" ]; then
  "$PYTHON" -m venv "$VENV"
fi
PY="$VENV/bin/python"
STAMP="$VENV/.gymprecice-setup"
WANT="torch==${TORCH_VERSION} ray[rllib]==${RAY_VERSION} pettingzoo==${PETTINGZOO_VERSION} tutorials[train] $(cat pyproject.toml packages/*/pyproject.toml scripts/venv-install.sh | cksum)"

if [ -f "$STAMP" ] && [ "$(cat "$STAMP")" = "$WANT" ] \
  && "$PY" -c "import torch, ray.rllib, pettingzoo, gymprecice, gymprecice_tutorials, stable_baselines3, pytest" >/dev/null 2>&1; then
  echo "setup-rllib: $VENV up to date ($((SECONDS - START)) s)"
  exit 0
fi

# torch pinned with pip, the rest with uv, torch held (scripts/venv-install.sh)
venv_install "$PY" "$TORCH_VERSION" \
  "ray[rllib]==${RAY_VERSION}" \
  "pettingzoo==${PETTINGZOO_VERSION}" \
  -e packages/gymprecice-core \
  -e packages/gymprecice-openfoam \
  -e packages/gymprecice-dealii \
  -e packages/gymprecice-fenics \
  -e packages/gymprecice-lab \
  -e "packages/gymprecice-tutorials[train]" \
  pytest pytest-timeout
"$PY" -c "import gymnasium, pettingzoo, ray, torch; print('setup-rllib: ray', ray.__version__, 'gymnasium', gymnasium.__version__, 'pettingzoo', pettingzoo.__version__, 'torch', torch.__version__)"
echo "$WANT" >"$STAMP"
echo "setup-rllib: $VENV ready in $((SECONDS - START)) s"

#!/usr/bin/env bash
# The main job: train a PPO controller on the jet cylinder (JetCylinder-v0).
#
#   bash scripts/train.sh [extra `gymprecice train` options, e.g. --n-envs 8 --timesteps 200000]
#
# Sets up the machine like the tests do, then checks it with `gymprecice doctor`: training
# couples to real OpenFOAM through preCICE, so without preCICE (and the OpenFOAM-preCICE
# adapter) it stops at once and says what to install.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
exec .venv/bin/gymprecice train jet-cylinder --require-solvers "$@"

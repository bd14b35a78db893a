#!/usr/bin/env bash
# Remake the documentation's flow pictures on the real solvers (preCICE, OpenFOAM, deal.II):
#   docs/assets/wake.mp4, wake.png   the jet cylinder's wake, uncontrolled and under the
#                                    shipped policy, side by side (home page)
#   docs/assets/field-*.png          each tutorial's field snapshot (tutorial pages)
#   docs/assets/sketch-*.png         each tutorial's case sketch (tutorial pages), drawn by
#                                    `gymprecice sketch` from the case files (blockMesh)
#   docs/assets/anim-*.mp4           each environment's short animation (the gallery): one
#                                    held-out start under its shipped policy (uncontrolled
#                                    where it ships none), a frame per action
# FSI3's pictures need its library of starts where the env looks for it: build it first
# (python -m gymprecice_tutorials.turek_hron.build_starts; docs/tutorials/turek-hron-fsi3.md).
# Usage: bash scripts/make_docs_pictures.sh [wake|snapshots|sketches|animations|all]
# (default: all)
# EPISODE_TIME (default 2) sets the wake video's simulated seconds; DOUBLE=1 makes the
# snapshots on the test double instead, to try the script on a machine without solvers
# (the pages say their pictures are the real solvers': do not publish those).
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-.venv/bin/python}
GP=${GYMPRECICE:-.venv/bin/gymprecice}
EPISODE_TIME=${EPISODE_TIME:-2}
what=${1:-all}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
mkdir -p docs/assets

if [[ $what == wake || $what == all ]]; then
    # the same start (seed 0) for both runs; compare puts them side by side
    "$GP" baseline jet-cylinder-fast --episode-time "$EPISODE_TIME" --out "$work/base" --video
    "$GP" evaluate jet-cylinder-fast --policy shipped --episode-time "$EPISODE_TIME" \
        --out "$work/shipped" --video
    "$GP" compare "$work/base" "$work/shipped" --out "$work/compare" \
        --video docs/assets/wake.mp4
    "$PY" scripts/docs_pictures.py still docs/assets/wake.mp4 docs/assets/wake.png --stack 2
fi

if [[ $what == snapshots || $what == all ]]; then
    double=()
    [[ ${DOUBLE:-0} == 1 ]] && double=(--double)
    while read -r env name steps; do
        "$PY" scripts/docs_pictures.py snapshot "$env" "docs/assets/field-$name.png" \
            --steps "$steps" "${double[@]}"
    done <<'EOF'
gymprecice/Quickstart-v0 quickstart 8
gymprecice/JetCylinderFast-v0 jet-cylinder 8
gymprecice/RotatingCylinderFast-v0 rotating-cylinder 8
gymprecice/PerpendicularFlapFast-v0 perpendicular-flap 4
gymprecice/HeatedPlateFast-v0 heated-plate 4
gymprecice/TwoFlapsFast-v0 two-flaps 4
EOF
fi

if [[ $what == sketches || $what == all ]]; then
    while read -r env name; do
        "$GP" sketch "$env" --out "docs/assets/sketch-$name.png"
    done <<'EOF'
quickstart quickstart
jet-cylinder-fast jet-cylinder
rotating-cylinder-fast rotating-cylinder
perpendicular-flap-fast perpendicular-flap
heated-plate-fast heated-plate
two-flaps-fast two-flaps
turek-hron-fsi3 turek-hron-fsi3
EOF
fi

if [[ $what == animations || $what == all ]]; then
    # ENV NAME SECONDS COMMAND: the policy where one ships, from the first held-out start;
    # SECONDS shortens the episode of an env that takes --episode-time ("-": its own)
    while read -r env name seconds command; do
        options=(--episodes 1)
        [[ $command == evaluate ]] && options+=(--policy shipped)
        [[ $seconds != - ]] && options+=(--episode-time "$seconds")
        "$GP" "$command" "$env" "${options[@]}" --out "$work/anim-$name" \
            --video "docs/assets/anim-$name.mp4"
    done <<'EOF'
quickstart quickstart 1 baseline
jet-cylinder-fast jet-cylinder 2 evaluate
rotating-cylinder-fast rotating-cylinder 2 evaluate
perpendicular-flap-fast perpendicular-flap - evaluate
heated-plate-fast heated-plate - evaluate
two-flaps-fast two-flaps 3 evaluate
turek-hron-fsi3 turek-hron-fsi3 0.4 baseline
EOF
    # FSI3's still is its animation's last frame: a snapshot would pay for another episode
    # (an FSI3 episode costs about 14 min a simulated second on 2 cores)
    "$PY" scripts/docs_pictures.py still docs/assets/anim-turek-hron-fsi3.mp4 \
        docs/assets/field-turek-hron-fsi3.png
fi

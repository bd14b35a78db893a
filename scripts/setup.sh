#!/usr/bin/env bash
# Set up a development environment on a fresh Debian machine: solvers, the real coupling
# stack, and .venv.
#
#   bash scripts/setup.sh            # everything the tests and `bash scripts/train.sh` need
#   bash scripts/setup.sh base       # only 1 and 2 (enough for the lint and the fast tests)
#   bash scripts/setup.sh stack      # only 3 and 4 (after `base`)
#
# It ends with its time split (apt, .venv, each stack piece, .venv-rllib); with
# GYMPRECICE_SETUP_TIMES=<file> the split is also appended to that file.
#
# 1. Debian packages (when missing and when allowed to): OpenFOAM v1912, deal.II, Open MPI,
#    and what building preCICE needs (compiler, CMake, Boost, Eigen, libxml2), in one apt
#    transaction; while apt runs, step 2 runs beside it where Python can make a venv already.
# 2. A virtual environment in .venv with the distributions editable. torch is installed
#    *pinned*, with pip, before stable-baselines3 so pip takes the CPU build instead of
#    resolving an unpinned torch with several GB of CUDA packages; uv installs the rest, with
#    torch held (scripts/venv-install.sh). Also the documentation site's dependencies
#    (docs/requirements.txt) and TorchRL for its guide (examples/).
# 3. `gymprecice install`: preCICE, pyprecice and both preCICE adapters, built from release
#    sources into a per-user prefix (reused by every clone; a second run takes seconds).
#    Sources: $GYMPRECICE_SOURCES (an offline mirror of the release archives; default: a
#    `vendor/` folder in `../shared/` beside the checkout, where one exists), else downloaded.
#    Once preCICE is built, two of the steps that need it build side by side (`--at-once
#    2`): each keeps one core busy for much of its build (docs/contributing/test-suite.md).
#    A piece that cannot be built is reported with its log and the fix; the rest of the
#    set-up goes on, and the tests that need that piece skip (fail under
#    GYMPRECICE_REQUIRE_REAL=1, as in CI).
#
#    With it, the FEniCS solver environment (`gymprecice install fenics`): Debian's
#    python3-dolfin on the system Python, numpy 1.x, pyprecice against the stack and
#    fenicsprecice, in the stack prefix (reused by every clone, like the adapters).
#
# 4. .venv-rllib: RLlib (ray[rllib] 2.60 pins gymnasium 1.2.2) for the RLlib tests.
#
# Variables: GYMPRECICE_SKIP_APT=1 (no apt), GYMPRECICE_SKIP_STACK=1 (no native builds),
# GYMPRECICE_SKIP_RLLIB=1 (no .venv-rllib), GYMPRECICE_SKIP_FENICS=1 (no FEniCS packages
# nor FEniCS solver environment; the FEniCS tests skip, or fail under GYMPRECICE_REQUIRE_REAL=1),
# GYMPRECICE_SOURCES, GYMPRECICE_STACK_PREFIX (default ~/.local/share/gymprecice/stack).
set -euo pipefail
cd "$(dirname "$0")/.."
# shellcheck source=scripts/venv-install.sh
source scripts/venv-install.sh

TORCH_VERSION="${GYMPRECICE_TORCH_VERSION:-2.13.0}"
PYTHON="${PYTHON:-python3}"
SETUP_START=$SECONDS

phase() { echo "setup: $1 ($((SECONDS - SETUP_START)) s so far)"; }

PART="${1:-all}"
case "$PART" in
  all | base | stack) ;;
  *)
    echo "usage: bash scripts/setup.sh [base|stack] (no argument: both)" >&2
    exit 2
    ;;
esac

# The time split: "what|seconds" per piece, said at the end (and appended to a file).
SPLIT=()
split_add() { SPLIT+=("$1|$2"); }
split_say() {
  local row label seconds unit lines=()
  lines+=("setup ($PART) time split, $((SECONDS - SETUP_START)) s in all:")
  for row in "${SPLIT[@]}"; do
    label="${row%|*}"
    seconds="${row##*|}"
    if [ "$seconds" = - ]; then seconds="" unit=""; else unit=" s"; fi
    lines+=("$(printf '  %-44s %5s%s' "$label" "$seconds" "$unit")")
  done
  printf '%s\n' "${lines[@]}"
  if [ -n "${GYMPRECICE_SETUP_TIMES:-}" ]; then
    mkdir -p "$(dirname "$GYMPRECICE_SETUP_TIMES")"
    printf '%s\n' "${lines[@]}" >>"$GYMPRECICE_SETUP_TIMES"
  fi
}

SOLVER_PACKAGES=(openfoam libdeal.ii-dev libopenmpi-dev)
BUILD_PACKAGES=(g++ make cmake pkg-config libeigen3-dev libxml2-dev
  libboost-dev libboost-log-dev libboost-thread-dev libboost-system-dev
  libboost-filesystem-dev libboost-program-options-dev libboost-test-dev)

# Debian's legacy FEniCS is built for the system Python only: FEniCS participants run in a
# solver environment of their own (see `gymprecice install fenics`).
FENICS_PACKAGES=(python3-dolfin python3-scipy python3-venv)
INSTALL_SKIP=()
if [ "${GYMPRECICE_SKIP_FENICS:-0}" = "1" ]; then
  INSTALL_SKIP=(--skip fenics)
fi

SUDO=""
can_apt() {
  command -v apt-get >/dev/null 2>&1 && [ "${GYMPRECICE_SKIP_APT:-0}" != "1" ] || return 1
  if [ "$(id -u)" -ne 0 ]; then
    command -v sudo >/dev/null 2>&1 || return 1
    SUDO="sudo"
  fi
}

# apt's package lists are refreshed once per set-up, when something is missing or a source
# was added (APT_STALE=1).
APT_STALE=0
apt_install() {
  local missing=()
  for pkg in "$@"; do dpkg -s "$pkg" >/dev/null 2>&1 || missing+=("$pkg"); done
  if [ ${#missing[@]} -eq 0 ] && [ "$APT_STALE" = 0 ]; then return 0; fi
  $SUDO apt-get update -qq
  APT_STALE=0
  [ ${#missing[@]} -eq 0 ] && return 0
  echo "setup: installing ${missing[*]} from Debian"
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends \
    "${missing[@]}" >/dev/null
}

# Debian's OpenFOAM ships no headers and no wmake; the OpenFOAM-preCICE adapter is built
# against the same release's source package, which apt fetches only with a deb-src entry.
# The entry mirrors the machine's own Debian `deb` sources (same mirror, same suites).
ensure_deb_src() {
  [ -n "$(apt-cache showsrc openfoam 2>/dev/null | head -1)" ] && return 0
  local made
  made=$($SUDO python3 - <<'PY'
import pathlib, re
root = pathlib.Path("/etc/apt")
made = []
for src in sorted((root / "sources.list.d").glob("*.sources")):
    text = src.read_text()
    stanzas = [s for s in re.split(r"\n\s*\n", text) if re.search(r"^Types:.*\bdeb\b", s, re.M)]
    stanzas = [s for s in stanzas if "deb-src" not in s and "debian" in s]
    if stanzas:
        out = root / "sources.list.d" / f"gymprecice-src-{src.stem}.sources"
        out.write_text("\n\n".join(re.sub(r"^Types:.*$", "Types: deb-src", s, flags=re.M)
                                   for s in stanzas) + "\n")
        made.append(str(out))
lines = []
legacy = root / "sources.list"
if legacy.is_file():
    lines = [ln.replace("deb ", "deb-src ", 1) for ln in legacy.read_text().splitlines()
             if ln.startswith("deb ") and "debian" in ln]
if lines:
    out = root / "sources.list.d" / "gymprecice-src.list"
    out.write_text("\n".join(lines) + "\n")
    made.append(str(out))
print(" ".join(made))
PY
)
  if [ -n "$made" ]; then
    echo "setup: added deb-src entries for Debian's OpenFOAM sources ($made)"
    APT_STALE=1
  fi
}

# Every Debian package the set-up needs, in one transaction (one `apt-get update`, one dpkg
# run). When FEniCS's packages cannot be installed, the rest is installed without them.
debian_packages() {
  local wanted=("${SOLVER_PACKAGES[@]}") fenics=()
  if [ "${GYMPRECICE_SKIP_FENICS:-0}" != "1" ]; then fenics=("${FENICS_PACKAGES[@]}"); fi
  if [ "${GYMPRECICE_SKIP_STACK:-0}" != "1" ]; then
    wanted+=("${BUILD_PACKAGES[@]}")
    ensure_deb_src || echo "setup: could not add deb-src entries; see the OpenFOAM adapter step" >&2
  fi
  if apt_install "${wanted[@]}" ${fenics[@]+"${fenics[@]}"}; then return 0; fi
  [ ${#fenics[@]} -gt 0 ] || return 1
  echo "setup: could not install ${FENICS_PACKAGES[*]}; the FEniCS solver environment" \
    "will not build (install them, then run \`gymprecice install fenics\`)" >&2
  apt_install "${wanted[@]}"
}

# apt and pip share no files and each keeps about one core busy: where this Python can make
# a venv before apt has run (python3-venv is there, or .venv is), they run side by side.
APT_PID=""
RLLIB_PID=""
SCRATCH=$(mktemp -d)
APT_SECONDS="$SCRATCH/apt-seconds"
# On any exit: wait for what runs in the background (never leave apt half done), tidy up.
cleanup() {
  local pid
  for pid in $APT_PID $RLLIB_PID; do wait "$pid" 2>/dev/null || true; done
  rm -rf "$SCRATCH"
}
trap cleanup EXIT
if [ "$PART" = stack ]; then
  [ -x .venv/bin/python ] || { echo "setup: no .venv; run \`bash scripts/setup.sh base\` first" >&2; exit 1; }
elif can_apt; then
  if [ -x .venv/bin/python ] || "$PYTHON" -c "import ensurepip, venv" >/dev/null 2>&1; then
    (
      started=$SECONDS
      debian_packages
      echo $((SECONDS - started)) >"$APT_SECONDS"
      phase "Debian packages ready"
    ) &
    APT_PID=$!
  else
    started=$SECONDS
    debian_packages
    echo $((SECONDS - started)) >"$APT_SECONDS"
    phase "Debian packages ready"
  fi
else
  echo "setup: not installing Debian packages (no apt, not root and no sudo, or GYMPRECICE_SKIP_APT=1)" >&2
fi

# .venv (not in `setup.sh stack`)
VENV_START=$SECONDS
if [ "$PART" != stack ]; then
if [ ! -x .venv/bin/python ]; then
  "$PYTHON" -m venv .venv
fi
# What .venv was installed from: the distributions' pyproject.toml files, the docs'
# requirements and this script. When none changed since the last install and every
# distribution still imports, pip has nothing to do: skip it (it takes most of a minute
# only to find that out, and `bash scripts/train.sh` counts that time).
VENV_STAMP=.venv/.gymprecice-setup-inputs
venv_inputs() {
  cat pyproject.toml packages/*/pyproject.toml docs/requirements.txt "$0" scripts/venv-install.sh |
    sha256sum | cut -d' ' -f1
}
if [ -f "$VENV_STAMP" ] && [ "$(cat "$VENV_STAMP")" = "$(venv_inputs)" ] &&
  .venv/bin/python -c "import gymprecice, gymprecice_lab, gymprecice_tutorials, gymprecice_openfoam, gymprecice_dealii, gymprecice_fenics, torch, xdist" >/dev/null 2>&1; then
  echo "setup: .venv up to date (its inputs are unchanged since it was installed)"
else
rm -f "$VENV_STAMP"
# torch pinned with pip, the rest with uv (scripts/venv-install.sh says why); pytest-xdist
# runs the test suite's two workers (scripts/test.sh)
venv_install .venv/bin/python "$TORCH_VERSION" \
  -e "packages/gymprecice-core[ray]" \
  -e packages/gymprecice-openfoam \
  -e packages/gymprecice-dealii \
  -e packages/gymprecice-fenics \
  -e packages/gymprecice-lab \
  -e "packages/gymprecice-tutorials[train]" \
  pytest pytest-timeout "pytest-xdist==3.8.0" "ruff==0.17.6" build mpi4py pettingzoo \
  imageio imageio-ffmpeg moviepy \
  -r docs/requirements.txt "torchrl==0.14.1"
venv_inputs >"$VENV_STAMP"
fi
phase ".venv ready"
split_add ".venv (pip)" $((SECONDS - VENV_START))
fi
if [ -n "$APT_PID" ]; then
  wait "$APT_PID" || { echo "setup: installing the Debian packages failed (see above)" >&2; exit 1; }
fi
if [ -s "$APT_SECONDS" ]; then
  split_add "Debian packages (apt, one transaction)" "$(cat "$APT_SECONDS")"
fi
if [ "$PART" = base ]; then
  split_say
  echo "setup: base done (.venv ready) in $((SECONDS - SETUP_START)) s"
  exit 0
fi

if [ "${GYMPRECICE_SKIP_STACK:-0}" != "1" ]; then
  if [ -z "${GYMPRECICE_SOURCES:-}" ] && [ -d ../shared/vendor ]; then
    GYMPRECICE_SOURCES="$(cd ../shared/vendor && pwd)"
    export GYMPRECICE_SOURCES
  fi
fi
# RLlib pins an older Gymnasium (1.2.2) than .venv's: its own environment, its own tests. It
# is mostly unpacking wheels, the stack mostly compiling: they are built side by side.
RLLIB_LOG="$SCRATCH/rllib.log"
RLLIB_SECONDS="$SCRATCH/rllib-seconds"
if [ "${GYMPRECICE_SKIP_RLLIB:-0}" != "1" ]; then
  (
    started=$SECONDS
    bash scripts/setup-rllib.sh >"$RLLIB_LOG" 2>&1
    echo $((SECONDS - started)) >"$RLLIB_SECONDS"
  ) &
  RLLIB_PID=$!
fi
if [ "${GYMPRECICE_SKIP_STACK:-0}" != "1" ]; then
  STACK_START=$SECONDS
  INSTALL_LOG="$SCRATCH/install.log"
  if ! .venv/bin/gymprecice install all --at-once 2 ${INSTALL_SKIP[@]+"${INSTALL_SKIP[@]}"} | tee "$INSTALL_LOG"; then
    echo "setup: part of the real stack did not build (see above); the tests that need it" \
      "will skip, or fail under GYMPRECICE_REQUIRE_REAL=1" >&2
  fi
  split_add "real stack (gymprecice install), of which:" $((SECONDS - STACK_START))
  # the install summary's lines: "  <step>  built in N s  <path>" (or done, found, failed)
  while read -r step status rest; do
    case "$status" in
      built | failed) split_add "  $step ($status)" "$(sed -E 's/^in ([0-9]+) s.*/\1/' <<<"$rest")" ;;
      *) split_add "  $step ($status)" - ;;
    esac
  done < <(sed -n '/^\[install\] summary/,$p' "$INSTALL_LOG" | tail -n +2)
  phase "real stack checked"
fi
if [ -n "$RLLIB_PID" ]; then
  if ! wait "$RLLIB_PID"; then
    cat "$RLLIB_LOG" >&2
    echo "setup: building .venv-rllib failed (above)" >&2
    exit 1
  fi
  grep -v '^WARNING: Location' "$RLLIB_LOG" || true
  split_add ".venv-rllib (beside the stack)" "$(cat "$RLLIB_SECONDS")"
  phase ".venv-rllib ready"
fi
split_say
echo "setup: done (.venv ready) in $((SECONDS - SETUP_START)) s"

# Sourced by scripts/setup.sh and scripts/setup-rllib.sh: install packages into a virtual
# environment, torch pinned.
#
#   venv_install VENV_PYTHON TORCH_VERSION [pip/uv install arguments...]
#
# torch is installed first with pip, *pinned*: pip's configuration is where a machine keeps
# a CPU build of torch (a find-links folder, a constraint), and uv reads none of it; an
# unpinned torch would resolve to a CUDA build of several GB. Everything else is installed
# by uv (`uv pip install`, uv itself put in the environment by pip), with torch held at the
# installed version by a constraint: on a 2-core machine uv installs the rest of .venv in
# about 10 s where pip took 73 s (same packages, same versions, empty caches both; before
# byte-compiling, which both do). Where uv cannot be installed or fails, pip installs the
# rest, as before.
venv_install() {
  local python="$1" torch_version="$2" constraints
  shift 2
  local pip=("$python" -m pip install -q --disable-pip-version-check)
  if [ "$("$python" -c 'import torch; print(torch.__version__.split("+")[0])' 2>/dev/null)" != "$torch_version" ]; then
    "${pip[@]}" "torch==${torch_version}"
  fi
  local bin
  bin="$(dirname "$python")"
  if [ -x "$bin/uv" ] || "${pip[@]}" uv >/dev/null 2>&1; then
    constraints="$(mktemp)"
    echo "torch==${torch_version}" >"$constraints"
    # --compile-bytecode, as pip does: where PYTHONDONTWRITEBYTECODE is set (CI machines,
    # containers), Python never caches what it compiles, and every process would compile
    # numpy, gymnasium and the rest from source at each import
    if "$bin/uv" pip install -q --compile-bytecode --python "$python" \
      --constraint "$constraints" "$@"; then
      rm -f "$constraints"
      return 0
    fi
    rm -f "$constraints"
    echo "setup: uv could not install the packages (above); installing them with pip" >&2
  fi
  "${pip[@]}" "torch==${torch_version}" "$@"
}

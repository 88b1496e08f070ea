#!/usr/bin/env bash
# colcon build of the workspace against the venv (wheels) or the sourced system Jazzy.
#   tools/colcon_build.sh VENV MODE
set -eo pipefail
VENV="$(cd "${1:?venv}" && pwd)"; MODE="${2:?mode}"
ROOT="$(cd "$(dirname "$0")/.." && pwd)"
cd "$ROOT"
set +u
if [ "$MODE" = wheels ]; then
  # AMENT_PREFIX_PATH must contain the venv at build time so install/setup.* chains to it.
  # shellcheck disable=SC1091
  . "$VENV/local_setup.sh"
else
  export VIRTUAL_ENV="$VENV" PATH="$VENV/bin:$PATH"
fi
# Standard interfaces the wheels lack (tf2_msgs, control_msgs) are built from
# src/upstream_interfaces in wheels mode only; a sourced system Jazzy provides the real ones,
# so there they are ignored and any copy left by an earlier wheels build is removed.
UPSTREAM_INTERFACES=(tf2_msgs control_msgs)
SELECT=()
if [ "$MODE" != wheels ]; then
  SELECT=(--packages-ignore "${UPSTREAM_INTERFACES[@]}")
  for pkg in "${UPSTREAM_INTERFACES[@]}"; do rm -rf "install/$pkg" "build/$pkg"; done
fi
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST ROS_LOG_DIR="$ROOT/build/ros_log"
export PYTHONWARNINGS="ignore::DeprecationWarning"
echo "setup: colcon build ($MODE mode)"
"$ROOT/tools/heartbeat.sh" "colcon build" "$VENV/bin/python" -m colcon --log-base build/colcon_log build --symlink-install "${SELECT[@]}" \
  --event-handlers console_cohesion- console_start_end+ summary+ status- \
  --cmake-args -DPython3_EXECUTABLE="$VENV/bin/python" -DBUILD_TESTING=OFF \
  2> >(grep -v -e 'byte-compiling is disabled' -e 'SetuptoolsDeprecationWarning' -e '^!!$' -e '^\s*\*\*\*' >&2)

# Source me (bash). Puts this shell into the workspace's ROS 2 environment, restricted to this host:
#  * sources install/setup.bash (which chains to the wheels venv or to the system Jazzy),
#  * ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST (never multicast on other interfaces),
#  * a private ROS_DOMAIN_ID, locked with flock for the life of this shell and its children
#    (parallel runs never share a domain); set SLIP_ROS_DOMAIN_ID to force one,
#  * ROS_LOG_DIR inside build/.
_slip_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
if [ ! -f "$_slip_root/install/setup.bash" ]; then
  echo "error: $_slip_root/install/setup.bash missing: run 'make setup' first" >&2
  return 1 2>/dev/null || exit 1
fi
set +u
# shellcheck disable=SC1091
. "$_slip_root/install/setup.bash"
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
unset ROS_LOCALHOST_ONLY ROS_STATIC_PEERS
export ROS_LOG_DIR="${ROS_LOG_DIR:-$_slip_root/build/ros_log}"
mkdir -p "$ROS_LOG_DIR"
if [ -n "${SLIP_ROS_DOMAIN_ID:-}" ]; then
  export ROS_DOMAIN_ID="$SLIP_ROS_DOMAIN_ID"
else
  _slip_lockdir="${TMPDIR:-/tmp}/slip_cell_ros_domains"
  mkdir -p "$_slip_lockdir"
  unset ROS_DOMAIN_ID
  # Linux-safe domain ids are 0..101; 0 is the default everyone else uses, so skip it.
  for _slip_id in $(shuf -i 1-101); do
    exec {_slip_fd}>"$_slip_lockdir/$_slip_id.lock"
    if flock -n "$_slip_fd"; then export ROS_DOMAIN_ID="$_slip_id"; break; fi
    exec {_slip_fd}>&-
  done
  if [ -z "${ROS_DOMAIN_ID:-}" ]; then
    echo "error: no free ROS_DOMAIN_ID in 1..101 (locks in $_slip_lockdir)" >&2
    return 1 2>/dev/null || exit 1
  fi
  unset _slip_lockdir _slip_id
fi
unset _slip_root

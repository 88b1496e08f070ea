#!/usr/bin/env bash
# Run a command inside the workspace's ROS 2 environment on a private, loopback-only domain.
#   tools/run_ros.sh python -m pytest ...
set -eo pipefail
# shellcheck disable=SC1091
. "$(cd "$(dirname "$0")" && pwd)/ros_env.sh"
echo "ros env: ROS_DOMAIN_ID=$ROS_DOMAIN_ID ROS_AUTOMATIC_DISCOVERY_RANGE=$ROS_AUTOMATIC_DISCOVERY_RANGE ROS_LOG_DIR=$ROS_LOG_DIR" >&2
exec "$@"

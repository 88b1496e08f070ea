#!/usr/bin/env bash
# Print "system" when a system ROS 2 Jazzy is sourced and its rclpy imports, else "wheels".
# SLIP_ROS_MODE=wheels|system overrides the detection.
if [ -n "${SLIP_ROS_MODE:-}" ]; then echo "$SLIP_ROS_MODE"; exit 0; fi
if [ "${ROS_DISTRO:-}" = jazzy ] && [ -z "${VIRTUAL_ENV:-}" ] && python3 -c 'import rclpy' >/dev/null 2>&1; then
  echo system
else
  echo wheels
fi

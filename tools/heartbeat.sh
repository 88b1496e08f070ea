#!/usr/bin/env bash
# Run a command and print a line every HEARTBEAT_S seconds (default 30) while it runs, so a
# long set-up step on a busy machine never looks hung. Exit status is the command's.
#   tools/heartbeat.sh [-o LOGFILE] LABEL CMD [ARG ...]   (-o: the command's output goes there)
set -uo pipefail
OUT=""
if [ "${1:-}" = -o ]; then OUT="$2"; shift 2; fi
LABEL="${1:?usage: heartbeat.sh [-o LOGFILE] LABEL CMD [ARG ...]}"; shift
PERIOD="${HEARTBEAT_S:-30}"
start=$(date +%s)
if [ -n "$OUT" ]; then "$@" >"$OUT" 2>&1 & else "$@" & fi
pid=$!
(
  while sleep "$PERIOD"; do
    kill -0 "$pid" 2>/dev/null || exit 0
    echo "setup: $LABEL still running ($(( $(date +%s) - start )) s)"
  done
) 2>/dev/null &   # a killed sleep would print "Terminated"
beat=$!
wait "$pid"
status=$?
# Stop the beat and its sleep (a sleep left behind would hold the caller's output pipe open).
pkill -P "$beat" 2>/dev/null
kill "$beat" 2>/dev/null
wait "$beat" 2>/dev/null
exit "$status"

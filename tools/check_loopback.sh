#!/usr/bin/env bash
# Run a command while capturing UDP and multicast on every non-loopback interface; report the
# packets seen (expected: 0). Needs tcpdump and root.   tools/check_loopback.sh make test
set -uo pipefail
ifaces=$(ls /sys/class/net | grep -v '^lo$')
dir=$(mktemp -d); pids=()
for i in $ifaces; do tcpdump -i "$i" -n -U -w "$dir/$i.pcap" 'udp or ip multicast or ip6 multicast' >/dev/null 2>&1 & pids+=($!); done
sleep 1
"$@"; rc=$?
sleep 1; kill "${pids[@]}" 2>/dev/null; wait 2>/dev/null
total=0
for i in $ifaces; do n=$(tcpdump -r "$dir/$i.pcap" -n 2>/dev/null | wc -l); echo "check_loopback: $i: $n UDP/multicast packets"; total=$((total + n)); done
rm -rf "$dir"
[ "$total" -eq 0 ] || { echo "check_loopback: FAIL, DDS traffic left loopback" >&2; exit 1; }
exit $rc

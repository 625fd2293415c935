#!/bin/sh
# Runs a command in a private network namespace with the loopback addresses the camera tests
# use (DESIGN.md section 8): `unshare -rn` (an unprivileged user + network namespace), lo up,
# 127.0.0.2 added beside 127.0.0.1, and SLS_TEST_NETNS=1 set. Each run gets its own UDP port
# 3956, so the fake cameras of tests running in parallel never meet.
# Where unprivileged user namespaces are not allowed (or `ip` is missing) the command runs as it
# is, without SLS_TEST_NETNS, and the camera tests report themselves skipped.
#   run_in_netns.sh COMMAND [ARGS...]
if unshare -rn true 2>/dev/null && command -v ip >/dev/null 2>&1; then
  exec unshare -rn sh -c 'ip link set lo up && ip addr add 127.0.0.2/8 dev lo && SLS_TEST_NETNS=1 exec "$@"' sh "$@"
fi
echo "run_in_netns: no private network namespace here (unshare -rn or ip missing); camera tests skip" >&2
exec "$@"

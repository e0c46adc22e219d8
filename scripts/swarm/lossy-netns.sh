#!/usr/bin/env bash
# Runs a command inside a fresh network namespace whose loopback drops a fraction of the UDP
# packets (the agents' mesh; the world's link is TCP and keeps every message), then removes the
# namespace. The kernel needs no netem: an nftables rule draws the loss per packet.
#
#   scripts/swarm/lossy-netns.sh PERCENT -- edgekf swarm SCENARIO --out DIR --lossy \
#       --after-ready "$PWD/scripts/swarm/lossy-netns.sh --rule PERCENT"
#
# The rule goes in once every agent is ready (`--after-ready`): Zenoh's declarations travel on
# the mesh too, and a declaration lost at start-up would silence a link for the whole run.
# Needs root (or CAP_NET_ADMIN), `ip` (iproute2) and `nft` (Debian: nftables).
set -euo pipefail
if [ "${1:-}" = "--rule" ]; then
  pct="$2"
  nft -f - <<NFT
table inet edgekf_loss {
  chain input {
    type filter hook input priority 0; policy accept;
    meta l4proto udp numgen random mod 100 < $pct drop
  }
}
NFT
  exit 0
fi
pct="${1:?usage: lossy-netns.sh PERCENT -- COMMAND...}"
shift
[ "${1:-}" = "--" ] && shift
case "$pct" in
  ''|*[!0-9]*) echo "lossy-netns.sh: PERCENT must be an integer 0..100, got '$pct'" >&2; exit 2 ;;
esac
if [ "$pct" -gt 100 ]; then
  echo "lossy-netns.sh: PERCENT must be at most 100, got $pct" >&2; exit 2
fi
for tool in ip nft; do
  if ! command -v "$tool" >/dev/null 2>&1; then
    echo "lossy-netns.sh: \`$tool\` is missing (Debian: iproute2, nftables)" >&2; exit 3
  fi
done
ns="edgekf-loss-$$"
if ! ip netns add "$ns" 2>/tmp/edgekf-netns-err.$$; then
  echo "lossy-netns.sh: cannot create a network namespace ($(cat /tmp/edgekf-netns-err.$$)): run as root, on a kernel with namespaces" >&2
  rm -f /tmp/edgekf-netns-err.$$
  exit 3
fi
rm -f /tmp/edgekf-netns-err.$$
trap 'ip netns del "$ns" 2>/dev/null || true' EXIT
ip -n "$ns" link set lo up
ip netns exec "$ns" "$@"

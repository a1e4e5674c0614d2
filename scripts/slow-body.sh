#!/usr/bin/env bash
# The slow-body measurement of docs/server.md (issue 46): serve_connections with the demo study
# and `mrstudy serve`'s default connection settings, in-process on loopback; slow clients each
# send a join with `Content-Length: 16000` and then 10 bytes every 2 s, while a control client
# asks GET /api/studies on a new connection every 20 ms. Prints the control client's p50/p99/max
# and how long the slow connections were kept; fails if one outlived the deadline.
#
#   scripts/slow-body.sh                 # 2 000 slow connections from 20 addresses 127.0.0.2-21
#   SLOW_ADDRESSES=1 scripts/slow-body.sh             # all from one address (the cap per address)
#   SLOW_CONNECTIONS=4200 scripts/slow-body.sh        # more than --max-connections (4 096)
#
# Needs a file-descriptor limit above twice the connections (ulimit -n).
set -euo pipefail
cd "$(dirname "$0")/.."
cargo test -p mrstudy-server --test connections -- --ignored --nocapture slow_body_attack_under_load

#!/usr/bin/env bash
# The server benchmark of bench/README.md: `mrstudy bench server` on sqlite (one process) and on a
# throw-away PostgreSQL cluster (scripts/postgres.sh) with one and with two server processes,
# 16/64/256 participants and 8 concurrent exports; the JSON of each goes to DIR (default
# bench-server/). Needs Debian's `postgresql` package (scripts/test.sh installs it).
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-bench-server}
mkdir -p "$out"
cargo build --release --locked --bin mrstudy
source scripts/postgres.sh
start_postgres
mrstudy=target/release/mrstudy
"$mrstudy" bench server --database sqlite --json "$out/sqlite-1.json"
"$mrstudy" bench server --database "$POSTGRES_URL" --processes 1 --json "$out/postgres-1.json"
"$mrstudy" bench server --database "$POSTGRES_URL" --processes 2 --json "$out/postgres-2.json"

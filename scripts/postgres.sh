# Sourced by scripts/test.sh and scripts/bench-server.sh: `start_postgres` starts a throw-away
# PostgreSQL cluster on a free loopback port (as the `postgres` user when run as root: initdb
# refuses root), trusting loopback connections only, sets POSTGRES_URL to its server URL
# (the database `postgres`) and stops and removes it when the shell exits. Needs Debian's
# `postgresql` package (/usr/lib/postgresql/*/bin).
start_postgres() {
  pg_bin=$(ls -d /usr/lib/postgresql/*/bin | sort -V | tail -n 1)
  pg_dir=$(mktemp -d /tmp/mrstudy-postgres.XXXXXX)
  local port
  port=$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
  as_owner=()
  if [[ $(id -u) -eq 0 ]]; then
    chown postgres "$pg_dir"
    as_owner=(runuser -u postgres --)
  fi
  trap stop_postgres EXIT
  "${as_owner[@]}" "$pg_bin/initdb" -D "$pg_dir/data" -U mrstudy -A trust >/dev/null
  "${as_owner[@]}" "$pg_bin/pg_ctl" -D "$pg_dir/data" -l "$pg_dir/log" -w \
    -o "-p $port -k $pg_dir -c listen_addresses=127.0.0.1 -c max_connections=300" start >/dev/null
  POSTGRES_URL="postgres://mrstudy@127.0.0.1:$port/postgres"
  echo "PostgreSQL $("$pg_bin/postgres" --version | awk '{print $3}') on 127.0.0.1:$port" >&2
}

stop_postgres() {
  "${as_owner[@]}" "$pg_bin/pg_ctl" -D "$pg_dir/data" -m immediate stop >/dev/null 2>&1 || true
  rm -rf "$pg_dir"
}

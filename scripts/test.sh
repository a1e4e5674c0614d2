#!/usr/bin/env bash
# Runs every test of the workspace on a fresh machine: installs the system packages the tests
# need (when run as root on Debian), checks the house style (rustfmt, clippy with -D warnings,
# rustdoc with -D warnings), starts a throw-away PostgreSQL cluster on a free loopback port,
# then `cargo test` over the whole workspace, and the server's router and end-to-end suites a
# second time against PostgreSQL. The cluster is stopped and removed on exit.
set -euo pipefail
cd "$(dirname "$0")/.."

need=()
# Packages the tests use; each line: a command or file that shows it is installed, then the package.
while read -r probe package; do
  [[ -z "$probe" ]] && continue
  if [[ "$probe" == /* ]]; then [[ -e "$probe" ]] || need+=("$package")
  else command -v "$probe" >/dev/null 2>&1 || need+=("$package"); fi
done <<'LIST'
chromium chromium
chromedriver chromium-driver
/usr/share/vulkan/icd.d/lvp_icd.x86_64.json mesa-vulkan-drivers
/usr/lib/postgresql postgresql
LIST

if ((${#need[@]})); then
  if [[ $(id -u) -eq 0 ]] && command -v apt-get >/dev/null; then
    echo "installing: ${need[*]}" >&2
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${need[@]}" >/dev/null
  else
    echo "missing system packages: ${need[*]} (install them, or run this script as root on Debian)" >&2
    exit 1
  fi
fi

# The house style (rustfmt.toml, [workspace.lints] in Cargo.toml). rustfmt and clippy come
# with the Rust toolchain's default profile; where a toolchain lacks them, rustup adds them.
for component in rustfmt clippy; do
  tool=$([[ $component == rustfmt ]] && echo fmt || echo clippy)
  if ! cargo "$tool" --version >/dev/null 2>&1; then
    rustup component add "$component" >/dev/null 2>&1 || { echo "cannot install the toolchain component $component: the style check needs it" >&2; exit 1; }
  fi
done
echo "style: cargo fmt --check" >&2
cargo fmt --all --check
echo "style: cargo clippy --workspace --all-targets -- -D warnings" >&2
cargo clippy --workspace --all-targets --locked -- -D warnings
echo "style: cargo doc --no-deps (warnings are errors)" >&2
RUSTDOCFLAGS="-D warnings" cargo doc --workspace --no-deps --locked

# A PostgreSQL of our own, as an unprivileged user (initdb refuses root): trust on loopback only.
pg_bin=$(ls -d /usr/lib/postgresql/*/bin | sort -V | tail -n 1)
pg_dir=$(mktemp -d /tmp/mrstudy-postgres.XXXXXX)
pg_port=$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
as_owner=()
if [[ $(id -u) -eq 0 ]]; then
  chown postgres "$pg_dir"
  as_owner=(runuser -u postgres --)
fi
stop_postgres() {
  "${as_owner[@]}" "$pg_bin/pg_ctl" -D "$pg_dir/data" -m immediate stop >/dev/null 2>&1 || true
  rm -rf "$pg_dir"
}
trap stop_postgres EXIT
"${as_owner[@]}" "$pg_bin/initdb" -D "$pg_dir/data" -U mrstudy -A trust >/dev/null
"${as_owner[@]}" "$pg_bin/pg_ctl" -D "$pg_dir/data" -l "$pg_dir/log" -w \
  -o "-p $pg_port -k $pg_dir -c listen_addresses=127.0.0.1 -c max_connections=300" start >/dev/null
export MRSTUDY_TEST_POSTGRES="postgres://mrstudy@127.0.0.1:$pg_port/postgres"
echo "PostgreSQL $("$pg_bin/postgres" --version | awk '{print $3}') for the tests on 127.0.0.1:$pg_port" >&2

cargo test --workspace --locked "$@"

# The serving suites again, each test on a new PostgreSQL database (not when a filter was given).
if (($# == 0)); then
  echo "the router and serving end-to-end tests against PostgreSQL" >&2
  MRSTUDY_TEST_DATABASE=postgres cargo test --locked -p mrstudy-server \
    --test router --test active --test hardening --test admin_participants
  MRSTUDY_TEST_DATABASE=postgres cargo test --locked --test e2e -- serve:: serve_durability admin::
fi

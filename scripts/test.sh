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

# A PostgreSQL of our own, as an unprivileged user: trust on loopback only (scripts/postgres.sh).
source scripts/postgres.sh
start_postgres
export MRSTUDY_TEST_POSTGRES="$POSTGRES_URL"

cargo test --workspace --locked "$@"

# The serving suites again, each test on a new PostgreSQL database (not when a filter was given).
if (($# == 0)); then
  echo "the router and serving end-to-end tests against PostgreSQL" >&2
  MRSTUDY_TEST_DATABASE=postgres cargo test --locked -p mrstudy-server \
    --test router --test active --test hardening --test admin_participants --test lab_ws --test rating
  MRSTUDY_TEST_DATABASE=postgres cargo test --locked --test e2e -- serve:: serve_durability admin:: lab::three_participants
fi

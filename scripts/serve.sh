#!/usr/bin/env bash
# The main job on a fresh machine: `bash scripts/serve.sh [serve flags]`. Installs what `serve`
# needs to render the studies' stimuli when it is missing and this runs as root on Debian (Mesa's
# Vulkan drivers, `mesa-vulkan-drivers`: the software adapter for a machine without a GPU), else
# says in one sentence what to install and stops; then builds and runs
# `cargo run --release -- serve "$@"`, which it stays equivalent to once the package is there.
# Nothing that only the tests need is installed here (that is scripts/test.sh).
#
# MRSTUDY_VULKAN_PROBE: the file that shows the drivers are installed (default: lavapipe's ICD);
# MRSTUDY_NO_INSTALL=1: never install, even as root (the script's test sets both);
# MRSTUDY_ADAPTER=hardware (the renderer's own switch): skip the check on a machine with a GPU.
set -euo pipefail
cd "$(dirname "$0")/.."

probe="${MRSTUDY_VULKAN_PROBE:-/usr/share/vulkan/icd.d/lvp_icd.x86_64.json}"
if [[ ! -e "$probe" && "${MRSTUDY_ADAPTER:-}" != hardware ]]; then
  if [[ $(id -u) -eq 0 && -z "${MRSTUDY_NO_INSTALL:-}" ]] && command -v apt-get >/dev/null; then
    echo "installing: mesa-vulkan-drivers (Mesa's Vulkan drivers, to render stimuli without a GPU)" >&2
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends mesa-vulkan-drivers >/dev/null
  else
    echo "mrstudy serve needs Mesa's Vulkan drivers to render the studies' stimuli ($probe is missing): install them with \`apt-get install mesa-vulkan-drivers\` as root, run this script as root on Debian, or set MRSTUDY_ADAPTER=hardware on a machine with a GPU." >&2
    exit 1
  fi
fi

# wgpu's adapter probe asks libwayland for a display, which complains on stderr when
# XDG_RUNTIME_DIR is unset (a service or a fresh ssh session): give it a private one.
if [[ -z "${XDG_RUNTIME_DIR:-}" ]]; then
  XDG_RUNTIME_DIR="${TMPDIR:-/tmp}/mrstudy-runtime-$(id -u)"
  mkdir -p -m 700 "$XDG_RUNTIME_DIR"
  export XDG_RUNTIME_DIR
fi

exec cargo run --release --locked -- serve "$@"

#!/usr/bin/env bash
# The GPU pipeline's frame rate at the thesis's setting (1024×768, 256 VPLs, 128² ISMs of 1024
# points, 512² caustic maps) on a machine with a hardware GPU but no Rust toolchain and no
# network — the `device` machines lent to some development sessions.
#
# Prepare here (the machine with the toolchain), then carry `.gpu-run` to the GPU machine:
#   bash scripts/gpu-frame-rate.sh --prepare
# On the GPU machine, from the repository root (results under $OUT, or ./gpu-frame-rate):
#   bash scripts/gpu-frame-rate.sh [--quick] [--scene NAME]
#
# --prepare builds the release binary, strips and compresses it into .gpu-run/mrstudy.gz and
# downloads the Vulkan loader's Debian package into .gpu-run/ (the GPU machine's driver brings
# its own ICD, not always the loader). The run unpacks both, prints the adapter, and writes
# `bench render --frame-rate`'s table, its JSON (timed, pipelined and live series, each pass's
# wall-clock and GPU time) and the log.
set -euo pipefail
cd "$(dirname "$0")/.."
run_dir=.gpu-run

if [[ "${1:-}" == "--prepare" ]]; then
    mkdir -p "$run_dir"
    cargo build --release -p mrstudy
    strip -o "$run_dir/mrstudy" target/release/mrstudy
    gzip -f "$run_dir/mrstudy"
    (cd "$run_dir" && rm -f ./*.deb && apt-get download libvulkan1)
    ls -l "$run_dir"
    echo "carry $run_dir (it is ignored by git) and run: bash scripts/gpu-frame-rate.sh"
    exit 0
fi

out="${OUT:-gpu-frame-rate}"
mkdir -p "$out"
if [[ ! -f "$run_dir/mrstudy.gz" ]]; then
    echo "error: $run_dir/mrstudy.gz is missing; run 'bash scripts/gpu-frame-rate.sh --prepare' on the build machine and carry $run_dir" >&2
    exit 1
fi
bin=/tmp/mrstudy-gpu-run
gunzip -c "$run_dir/mrstudy.gz" > "$bin"
chmod +x "$bin"
if ! ldconfig -p | grep -q 'libvulkan.so.1'; then
    shopt -s nullglob
    debs=("$run_dir"/libvulkan1_*.deb)
    if [[ ${#debs[@]} -eq 0 ]]; then
        echo "error: no Vulkan loader on this machine and no libvulkan1 package in $run_dir" >&2
        exit 1
    fi
    mkdir -p /tmp/vulkan-loader
    dpkg -x "${debs[0]}" /tmp/vulkan-loader
    export LD_LIBRARY_PATH="/tmp/vulkan-loader/usr/lib/x86_64-linux-gnu:${LD_LIBRARY_PATH:-}"
fi
if command -v nvidia-smi > /dev/null; then
    nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv,noheader | tee "$out/gpu.txt"
fi
"$bin" bench render --frame-rate "$@" --json "$out/render_frame_rate.json" 2>&1 | tee "$out/log.txt"

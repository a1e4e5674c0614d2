#!/usr/bin/env bash
# The ISM pass splatted by the compute pass and by the rasteriser, side by side: single gi
# frames at 1024×768 (`mrstudy render --spp 1`), the splattings alternating, over the points per
# cloud and the tile size, two repeats each; prints each run's ISM pass time.
#   bash scripts/ism-splatting.sh [BINARY] > renderer/bench/render_ism_splatting_lavapipe.txt
set -euo pipefail
cd "$(dirname "$0")/.."
bin="${1:-target/release/mrstudy}"
out=$(mktemp -d)
for scene in dir-lamp-box glass-figure; do
    for points in 256 1024; do
        for size in 32 128; do
            for rep in 1 2; do
                for splatting in compute raster; do
                    line=$("$bin" render --scene "$scene" --condition gi --spp 1 --size 1024x768 \
                        --ism-points "$points" --ism-size "$size" --ism-splatting "$splatting" \
                        --out "$out/frame.exr" 2>&1 | grep -E '^ +ISMs' | sed -E 's/^ +//; s/ +/ /g')
                    echo "$scene rep $rep: $line"
                done
            done
        done
    done
done
rm -rf "$out"

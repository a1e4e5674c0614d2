#!/usr/bin/env bash
# Makes docs/img/overview.svg, the README's picture: a stimulus pair of the web survey
# (survey-1 as LQ, every factor off, and as HQ, gi + cm + ca) rendered by `mrstudy render`,
# beside the worth plot `mrstudy analyze --plot` draws for a simulated study of the web
# survey's eight conditions (40 participants, every pair once each, Bradley–Terry judgments
# with the thesis's effects gi 0.27, cm -0.22, ca 0.43; seed 1).
# Usage: bash docs/img/make-overview.sh [path/to/mrstudy]   (default: target/release/mrstudy)
set -euo pipefail
cd "$(dirname "$0")/../.."
mrstudy=${1:-target/release/mrstudy}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

"$mrstudy" render --scene survey-1 --condition none --size 240x180 --spp 64 --out "$tmp/lq.png"
"$mrstudy" render --scene survey-1 --factors gi,cm,ca --size 240x180 --spp 64 --out "$tmp/hq.png"

python3 - "$tmp" <<'PY'
import itertools, math, random, sys
tmp = sys.argv[1]
conditions = {"LQ": (0, 0, 0), "GI": (1, 0, 0), "CM": (0, 1, 0), "CA": (0, 0, 1),
              "GI+CM": (1, 1, 0), "GI+CA": (1, 0, 1), "CM+CA": (0, 1, 1), "HQ": (1, 1, 1)}
effects = (0.27, -0.22, 0.43)
log_worth = {name: sum(e * l for e, l in zip(effects, levels)) for name, levels in conditions.items()}
rng = random.Random(1)
with open(f"{tmp}/trials.csv", "w") as out:
    out.write("participant,left,right,chosen\n")
    for participant in range(1, 41):
        for left, right in itertools.combinations(conditions, 2):
            if rng.random() < 0.5:
                left, right = right, left
            p_left = 1 / (1 + math.exp(-(log_worth[left] - log_worth[right])))
            chosen = left if rng.random() < p_left else right
            out.write(f"p{participant},{left},{right},{chosen}\n")
with open(f"{tmp}/conditions.csv", "w") as out:
    out.write("condition,gi,cm,ca\n")
    for name, levels in conditions.items():
        out.write(name + "," + ",".join(map(str, levels)) + "\n")
PY
"$mrstudy" analyze --trials "$tmp/trials.csv" --conditions "$tmp/conditions.csv" --plot "$tmp/worth.svg" >/dev/null

python3 - "$tmp" docs/img/overview.svg <<'PY'
import base64, re, sys
tmp, out = sys.argv[1], sys.argv[2]
def png(name):
    return base64.b64encode(open(f"{tmp}/{name}.png", "rb").read()).decode()
worth = open(f"{tmp}/worth.svg").read()
worth = re.sub(r"<\?xml[^>]*\?>\s*", "", worth)
tag = re.search(r"<svg\b[^>]*>", worth).group(0)
box = re.search(r'viewBox="([^"]*)"', tag)
if box:
    width, height = map(float, box.group(1).split()[2:])
else:
    width = float(re.search(r'\bwidth="([\d.]+)', tag).group(1))
    height = float(re.search(r'\bheight="([\d.]+)', tag).group(1))
scale = 200 / height
bare = re.sub(r'\s(width|height|viewBox|x|y)="[^"]*"', "", tag)
worth = worth.replace(tag, bare.replace("<svg", f'<svg x="500" y="10" width="{width * scale:.0f}" '
                                      f'height="200" viewBox="0 0 {width:g} {height:g}"', 1), 1)
total = 500 + width * scale + 10
font = 'font-family="sans-serif" font-size="13" text-anchor="middle"'
svg = f'''<svg xmlns="http://www.w3.org/2000/svg" xmlns:xlink="http://www.w3.org/1999/xlink" width="{total:.0f}" height="220" viewBox="0 0 {total:.0f} 220">
<rect width="100%" height="100%" fill="white"/>
<image x="10" y="10" width="240" height="180" xlink:href="data:image/png;base64,{png("lq")}"/>
<image x="250" y="10" width="240" height="180" xlink:href="data:image/png;base64,{png("hq")}"/>
<text x="130" y="208" {font}>LQ</text>
<text x="370" y="208" {font}>HQ (gi + cm + ca)</text>
{worth}
</svg>
'''
open(out, "w").write(svg)
PY
echo "wrote docs/img/overview.svg ($(wc -c < docs/img/overview.svg) bytes)"

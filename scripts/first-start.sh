#!/usr/bin/env bash
# Measures a first start of `mrstudy serve` on a fresh data directory (issue 47):
#   - the time from launching the process to its first accepted TCP connection, and to its first
#     answer of GET /api/studies;
#   - the time until each study of the studies directory is open (a survey study: listed by
#     GET /api/studies; a lab task study: GET /lab/<slug> answers 200), and until all are.
# A study the server does not serve (a warning line naming it) is reported and not waited for.
#
# Usage: scripts/first-start.sh [BINARY] [STUDIES_DIR]
#   BINARY       default target/release/mrstudy (build it with `cargo build --release --locked`)
#   STUDIES_DIR  default studies/ (the default studies)
# Environment: FIRST_START_TIMEOUT (seconds to wait for every study, default 3600),
#   FIRST_START_KEEP=1 keeps the data directory and the server's output (their path is printed).
# Prints one line per measurement; the server's stdout and stderr are kept beside the data.
set -euo pipefail

cd "$(dirname "$0")/.."
binary=${1:-target/release/mrstudy}
studies=${2:-studies}
timeout=${FIRST_START_TIMEOUT:-3600}
[[ -x $binary ]] || { echo "no executable $binary: build it first (cargo build --release --locked)" >&2; exit 1; }

work=$(mktemp -d "${TMPDIR:-/tmp}/mrstudy-first-start.XXXXXX")
port=$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
base="http://127.0.0.1:$port"

# the studies to wait for: slug and whether it is a lab task study
declare -A task
slugs=()
for file in "$studies"/*.toml; do
    slug=$(sed -n 's/^slug *= *"\(.*\)".*/\1/p' "$file" | head -n 1)
    [[ -n $slug ]] || continue
    slugs+=("$slug")
    if grep -q '^kind *= *"task"' "$file"; then task[$slug]=1; else task[$slug]=0; fi
done

now() { date +%s.%N; }
since() { awk -v a="$1" -v b="$(now)" 'BEGIN { printf "%.2f", b - a }'; }

start=$(now)
"$binary" serve --addr "127.0.0.1:$port" --data-dir "$work/data" --studies "$studies" \
    >"$work/stdout.log" 2>"$work/stderr.log" &
server=$!
cleanup() {
    kill "$server" 2>/dev/null && wait "$server" 2>/dev/null || true
    if [[ ${FIRST_START_KEEP:-0} == 1 ]]; then echo "kept: $work"; else rm -rf "$work"; fi
}
trap cleanup EXIT

echo "mrstudy first start: $binary, studies in $studies, $(nproc) CPU cores, fresh data directory"
until (exec 3<>"/dev/tcp/127.0.0.1/$port") 2>/dev/null; do
    kill -0 "$server" 2>/dev/null || { echo "the server stopped:" >&2; cat "$work/stderr.log" >&2; exit 1; }
    sleep 0.02
done
echo "first accepted connection: $(since "$start") s"
until curl -sf -o /dev/null "$base/api/studies"; do sleep 0.02; done
echo "first answer of GET /api/studies: $(since "$start") s"

declare -A done_at
left=${#slugs[@]}
while ((left > 0)); do
    listed=$(curl -sf "$base/api/studies" || true)
    for slug in "${slugs[@]}"; do
        [[ -z ${done_at[$slug]:-} ]] || continue
        if [[ ${task[$slug]} == 1 ]]; then
            [[ $(curl -s -o /dev/null -w '%{http_code}' "$base/lab/$slug") == 200 ]] && open=1 || open=0
        else
            [[ $listed == *"\"slug\":\"$slug\""* ]] && open=1 || open=0
        fi
        if ((open)); then
            done_at[$slug]=$(since "$start")
            echo "study \"$slug\" open: ${done_at[$slug]} s"
            left=$((left - 1))
        elif grep -q "^warning: .*\"$slug\".*not served\|^warning: .*\"$slug\".*not serving it" "$work/stderr.log"; then
            done_at[$slug]=never
            echo "study \"$slug\" not served: $(grep -m 1 "\"$slug\"" "$work/stderr.log")"
            left=$((left - 1))
        fi
    done
    if ((left > 0)); then
        if [[ $(since "$start" | cut -d. -f1) -ge $timeout ]]; then
            echo "gave up after $timeout s with $left studies not open" >&2
            exit 1
        fi
        sleep 1
    fi
done
echo "every study open (or reported not served): $(since "$start") s"

#!/usr/bin/env bash
# Load test of the server (issue 5's bars), with wrk (Debian's package) on this machine:
#   1. LOD on demand for the 8,431-vertex horse at random frames and budgets, 64 connections,
#      closed loop (wrk: each connection sends its next request when the last answer arrives,
#      so this measures throughput, and latency is 64 / throughput);
#   2. the same, and the 7,207-vertex cat, open loop at fixed offered rates (oha -q with its
#      coordinated-omission correction: latency at a stated load);
#   3. range requests for random chunks of its container, 64 connections;
#   4. bytes a playback client downloads for the whole sequence at 10% of the triangles,
#      beside a full-resolution client.
# Usage: crates/pmcodec-server/loadtest/run.sh [seconds per run, default 20]
# Installs wrk (apt) and oha (cargo install, a few minutes the first time) when missing.
#
# Soak (issue 13): crates/pmcodec-server/loadtest/run.sh soak [seconds, default 600]
#   64 connections of mixed traffic for the whole time: LOD on demand at random frames and
#   budgets (wrk: 24 on the horse, 8 on the cat), range requests for random chunks (wrk, 24),
#   8 slow clients (soak.py: 4 KiB receive buffers read 1 KiB per 20 ms, request heads sent in
#   pieces), and an upload of 8 OBJ frames every 15 s polled to its job's end; the server's
#   VmRSS every 10 s into $SOAK_OUT/rss.tsv (default /tmp/pmcodec-soak-DATE); then errors per
#   client, the decode metrics, and RSS over time with its trend after a 60 s warm-up.
set -euo pipefail
cd "$(dirname "$0")/../../.."
mode=bench
if [ "${1:-}" = soak ]; then
  mode=soak
  secs=${2:-600}
else
  secs=${1:-20}
fi
export LOADTEST_DIR=crates/pmcodec-server/loadtest
command -v wrk >/dev/null || { apt-get update -qq && apt-get install -y -qq wrk >/dev/null; }
[ $mode = soak ] || command -v oha >/dev/null || cargo install oha@1.16.0 --locked -q
cargo build --release --locked -q -p pmcodec
bin=target/release/pmcodec
work=$(mktemp -d)
trap 'kill $server 2>/dev/null || true; rm -rf "$work"' EXIT
mkdir -p "$work/assets"
$bin encode ../shared/data/horse-gallop -o "$work/assets/horse.pmc" --quiet
$bin encode ../shared/data/cat-poses -o "$work/assets/cat.pmc" --quiet
port=${LOADTEST_PORT:-18480}
# Uploads need a write token; only the soak uploads.
[ $mode = soak ] && export PMCODEC_WRITE_TOKEN="soak-$RANDOM$RANDOM"
$bin serve --assets "$work/assets" --listen 127.0.0.1:$port --no-viewer --quiet &
server=$!
for _ in $(seq 100); do curl -fs http://127.0.0.1:$port/readyz >/dev/null && break; sleep 0.1; done
base=http://127.0.0.1:$port
info=$(curl -fs $base/v1/assets/horse)
file=$(echo "$info" | python3 -c 'import json,sys; print(json.load(sys.stdin)["file"])')
index=$(echo "$info" | python3 -c 'import json,sys; print(json.load(sys.stdin)["index"])')
curl -fs "$base$index" | python3 -c 'import json,sys
for c in json.load(sys.stdin)["chunks"]: print(c["offset"], c["length"])' > "$work/chunks.txt"

if [ $mode = soak ]; then
  out=${SOAK_OUT:-/tmp/pmcodec-soak-$(date -u +%Y%m%d-%H%M%S)}
  mkdir -p "$out"
  echo "== soak: ${secs}s, 64 connections: LOD horse 24 + cat 8, chunk ranges 24, 8 slow clients, an upload every 15 s; output in $out"
  # Sampling goes on for 30 s after the load stops: what the server holds when idle again.
  python3 $LOADTEST_DIR/soak.py rss $server $((secs + 30)) "$out/rss.tsv" &
  sampler=$!
  pids=()
  ASSET=horse FRAMES=48 wrk -t1 -c24 -d${secs}s --timeout 10s --latency -s $LOADTEST_DIR/lod.lua $base > "$out/lod-horse.txt" &
  pids+=($!)
  ASSET=cat FRAMES=10 MAX_TRIS=14410 wrk -t1 -c8 -d${secs}s --timeout 10s --latency -s $LOADTEST_DIR/lod.lua $base > "$out/lod-cat.txt" &
  pids+=($!)
  FILE=$file CHUNKS=$work/chunks.txt wrk -t1 -c24 -d${secs}s --timeout 10s --latency -s $LOADTEST_DIR/chunks.lua $base > "$out/chunks.txt" &
  pids+=($!)
  python3 $LOADTEST_DIR/soak.py slow $base $secs 8 "$file" > "$out/slow.txt" 2> "$out/slow.err" &
  pids+=($!)
  python3 $LOADTEST_DIR/soak.py uploads $base $secs ../shared/data/horse-gallop > "$out/uploads.txt" 2> "$out/uploads.err" &
  pids+=($!)
  wait "${pids[@]}"
  wait $sampler
  for f in lod-horse lod-cat chunks; do
    echo "-- $f"
    grep -E "requests in|Requests/sec|non-2xx|p50|p99:" "$out/$f.txt"
  done
  cat "$out/slow.txt" "$out/uploads.txt"
  head -n 5 "$out/slow.err" "$out/uploads.err"
  curl -fs $base/metrics | grep -E "^pmcodec_(decode_|jobs_finished)" | tee "$out/metrics.txt"
  python3 $LOADTEST_DIR/soak.py summary "$out/rss.tsv" 60 $secs | tee "$out/rss-summary.txt"
  exit 0
fi

echo "== warm-up (decoder states for every keyframe interval)"
ASSET=horse FRAMES=48 wrk -t2 -c8 -d3s -s crates/pmcodec-server/loadtest/lod.lua $base >/dev/null
echo "== LOD on demand: horse, random frame 0..47, random budget 200..16000 triangles, 64 connections, ${secs}s"
ASSET=horse FRAMES=48 wrk -t2 -c64 -d${secs}s --latency -s crates/pmcodec-server/loadtest/lod.lua $base | tee "$work/lod.txt"
# What the same connections get from bytes already in memory, at the LOD answers' mean size: the
# ceiling that transfer alone (server writes, wrk reads, both on these cores) puts on LOD latency.
mean=$(python3 - "$work/lod.txt" <<'P'
import re, sys
t = open(sys.argv[1]).read()
n, size, unit = re.search(r"(\d+) requests in [\d.]+\w+, ([\d.]+)(\w+) read", t).groups()
scale = {"B": 1, "KB": 2**10, "MB": 2**20, "GB": 2**30}[unit]
print(int(float(size) * scale / int(n)))
P
)
echo "== transfer ceiling: a ${mean}-byte range of the container (the mean LOD answer), 64 connections, ${secs}s"
wrk -t2 -c64 -d${secs}s --latency -H "Range: bytes=0-$((mean - 1))" -s crates/pmcodec-server/loadtest/report.lua "$base$file"
# Open loop: random (frame, budget) URLs, 64 connections, requests sent at a fixed rate whether
# or not earlier answers came back.
open_loop() { # asset frames max_triangles rates...
  local asset=$1 frames=$2 max=$3; shift 3
  python3 - "$base" "$asset" "$frames" "$max" > "$work/urls-$asset.txt" <<'P'
import random, sys
base, asset, frames, top = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
random.seed(1)
for _ in range(20000):
    print(f"{base}/v1/assets/{asset}/mesh?frame={random.randint(0, frames - 1)}&triangles={random.randint(200, top)}&format=bin")
P
  oha -z 3s -c 8 --no-tui --urls-from-file "$work/urls-$asset.txt" >/dev/null
  for rate in "$@"; do
    oha -z ${secs}s -c 64 -q "$rate" --latency-correction --no-tui --output-format json \
      --urls-from-file "$work/urls-$asset.txt" > "$work/oha.json"
    python3 - "$work/oha.json" "$asset" "$rate" <<'P'
import json, sys
d = json.load(open(sys.argv[1]))
s, p = d["summary"], d["latencyPercentiles"]
# "aborted due to deadline": requests still in flight when the run's time ran out.
errors = {k: v for k, v in d["errorDistribution"].items() if k != "aborted due to deadline"}
codes = d["statusCodeDistribution"]
print(f"{sys.argv[2]} at {sys.argv[3]} req/s offered: {s['requestsPerSec']:.0f} req/s, p50 {p['p50']*1e3:.2f} ms, "
      f"p99 {p['p99']*1e3:.2f} ms, p99.9 {p['p99.9']*1e3:.2f} ms, status {codes}, errors {errors or 0}")
P
  done
}
echo "== LOD on demand, open loop, 64 connections, ${secs}s per rate"
open_loop horse 48 16000 1000 2000 3000 4000
open_loop cat 10 14410 2000 3000 4000 5000
echo "== chunk range requests: random chunk of the horse's container, 64 connections, ${secs}s"
FILE=$file CHUNKS=$work/chunks.txt wrk -t2 -c64 -d${secs}s --latency -s crates/pmcodec-server/loadtest/chunks.lua $base
echo "== playback: bytes downloaded for the whole sequence"
full=$($bin play $base --asset horse --triangles 16843 --json --quiet | tail -n 1)
tenth=$($bin play $base --asset horse --triangles 1684 --json | tail -n 1)
python3 - "$full" "$tenth" <<'P'
import json, sys
full, tenth = json.loads(sys.argv[1]) if sys.argv[1] else None, json.loads(sys.argv[2])
print(f"10% client (budget {tenth['budget']}, level >= {tenth['level']}): {tenth['bytes_downloaded']} bytes, "
      f"{tenth['share_of_file']*100:.1f}% of the file, mean decode {tenth['mean_decode_ms']:.3f} ms/frame")
if full:
    print(f"full-resolution client: {full['bytes_downloaded']} bytes; 10% client downloads "
          f"{tenth['bytes_downloaded']/full['bytes_downloaded']*100:.1f}% of that")
P

#!/usr/bin/env bash
# The server's memory with large uploads queued behind a slow encode job (issue 13): five
# 100 MB bodies wait in temporary files, not in memory, and a full queue refuses at once.
# Not part of the test run (it moves half a gigabyte); prints RSS before and after.
#   tests/system/queued-uploads-rss.sh [path/to/pmcodec]
set -euo pipefail
cd "$(dirname "$0")/../.."
bin="${1:-target/release/pmcodec}"
port=18181
base="http://127.0.0.1:$port"
work="$(mktemp -d)"
mkdir -p "$work/assets" "$work/up"
# Six places in the job queue: the slow job and five uploads fill it.
PMCODEC_WRITE_TOKEN=t PMCODEC_MAX_PENDING_JOBS=6 PMCODEC_LOG=warn "$bin" -q serve --assets "$work/assets" --listen "127.0.0.1:$port" \
  --upload-dir "$work/up" --no-viewer &
pid=$!
trap 'kill "$pid" 2>/dev/null; rm -rf "$work"' EXIT
for _ in $(seq 100); do curl -sf "$base/readyz" >/dev/null && break; sleep 0.1; done
rss() { awk '/VmRSS/ {printf "%.0f MB", $2 / 1024}' "/proc/$pid/status"; }
echo "RSS at start: $(rss)"
# The slow job: the horse gallop four times over (192 frames of 8,431 vertices).
python3 - "$work/slow.zip" <<'PY'
import sys, zipfile, glob
frames = sorted(glob.glob("../shared/data/horse-gallop/*.obj"))
with zipfile.ZipFile(sys.argv[1], "w", zipfile.ZIP_DEFLATED, compresslevel=1) as z:
    for k in range(4):
        for i, f in enumerate(frames):
            z.write(f, f"f{k * len(frames) + i:04d}.obj")
PY
curl -sf -o /dev/null -H 'Authorization: Bearer t' -H 'Content-Type: application/zip' \
  --data-binary @"$work/slow.zip" "$base/v1/assets?id=slow"
echo "RSS with the slow job running: $(rss)"
# Five 100 MB bodies (a zip's magic number, then zeros): queued behind it.
head -c 4 <(printf 'PK\x03\x04') > "$work/big.zip"
head -c $((100 << 20)) /dev/zero >> "$work/big.zip"
for i in 1 2 3 4 5; do
  code=$(curl -s -o /dev/null -w '%{http_code}' -H 'Authorization: Bearer t' -H 'Content-Type: application/zip' \
    --data-binary @"$work/big.zip" "$base/v1/assets?id=big$i")
  echo "upload big$i: $code, RSS $(rss)"
done
echo "temporary files: $(ls "$work/up" | wc -l), $(du -sm "$work/up" | cut -f1) MB"
# The queue is full: a sixth 100 MB body is refused at once.
curl -s -o /dev/null -w 'a 100 MB upload to a full queue: %{http_code} after %{time_total} s\n' -H 'Authorization: Bearer t' \
  -H 'Content-Type: application/zip' -H 'Expect: 100-continue' --data-binary @"$work/big.zip" "$base/v1/assets?id=refused"
echo "RSS with the queue full: $(rss)"
echo "queue: $(curl -s "$base/metrics" | grep '^pmcodec_jobs_pending')"

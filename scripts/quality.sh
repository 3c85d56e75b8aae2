#!/usr/bin/env bash
# Quality at every budget (issue 15): for each sequence, pmcodec's container cut as a client gets
# it (`pmcodec eval --pmc`) beside "direct" (our QEM of each frame from scratch) and "static"
# (frame 0's clusters, positions re-solved per frame), at budgets on the levels (25%, 10%) and
# between them (40%, 15%, 5%, 1.5%: 2,022 vertices on the subdivided horse), plus frame 0 alone
# beside plain QEM on frame 0 (meshoptimizer, examples/qem_reference.rs).
#
# usage: scripts/quality.sh GEN_DIR OUT_DIR [DATA_DIR]
#   GEN_DIR: where `cargo run --release -p pmcodec-eval --example make_meshes -- GEN_DIR` wrote
#   OUT_DIR: containers, JSON reports and the table (quality.md)
#   env: FRAMES (frames measured per sequence, default 12), LARGE_FRAMES (horse-sub4, default 4),
#        BUDGETS (percent, default "40 25 15 10 5 1.5"), SEQS (names, default all seven),
#        ENCODE_ARGS (extra `pmcodec encode` flags), PMCODEC and QEM_REFERENCE (prebuilt binaries)
# Prints a Markdown table; ratios below 1 favour the container.
set -euo pipefail
gen=${1:?usage: scripts/quality.sh GEN_DIR OUT_DIR [DATA_DIR]}
out=${2:?usage: scripts/quality.sh GEN_DIR OUT_DIR [DATA_DIR]}
root=$(cd "$(dirname "$0")/.." && pwd)
data=${3:-$root/../shared/data}
frames=${FRAMES:-12}
large_frames=${LARGE_FRAMES:-4}
budgets=${BUDGETS:-40 25 15 10 5 1.5}
seqs=${SEQS:-horse-gallop samba-60 cat-poses horse-sub4 samba-open cat-open horse-half samba-half waving-cloth}
mkdir -p "$out"
# PMCODEC / QEM_REFERENCE: binaries to use instead of building this checkout's (a "before").
if [ -z "${PMCODEC:-}" ]; then
  (cd "$root" && cargo build --release -q -p pmcodec && cargo build --release -q -p pmcodec-eval --example qem_reference)
fi
pm=${PMCODEC:-$root/target/release/pmcodec}
qem=${QEM_REFERENCE:-$root/target/release/examples/qem_reference}

path_of() {
  case $1 in
    horse-gallop | samba-60 | cat-poses) echo "$data/$1" ;;
    *) echo "$gen/$1" ;;
  esac
}

table=$out/quality.md
{
  echo "| sequence | budget | vertices | container | direct | static | container/direct | container/static | frame 0 container/direct | frame 0 container/QEM |"
  echo "|---|---|---|---|---|---|---|---|---|---|"
} > "$table"
for s in $seqs; do
  in=$(path_of "$s")
  [ -e "$in" ] || { echo "quality.sh: $in is missing" >&2; exit 3; }
  f=$frames
  [ "$s" = horse-sub4 ] && f=$large_frames
  pmc=$out/$s.pmc
  # shellcheck disable=SC2086
  "$pm" encode "$in" -o "$pmc" --quiet ${ENCODE_ARGS:-}
  nv=$("$pm" info "$pmc" --json | jq '.vertices // .header.vertex_count')
  ns=()
  for b in $budgets; do ns+=("$(awk -v n="$nv" -v b="$b" 'BEGIN { printf "%d", n * b / 100 + 0.5 }')"); done
  "$qem" "$in" "${ns[@]}" > "$out/$s.qem.jsonl"
  i=0
  for b in $budgets; do
    n=${ns[$i]}
    i=$((i + 1))
    j=$out/$s.$b.json
    "$pm" eval "$in" --pmc "$pmc" --methods static,direct --vertices "$n" --frames "$f" --json --quiet > "$j"
    q=$(jq -s --argjson n "$n" '[.[] | select(.vertices == $n)][0].rms' "$out/$s.qem.jsonl")
    jq -r --arg s "$s" --arg b "$b%" --argjson q "$q" '
      def m(k): (.methods[] | select(.method == k));
      [ $s, $b, (.vertices | tostring),
        (m("container").mean_rms | . * 1e4 | round / 1e4 | tostring),
        (m("direct").mean_rms | . * 1e4 | round / 1e4 | tostring),
        (m("static").mean_rms | . * 1e4 | round / 1e4 | tostring),
        (m("container").mean_rms / m("direct").mean_rms | . * 1e3 | round / 1e3 | tostring),
        (m("container").mean_rms / m("static").mean_rms | . * 1e3 | round / 1e3 | tostring),
        (m("container").rms[0] / m("direct").rms[0] | . * 1e3 | round / 1e3 | tostring),
        (m("container").rms[0] / $q | . * 1e3 | round / 1e3 | tostring) ]
      | "| " + join(" | ") + " |"' "$j" >> "$table"
  done
done
cat "$table"

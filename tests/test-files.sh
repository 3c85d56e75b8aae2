#!/usr/bin/env bash
# Test files that would never run: a crate with `autotests = false` builds only the [[test]]
# targets its Cargo.toml names, so each file directly in its tests/ folder must be one of them
# or a `mod` of one (tests/main.rs gathers a crate's integration tests into one binary, one link
# instead of one per file). A text check: exit 1 naming each file nothing compiles.
set -euo pipefail
cd "$(dirname "$0")/.."
status=0
for toml in crates/*/Cargo.toml tests/Cargo.toml; do
  grep -q '^autotests = false' "$toml" || continue
  dir="$(dirname "$toml")"
  targets="$(awk '/^path = "/ { gsub(/^path = "|"$/, ""); print }' "$toml")"
  for f in "$dir"/tests/*.rs "$dir"/system/*.rs; do
    [ -e "$f" ] || continue
    rel="${f#"$dir"/}"
    name="$(basename "$f" .rs)"
    grep -qx "$rel" <<<"$targets" && continue
    found=0
    for t in $targets; do
      [ "$(dirname "$t")" = "$(dirname "$rel")" ] && grep -qE "^mod $name;" "$dir/$t" && found=1
    done
    if [ "$found" = 0 ]; then
      echo "test-files: $f is neither a [[test]] of $toml nor a \`mod\` of one: it never runs" >&2
      status=1
    fi
  done
done
[ "$status" = 0 ] && echo "test-files: every test file is built"
exit "$status"

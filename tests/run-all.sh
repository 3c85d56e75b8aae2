#!/usr/bin/env bash
# Every test of the project, on a fresh machine (installs what it needs):
#   1. the Rust workspace: clippy with warnings as errors, then unit, integration, property, corpus
#      and CLI tests, and the system tests
#      in tests/system (the server on real sockets, uploads of ../shared/data, the client, the S3
#      store against s3s-fs, served in the test's own process);
#   2. the viewer: TypeScript unit tests (node's test runner) and the production build;
#   3. end to end: `pmcodec serve` with the built-in samples and the viewer, driven by headless
#      Chromium (Debian's package) through playwright-core;
#   4. `pmcodec lod` output checked by the Khronos glTF validator (npm `gltf-validator`), and
#      every level of it played by three.js's glTF loader in headless Chromium (web/lod.html).
# Benchmarks and long fuzzing are not part of it (see README.md).
set -euo pipefail
cd "$(dirname "$0")/.."
export CARGO_TERM_COLOR=never
# One build per run: incremental caches would only double target/'s size on a fresh clone.
export CARGO_INCREMENTAL="${CARGO_INCREMENTAL:-0}"
disk() { echo "-- disk: $(df -h . | awk 'NR==2 {print $4 " free"}'), target/ $(du -sh target 2>/dev/null | cut -f1)"; }
disk
# Each phase says how long the one before took (CI's budget is 25 minutes on 2 cores).
phase_start=$SECONDS
phase() { echo "-- $((SECONDS - phase_start)) s"; phase_start=$SECONDS; echo "== $*"; }

phase "unused dependencies and unbuilt test files (text checks, about a second)"
tests/unused-deps.sh
tests/test-files.sh

phase "cargo build with clippy's lints (every crate and target; warnings are errors)"
# `cargo clippy` is `cargo check` with clippy-driver as the workspace's rustc wrapper. Run as the
# wrapper of the build itself, it lints the same targets with the same flags while they are
# compiled for the tests, instead of checking every dependency and crate a second time (that
# was about 6 of a fresh run's 30 minutes on 2 cores). Exported for the rest of the run: a
# cargo command without it would see other flags and rebuild the workspace's crates.
export RUSTC_WORKSPACE_WRAPPER="$(rustc --print sysroot)/bin/clippy-driver"
export CLIPPY_ARGS="-D__CLIPPY_HACKERY__warnings__CLIPPY_HACKERY__" # cargo-clippy's own encoding of `-- -D warnings`
[ -x "$RUSTC_WORKSPACE_WRAPPER" ] || { echo "run-all: clippy-driver is missing: rustup component add clippy" >&2; exit 1; }
cargo test --workspace --all-targets --locked --no-run 2>&1

phase "cargo test"
# Libraries, binaries and tests (the examples and benchmarks were built and linted above; no
# test runs them, and a benchmark run as a test would time things).
cargo test --workspace --lib --bins --tests --locked --no-fail-fast 2>&1
disk

phase "viewer unit tests and build"
(cd web && npm ci --no-audit --no-fund && PMCODEC_BIN="$PWD/../target/debug/pmcodec" npm test && npm run build)

phase "end to end"
if ! command -v chromium >/dev/null 2>&1; then
  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null
fi
# `cargo test` above already built target/debug/pmcodec for the CLI tests; build only if not.
[ -x target/debug/pmcodec ] || cargo build --locked -p pmcodec 2>&1
(cd web && PMCODEC_BIN="$PWD/../target/debug/pmcodec" node test/e2e.mjs)
# The viewer and the pmcodec-three package, one check per bug of issue 18 (uploads included).
(cd web && PMCODEC_BIN="$PWD/../target/debug/pmcodec" node test/viewer-e2e.mjs)
(cd web && PMCODEC_BIN="$PWD/../target/debug/pmcodec" node test/appearance-e2e.mjs) # issue 16: each shared GLB's stream vs three.js, SSIM >= 0.97
(cd web && PMCODEC_BIN="$PWD/../target/debug/pmcodec" node test/skin-e2e.mjs) # issue 17: GPU-skinned drawing vs the worker-posed one, paused, played and after a budget change

# ---- glTF validator on `pmcodec lod` output --------------------------------------------------
# LOD chains of the built-in test rig, of a generated multi-part character (many small parts on
# one skeleton, the kind that crashed `pmcodec lod` in issue 13) and of every shared model at
# 50%, 25%, 10% and 5% (the Draco-compressed Parrot read directly) must have no validator
# errors and no warnings. A missing model is a failure.
phase "glTF validator on pmcodec lod output"
(cd tests && npm ci --no-audit --no-fund)
bin="${CARGO_TARGET_DIR:-target}/debug/pmcodec"
[ -x "$bin" ] || cargo build --locked -p pmcodec 2>&1
lod_out="$(mktemp -d)"
trap 'rm -rf "$lod_out"' EXIT
cargo run --locked -q -p pmcodec-lod --example write_fixture -- "$lod_out/fixture.glb"
"$bin" -q lod "$lod_out/fixture.glb" --triangles 50%,20% -o "$lod_out/fixture-lod.glb"
cargo run --locked -q -p pmcodec-lod --example write_fixture -- --character 13 "$lod_out/character.glb"
"$bin" -q lod "$lod_out/character.glb" --triangles 50%,25%,10%,5% -o "$lod_out/character-lod.glb"
"$bin" -q lod "$lod_out/character.glb" --triangles 25%,10% --placement endpoint -o "$lod_out/character-endpoint-lod.glb"
models=../shared/data/gltf
for m in Fox RobotExpressive Horse Parrot; do
  if [ ! -f "$models/$m.glb" ]; then
    echo "run-all: $models/$m.glb is missing: the LOD checks need the shared models beside the repository" >&2
    exit 1
  fi
done
# RobotExpressive beside the other three (`pmcodec lod` works on one core; the robot takes about
# as long as the three together): half a minute less on 2 cores.
"$bin" -q lod "$models/RobotExpressive.glb" --triangles 50%,25%,10%,5% -o "$lod_out/RobotExpressive-lod.glb" &
robot=$!
for m in Fox Horse Parrot; do
  "$bin" -q lod "$models/$m.glb" --triangles 50%,25%,10%,5% -o "$lod_out/$m-lod.glb"
done
wait "$robot"
node tests/gltf-validate.mjs "$lod_out"/*.glb
# Every level of every chain plays in three.js's stock glTF loader (web/lod.html in headless
# Chromium): loads, skins or morphs, animates on the one shared skeleton with no track missing
# its node, draws (textured when the file has images), and has fewer triangles than the last.
phase "three.js plays pmcodec lod output"
bin_abs="$(cd "$(dirname "$bin")" && pwd)/$(basename "$bin")"
(cd web && PMCODEC_BIN="$bin_abs" node test/lod-e2e.mjs "$lod_out"/*-lod.glb)
# ---- end of glTF validator block --------------------------------------------------------------
disk
echo "-- $((SECONDS - phase_start)) s, $SECONDS s in all"

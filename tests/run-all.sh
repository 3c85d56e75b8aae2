#!/usr/bin/env bash
# Every test of the project: the Rust workspace (unit, integration, property and corpus tests,
# which read the real meshes in ../shared/data when present). Benchmarks and long fuzzing are
# not part of it (see README.md).
set -euo pipefail
cd "$(dirname "$0")/.."
export CARGO_TERM_COLOR=never
cargo test --workspace --locked --no-fail-fast 2>&1

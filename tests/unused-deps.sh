#!/usr/bin/env bash
# Unused dependencies: for every crate of the workspace (and fuzz/), each name listed under
# [dependencies], [dev-dependencies] or [build-dependencies] must be referenced as a path
# (`name::`) or by `extern crate` in that crate's Rust sources (comment lines do not count).
# A text check, so it costs a second and installs nothing; cargo-udeps/cargo-machete would be
# exact but cost minutes to install on every fresh CI machine.
#   tests/unused-deps.sh            check the whole tree, exit 1 naming each unused dependency
#   tests/unused-deps.sh DIR...     check only these crate folders
set -euo pipefail
cd "$(dirname "$0")/.."

# Dependency names of one Cargo.toml: keys of the dependency tables, dotted (`glam.workspace =
# true`) or inline (`glam = { ... }`), plus the `[dependencies.name]` table form.
dep_names() {
  awk '
    /^\[/ {
      t = $0
      sub(/[ \t]*#.*/, "", t)
      in_deps = (t ~ /^\[(dev-|build-)?dependencies\]$/)
      if (t ~ /^\[(dev-|build-)?dependencies\.[A-Za-z0-9_-]+\]$/) {
        n = t; sub(/^\[[a-z-]*dependencies\./, "", n); sub(/\]$/, "", n); print n
      }
      next
    }
    in_deps && /^[A-Za-z0-9_-]+[ \t]*[.=]/ {
      n = $0; sub(/[ \t]*[.=].*/, "", n); print n
    }
  ' "$1" | sort -u
}

if [ "$#" -gt 0 ]; then
  dirs=("$@")
else
  mapfile -t dirs < <(git ls-files -- '*Cargo.toml' ':!:Cargo.toml' | xargs -n1 dirname | sort -u)
fi

failed=0
for dir in "${dirs[@]}"; do
  manifest="$dir/Cargo.toml"
  [ -f "$manifest" ] || { echo "unused-deps: $manifest does not exist" >&2; exit 2; }
  # The crate's own Rust files, without comment lines.
  sources="$(find "$dir" -name target -prune -o -name node_modules -prune -o -name '*.rs' -print0 \
    | xargs -0 -r cat | grep -v '^[[:space:]]*//' || true)"
  while read -r dep; do
    [ -n "$dep" ] || continue
    ident="${dep//-/_}"
    if ! grep -Eq "(^|[^A-Za-z0-9_])${ident}::|extern crate ${ident}([^A-Za-z0-9_]|$)" <<<"$sources"; then
      echo "unused-deps: $manifest lists \`$dep\`, but no Rust file under $dir/ uses \`${ident}::\`" >&2
      failed=1
    fi
  done < <(dep_names "$manifest")
done

if [ "$failed" -ne 0 ]; then
  echo "unused-deps: remove the dependencies above (or use them)" >&2
  exit 1
fi
echo "unused-deps: ${#dirs[@]} crates, every dependency is used"

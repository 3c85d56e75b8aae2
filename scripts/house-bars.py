#!/usr/bin/env python3
"""Checks issue 14's size bars on the tracked sources: no source file over 800 lines and no
function over 120 lines outside tests (Rust in crates/*/src, TypeScript in web/src).

Test code does not count: files under tests/, benches/, examples/ and fuzz/, `*_tests.rs`,
`web/test/`, and `#[cfg(test)]` modules inside a source file (their lines are left out of the
file's count, their functions are not measured). A function's length runs from its `fn` (or
`function`/method) line to its closing brace, comments and blank lines included: what a reader
scrolls through.

    python3 scripts/house-bars.py            # the offenders, then a summary line
    python3 scripts/house-bars.py --all      # also the ten longest files and functions

Exits 1 when a bar is passed, so it can guard CI; it reads files only.
"""

import re
import subprocess
import sys
from pathlib import Path

FILE_BAR = 800
FUNCTION_BAR = 120

ROOT = Path(__file__).resolve().parent.parent


def tracked() -> list[str]:
    out = subprocess.run(["git", "ls-files"], cwd=ROOT, check=True, capture_output=True, text=True).stdout
    return out.splitlines()


def is_source(path: str) -> bool:
    p = Path(path)
    parts = p.parts
    if any(d in parts for d in ("tests", "benches", "examples", "fuzz", "node_modules", "test")):
        return False
    if p.name.endswith("_tests.rs") or p.name.endswith(".test.ts") or p.name.endswith(".d.ts"):
        return False
    if p.suffix == ".rs":
        return len(parts) > 2 and parts[0] == "crates" and "src" in parts
    if p.suffix == ".ts":
        return parts[0] == "web" and "src" in parts
    return False


def strip_strings(line: str) -> str:
    """The line without string and char literals and `//` comments, so braces inside them do
    not count. Good enough for this code base (no raw strings with braces spanning lines)."""
    line = re.sub(r'"(\\.|[^"\\])*"', '""', line)
    line = re.sub(r"'(\\.|[^'\\])'", "''", line)
    line = re.sub(r"`(\\.|[^`\\])*`", "``", line)
    return line.split("//", 1)[0]


def block_end(lines: list[str], start: int) -> int:
    """Index of the line closing the first block opened at or after `start` (or the last line)."""
    depth = 0
    opened = False
    for i in range(start, len(lines)):
        for ch in strip_strings(lines[i]):
            if ch == "{":
                depth += 1
                opened = True
            elif ch == "}":
                depth -= 1
                if opened and depth == 0:
                    return i
        # A declaration without a body (`fn f();`, a type's method signature) ends at `;`.
        if not opened and strip_strings(lines[i]).rstrip().endswith(";"):
            return -1
    return len(lines) - 1


RUST_FN = re.compile(r"^\s*(pub(\([^)]*\))?\s+)?(const\s+)?(async\s+)?(unsafe\s+)?(extern\s+\"[^\"]*\"\s+)?fn\s+(\w+)")
TS_FN = re.compile(
    r"^\s*(export\s+)?(default\s+)?(async\s+)?function\s*\*?\s*(\w+)"
    r"|^\s*(public\s+|private\s+|protected\s+|static\s+|async\s+|readonly\s+|get\s+|set\s+)*(\w+)\s*(<[^>]*>)?\s*\([^;]*$"
    r"|^\s*(export\s+)?(const|let)\s+(\w+)\s*=\s*(async\s*)?(\([^)]*\)|\w+)\s*(:[^=]*)?=>\s*\{"
)
TS_NOT_FN = {"if", "for", "while", "switch", "catch", "return", "function", "new", "await", "else", "do", "try"}


def measure(path: str):
    lines = (ROOT / path).read_text(encoding="utf-8", errors="replace").split("\n")
    if lines and lines[-1] == "":
        lines.pop()
    skip = [False] * len(lines)
    if path.endswith(".rs"):
        i = 0
        while i < len(lines):
            if lines[i].strip().startswith("#[cfg(test)]"):
                end = block_end(lines, i + 1)
                if end >= 0:
                    for k in range(i, end + 1):
                        skip[k] = True
                    i = end + 1
                    continue
            i += 1
    counted = sum(1 for s in skip if not s)
    functions = []
    for i, line in enumerate(lines):
        if skip[i]:
            continue
        name = None
        if path.endswith(".rs"):
            m = RUST_FN.match(line)
            if m:
                name = m.group(7)
        else:
            m = TS_FN.match(line)
            if m:
                name = m.group(4) or m.group(6) or m.group(10)
                if name in TS_NOT_FN:
                    name = None
        if not name:
            continue
        end = block_end(lines, i)
        if end < 0:
            continue
        functions.append((end - i + 1, name, i + 1))
    return counted, functions


def main() -> int:
    show_all = "--all" in sys.argv[1:]
    files = []
    functions = []
    for path in tracked():
        if not is_source(path) or not (ROOT / path).is_file():
            continue
        counted, fns = measure(path)
        files.append((counted, path))
        functions.extend((n, f"{path}:{line} {name}") for n, name, line in fns)
    long_files = sorted((f for f in files if f[0] > FILE_BAR), reverse=True)
    long_fns = sorted((f for f in functions if f[0] > FUNCTION_BAR), reverse=True)
    for n, p in long_files:
        print(f"file over {FILE_BAR} lines: {p} ({n})")
    for n, what in long_fns:
        print(f"function over {FUNCTION_BAR} lines: {what} ({n})")
    if show_all:
        print("longest files:")
        for n, p in sorted(files, reverse=True)[:10]:
            print(f"  {n:5} {p}")
        print("longest functions:")
        for n, what in sorted(functions, reverse=True)[:10]:
            print(f"  {n:5} {what}")
    longest_file = max(files, default=(0, "-"))
    longest_fn = max(functions, default=(0, "-"))
    print(
        f"{len(files)} source files, {len(functions)} functions; longest file {longest_file[0]} lines ({longest_file[1]}), "
        f"longest function {longest_fn[0]} lines ({longest_fn[1]}); "
        f"{len(long_files)} files over {FILE_BAR}, {len(long_fns)} functions over {FUNCTION_BAR}"
    )
    return 1 if long_files or long_fns else 0


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env python3
"""Runs every benchmark and figure-producing example or script of pmcodec and writes
BENCHMARKS.md: one row per figure with its value, the exact command, the commit it was
measured at and the date, under the machine's description (nproc, CPU model, load).

  scripts/benchmarks.py                 every row (about an hour on a quiet 2-core machine)
  scripts/benchmarks.py ROW...          only these rows; the others keep their last values
  scripts/benchmarks.py --quick [ROW...]  shorter runs where a command has a length (load test,
                                        soak, seeks); the rows say they were quick
  scripts/benchmarks.py --list          the rows and their commands
  scripts/benchmarks.py --extract       rebuild BENCHMARKS.md from the saved logs, running nothing

Each row's command runs from the repository root with bash; its whole output is kept in
target/benchmarks/logs/ROW.log (with the commit, date and command it ran), and the row's value is
the lines of that output its pattern selects, as printed. Benchmarks are never part of the test
command (tests/run-all.sh): they time things, and CI machines are busy.
"""

import datetime
import re
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
LOGS = ROOT / "target" / "benchmarks" / "logs"
OUT = ROOT / "BENCHMARKS.md"
BIN = "target/release/pmcodec"
DATA = "../shared/data"
# Files the rows encode for themselves (the same encode in each row that needs one).
HORSE_PMC = f"{BIN} encode -q {DATA}/horse-gallop -o target/benchmarks/horse-gallop.pmc"
SAMBA_PMC = f"{BIN} encode -q {DATA}/samba-60 -o target/benchmarks/samba-60.pmc"
# One build of every binary and example for the whole workspace: with `-p CRATE` cargo would
# unify features per package and rebuild much of the tree for each row.
RELEASE = "cargo build --release --locked -q --workspace --bins --examples"


@dataclass
class Row:
    id: str
    title: str
    # The command, with {secs} where its length goes (full / quick).
    command: str
    # Lines of the output that make the value (a regular expression, searched per line).
    pick: str
    # Divan benches: their tables are turned into "bench/arg: median" lines first.
    divan: bool = False
    secs: tuple = (0, 0)

    def cmd(self, quick: bool) -> str:
        return self.command.replace("{secs}", str(self.secs[1] if quick else self.secs[0]))


def divan(bench: str, filter: str = "") -> str:
    # --workspace for the same reason as RELEASE: one feature set, one build for every bench.
    return f"cargo bench --locked -q --workspace --bench {bench}" + (f" -- {filter}" if filter else "")


def example(crate: str, name: str, args: str, env: str = "") -> str:
    # `crate` names where the example lives (crates/CRATE/examples); RELEASE builds them all.
    return f"{RELEASE} && {env}target/release/examples/{name} {args}"


ROWS = [
    # The hierarchy (Kircher & Garland, "Progressive Multiresolution Meshes for Deforming
    # Surfaces", 2005).
    Row("build", "multilevel build, horse and a 270k-triangle subdivided horse, beside meshoptimizer's simplifier (median)",
        divan("build"), r"^(pmcodec_build|meshopt_simplify|degenerate_sets)", divan=True),
    Row("recluster", "reclustering (encode) per frame, horse; client: one frame's swaps applied to a 2,000-triangle cut (median)",
        divan("recluster"), r"^(encode_frame|apply_frame)", divan=True),
    Row("raw-swaps", "raw swaps and full hierarchy per frame, horse, b = 8 (as the paper counts them)",
        example("pmcodec-hierarchy", "delta_sizes", f"{DATA}/horse-gallop 8"), r"^(raw swaps|full hierarchy)"),
    # Quality (pmcodec-eval).
    Row("distance", "surface distance, horse against a coarse copy (median)",
        divan("distance"), r".", divan=True),
    *[Row(f"quality-{name}", f"RMS at 800 vertices, % of bbox diagonal (static / direct / pmcodec), and shown triangles changing per frame at 1,600 triangles, {name}",
          f"{RELEASE} && {BIN} eval {DATA}/{data} --vertices 800 --coherence-triangles 1600",
          r"mean RMS|pmcodec / direct|below static") for name, data in (("horse", "horse-gallop"), ("samba", "samba-60"), ("cat", "cat-poses"))],
    *[Row(f"client-quality-{name}", f"what a client of the container gets, {name}: each frame decoded from a default .pmc and cut by its split order",
          f"{RELEASE} && {enc} && {BIN} eval {DATA}/{data} --methods pmcodec --pmc target/benchmarks/{data}.pmc --vertices 800 --coherence-triangles 1600",
          r"mean RMS|container / pmcodec") for name, data, enc in (("horse", "horse-gallop", HORSE_PMC), ("samba", "samba-60", SAMBA_PMC))],
    # The container.
    *[Row(f"sizes-{name}", f"container, 12-bit positions, default options, {name}: sizes, bytes of a 10% client, decode and seek",
          example("pmcodec-container", "sizes", f"{DATA}/{data} 12"),
          r"^(total|positions \(|positions on|band 0 alone|topology|10% of|decode,|seek|each frame|meshoptimizer)") for name, data in (("horse", "horse-gallop"), ("samba", "samba-60"))],
    *[Row(f"sizes-{name}-v4", f"the same with version 4's default (mean motion in input order), {name}",
          example("pmcodec-container", "sizes", f"{DATA}/{data} 12", env="PMCODEC_MOTION=mean PMCODEC_ORDER=input "),
          r"^(positions \(|band 0 alone|decode,)") for name, data in (("horse", "horse-gallop"), ("samba", "samba-60"))],
    *[Row(f"position-bounds-{name}", f"what band 0's coding could still gain, frames 1.. in closed loop, {name} (bits/vertex/frame)",
          example("pmcodec-container", "position_bounds", f"{DATA}/{data}"), r"^(input order|breadth first),") for name, data in (("horse", "horse-gallop"), ("samba", "samba-60"))],
    *[Row(f"coarse-bounds-{name}", f"what the coarse bands could gain from their model error alone, frames 1.., {name} (bits per input vertex per frame)",
          example("pmcodec-container", "coarse_bounds", f"{DATA}/{data}"), r"total") for name, data in (("horse", "horse-gallop"), ("samba", "samba-60"))],
    Row("cut-quality", "what --coarse-grid costs in cut quality, horse (mean symmetric RMS, % of bbox diagonal)",
        example("pmcodec-container", "cut_quality", f"{DATA}/horse-gallop"), r"."),
    Row("encode-speed", "the whole `pmcodec encode` process per frame beside one meshoptimizer simplification of a frame to 800 vertices, in the same run, and the encoder's peak RSS: horse, and the 4x-subdivided horse (issue 15's encoder bar)",
        example("pmcodec-eval", "make_meshes", "target/benchmarks/made")
        + f" && target/release/examples/encode_speed {BIN} {DATA}/horse-gallop 5"
        + f" && target/release/examples/encode_speed {BIN} target/benchmarks/made/horse-sub4 1",
        r"^(encode|meshoptimizer)|ms/frame|vertices;"),
    # Issue 17's encode-cost bar (under 10 s and 200 MB): a character of the issue's size made
    # by code (crates/pmcodec-mesh/src/samples/character.rs), its frames posed as the encoder
    # asks for them.
    Row("encode-big-character", "issue 17's encode cost: a generated skinned character (59 parts, 34,102 vertices, one skeleton of 57 joints, 35 s at 30 fps, 1,051 frames): the whole `pmcodec encode` process's wall time and peak RSS (bars 10 s, 200 MB), the .pmc's bytes beside the GLB's, and the load average before the run",
        "mkdir -p target/benchmarks && "
        + example("pmcodec-mesh", "make_character", "target/benchmarks/big-character.glb")
        + " && wc -c < target/benchmarks/big-character.glb | sed 's/^/GLB bytes /' && sed 's/^/load average /' /proc/loadavg"
        + f" && /usr/bin/time -f 'encode: wall %e s, peak RSS %M KiB' {BIN} encode target/benchmarks/big-character.glb -o target/benchmarks/big-character.pmc 2>&1",
        r"^(GLB bytes|load average|encode:)|bytes;"),
    Row("encode-speed-fit", "the same with a fitted skin (`encode --fit-skin`: Le & Deng's SSDR, then the encode), horse and samba, beside meshoptimizer in the same run (issue 19's encoder bar)",
        example("pmcodec-eval", "encode_speed", f"{BIN} {DATA}/horse-gallop 3 -- --fit-skin --quant-bits 12")
        + f" && target/release/examples/encode_speed {BIN} {DATA}/samba-60 3 -- --fit-skin --quant-bits 12",
        r"^(encode|meshoptimizer)|ms/frame|vertices;"),
    Row("encode", "container encode, horse, 48 frames (median)",
        divan("container", "encode_horse"), r".", divan=True),
    Row("decode", "container decode, horse, 48 frames, one core, by band-0 motion; decoded and cut at 2,000 triangles every frame by a level-0 / level-1 decoder (median)",
        divan("container", "decode_"), r".", divan=True),
    Row("lod-cut", "LOD cut of a decoded frame at 500 / 2,000 / 8,000 / 16,000 triangles; as the server sees it, 64 requests at random frame and budget, each cut and its format=bin body (median; lod_on_demand_random_frames is per 64 requests)",
        divan("container", "lod_"), r".", divan=True),
    Row("seek", "playback and random seek with an open decoder, horse, CPU time",
        f"{RELEASE} && {HORSE_PMC} && " + example("pmcodec-container", "speed", "target/benchmarks/horse-gallop.pmc {secs}"),
        r"^(playback|random seek)", secs=(30, 3)),
    Row("decode-normals", "decode at full resolution with normals computed, horse, CPU time: bare (level-0 cut, area-weighted vertex normals) and with a generated appearance (Decoder::textured_mesh: attributes and normals split at seams); bar 1,000 frames/s",
        example("pmcodec-container", "decode_normals", f"{DATA}/horse-gallop {{secs}}"), r"^decode with normals", secs=(20, 3)),
    # Issue 16's size bar: appearance bytes beside Draco's for the same attributes.
    Row("attribute-sizes", "texture coordinates, colours and material ids: pmcodec's appearance bytes beside Draco's (draco3d, Edgebreaker, default prediction) on the same mesh at the same quantization, and the textures' own bytes",
        f"(cd tests && npm ci --no-audit --no-fund -s) && {RELEASE} && node scripts/attribute-sizes.mjs {BIN} {DATA}/gltf/Fox.glb {DATA}/gltf/RobotExpressive.glb",
        r"^(\S+\.glb:|draco|pmcodec|ratio|bar )"),
    # Issue 16's image-error bar: streams cut to 25% / 10% against meshoptimizer's
    # simplifyWithAttributes of the bind pose, SSIM against the full GLB, every animation.
    Row("simplified-ssim", "image error under simplification: mean SSIM (over the model's windows) against the full GLB of the stream cut to 25% and 10% of the triangles beside meshoptimizer's simplifyWithAttributes of the bind pose at the same share, 4 frames of every animation, headless Chromium",
        f"{RELEASE} && (cd web && npm ci --no-audit --no-fund -s && npm run build -s) && (cd web && PMCODEC_BIN=../{BIN} node test/simplified-ssim.mjs)",
        r"^\| "),
    # LODs of skinned and morph-target glTF (Mohr & Gleicher, "Deformation Sensitive Decimation",
    # 2003; Houle & Poulin, "Simplification and Real-time Smooth Transitions of Articulated
    # Meshes", 2001).
    Row("lod-eval", "pmcodec lod at 25% and 10% of the triangles against meshoptimizer (rest pose, Regularize), mean / max per-frame RMS over every animation, % of bbox diagonal",
        example("pmcodec-lod", "lod_eval", f"{DATA}/gltf/Fox.glb {DATA}/gltf/RobotExpressive.glb {DATA}/gltf/Horse.glb {DATA}/gltf/Parrot.glb"),
        r"^\S+\s+\d+%|^\S+.*(meshopt|houle|refit)"),
    # The server.
    Row("loadtest", "server under load (wrk and oha on the same 2 cores, 64 connections): LOD on demand closed and open loop, transfer ceiling, chunk ranges, playback bytes",
        "LOADTEST_PORT=18614 crates/pmcodec-server/loadtest/run.sh {secs}",
        r"^== |Requests/sec|req/s offered|10% client|full-resolution client|99%", secs=(20, 5)),
    Row("soak", "soak: LOD horse 24 + cat 8, chunk ranges 24, 8 slow clients, an upload every 15 s; errors and RSS over time",
        "LOADTEST_PORT=18615 crates/pmcodec-server/loadtest/run.sh soak {secs}",
        r"^-- |requests in|Requests/sec|non-2xx|^slow clients|^uploads:|^under load|too few", secs=(600, 120)),
    # The browser side.
    Row("ts-decode", "TypeScript decoder in Node, horse at full resolution: decode alone, and the player worker's path (decode, cut, normals)",
        f"{RELEASE} && {HORSE_PMC} && (cd web && npx tsc -p tsconfig.test.json && node bench/decode.mjs ../target/benchmarks/horse-gallop.pmc)",
        r"^(decode|worker path):"),
    Row("viewer", "the viewer on the full-resolution horse in headless Chromium: frame rate, page thread, bytes, budget lowered to 10%, seeks",
        f"{RELEASE} && mkdir -p target/benchmarks/assets && {BIN} encode -q {DATA}/horse-gallop -o target/benchmarks/assets/horse-gallop.pmc && "
        "(cd web && npm run build -s && npx tsc -p tsconfig.test.json && PMCODEC_BIN=../target/release/pmcodec node bench/play.mjs ../target/benchmarks/assets)",
        r"^(loopback|paused|bytes|50 ms|budget|seek):"),
]


def git(*args: str) -> str:
    return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True, check=True).stdout.strip()


def commit() -> str:
    # Edits to what no row measures (this script, the documents) do not make a measurement dirty.
    dirty = git("status", "--porcelain", "--untracked-files=no", "--", ".", *[f":!{p}" for p in ("BENCHMARKS.md", "README.md", "docs", "proto", "scripts")])
    return git("rev-parse", "--short=10", "HEAD") + ("-dirty" if dirty else "")


def machine() -> str:
    model = "unknown CPU"
    for line in Path("/proc/cpuinfo").read_text().splitlines():
        if line.startswith("model name"):
            model = line.split(":", 1)[1].strip()
            break
    load = Path("/proc/loadavg").read_text().split()[:3]
    nproc = subprocess.run(["nproc"], capture_output=True, text=True).stdout.strip()
    return f"nproc {nproc}, {model}; load average {' '.join(load)} at the start of the script's last run (rows may come from earlier runs)"


def divan_medians(text: str) -> list[str]:
    """Divan's tables as "bench/arg: median" lines (leaves only)."""
    out, stack = [], []
    for line in text.splitlines():
        m = re.search(r"[├╰]─ ", line)
        if not m:
            continue
        depth = m.start() // 3
        cols = line[m.end():].split("│")
        name = re.split(r"\s{2,}", cols[0].strip())[0]
        stack[depth:] = [name]
        if len(cols) > 2 and cols[2].strip():
            out.append(f"{'/'.join(stack)}: {cols[2].strip()}")
    return out


def value(row: Row, text: str) -> str:
    lines = divan_medians(text) if row.divan else [re.sub(r"\s+", " ", l.strip()) for l in text.splitlines()]
    picked = [l for l in lines if l and re.search(row.pick, l)]
    return "; ".join(picked) if picked else "(no figure in the output: see the log)"


def run(row: Row, quick: bool) -> None:
    LOGS.mkdir(parents=True, exist_ok=True)
    cmd = row.cmd(quick)
    stamp = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    print(f"== {row.id}: {cmd}", flush=True)
    p = subprocess.run(["bash", "-o", "pipefail", "-c", cmd], cwd=ROOT, capture_output=True, text=True)
    head = f"# commit: {commit()}\n# date: {stamp}\n# quick: {int(quick and row.secs != (0, 0))}\n# status: {p.returncode}\n# command: {cmd}\n"
    (LOGS / f"{row.id}.log").write_text(head + p.stdout + ("\n# stderr:\n" + p.stderr if p.stderr else ""))
    print(f"   exit {p.returncode}: {value(row, p.stdout)[:300]}", flush=True)


def saved(row: Row) -> dict | None:
    path = LOGS / f"{row.id}.log"
    if not path.exists():
        return None
    text = path.read_text()
    meta = dict(re.findall(r"^# (commit|date|quick|status|command|note): (.*)$", text, re.M))
    body = text.split("\n# stderr:\n")[0]
    v = value(row, body)
    if meta.get("status") != "0":
        v = f"(the command failed, exit {meta.get('status')}) " + v
    if meta.get("quick") == "1":
        v = "(quick run) " + v
    # A line "# note: ..." added to a log by hand says why a run failed or stopped.
    if "note" in meta:
        v = f"({meta['note']}) " + v
    return {**meta, "value": v}


def cell(s: str) -> str:
    return s.replace("|", "\\|")


def committed() -> dict:
    """The rows BENCHMARKS.md holds now, by id: a row whose log is not in this checkout's target/
    (measured in another clone or worktree) keeps its committed value, commit and date, as long as
    its command is still the one the row runs."""
    if not OUT.exists():
        return {}
    rows = {}
    for line in OUT.read_text().splitlines():
        m = re.match(r'\| <a id="([^"]+)"></a>', line)
        if not m:
            continue
        cells = [c.strip() for c in re.split(r"(?<!\\)\|", line)[1:-1]]
        if len(cells) == 5 and cells[1] != "(not measured yet)":
            rows[m.group(1)] = {"value": cells[1], "command": cells[2].strip("`"), "commit": cells[3], "date": cells[4]}
    return rows


def write(header_machine: str) -> None:
    lines = [
        "# Benchmarks and figures",
        "",
        "Generated by `scripts/benchmarks.py` (every row; `scripts/benchmarks.py ROW` regenerates one, "
        "`--quick` shortens the timed runs, `--list` lists the rows). Each value is what the command printed, "
        "the lines the script selects from its output (the whole output is in `target/benchmarks/logs/ROW.log`). "
        "Data: `../shared/data` beside the repository.",
        "",
        f"Machine: {header_machine}.",
        "",
        "**These figures were measured on a shared, loaded 2-core machine** (seven engineers building and "
        "testing on it at once): timings are slower and noisier than on a quiet machine, sizes and "
        "distances are not affected. Compare timings only within one run.",
        "",
        "| figure | value | command | commit | date |",
        "|---|---|---|---|---|",
    ]
    kept = committed()
    for row in ROWS:
        s = saved(row)
        k = kept.get(row.id)
        if s is None and k is not None and k["command"] == cell(row.cmd(False)):
            lines.append(f'| <a id="{row.id}"></a>{cell(row.title)} | {k["value"]} | `{k["command"]}` | {k["commit"]} | {k["date"]} |')
            continue
        if s is None:
            lines.append(f'| <a id="{row.id}"></a>{cell(row.title)} | (not measured yet) | `{cell(row.cmd(False))}` | | |')
            continue
        lines.append(f'| <a id="{row.id}"></a>{cell(row.title)} | {cell(s["value"])} | `{cell(s["command"])}` | {s["commit"]} | {s["date"]} |')
    lines += [
        "",
        "Not figures, so not rows: the fuzzers (`cd fuzz && cargo +nightly fuzz run decode -- -max_total_time=600`, "
        "and `resealed -- -max_len=16384 -fork=1 -max_total_time=1800`), whose corpora run in the tests.",
        "",
    ]
    OUT.write_text("\n".join(lines))
    print(f"wrote {OUT.relative_to(ROOT)}")


def main(argv: list[str]) -> int:
    quick = "--quick" in argv
    args = [a for a in argv if a != "--quick"]
    if args == ["--list"]:
        for row in ROWS:
            print(f"{row.id:22} {row.cmd(quick)}")
        return 0
    known = {r.id: r for r in ROWS}
    header = machine()
    machine_file = LOGS / "machine.txt"
    if args == ["--extract"]:
        header = machine_file.read_text().strip() if machine_file.exists() else header
        write(header)
        return 0
    unknown = [a for a in args if a not in known]
    if unknown:
        print(f"unknown rows: {' '.join(unknown)} (see --list)", file=sys.stderr)
        return 2
    LOGS.mkdir(parents=True, exist_ok=True)
    (ROOT / "target" / "benchmarks").mkdir(parents=True, exist_ok=True)
    machine_file.write_text(header)
    for row in [known[a] for a in args] if args else ROWS:
        run(row, quick)
    write(header)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

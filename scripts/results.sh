#!/usr/bin/env bash
# Regenerates the figures the guides quote, from one run, into one file: docs/results.md.
# Usage: scripts/results.sh [OUT]   (release build; reads ../shared/data; OUT defaults to
# docs/results.md)
#
# Each figure sits in a block between `<!-- result NAME -->` and `<!-- /result -->`. A guide
# quotes a table by copying its block, markers and all; tests/tests/results.rs checks that every
# copy equals this file's block, and recomputes the cheap rows (car6's) from the code, so neither
# a guide nor this file can drift unnoticed. Figures that vary by machine (wall time, resident
# memory) are kept apart, in the `times` block, with the machine they were measured on: the
# guides state them once in prose and no test asserts them.
#
# The benchmarks that take minutes to hours write their own tables: `mema bench` (performance.md),
# `scripts/bench.sh --only fidelity` (fidelity.md), `firmware-sim/check.sh` (firmware.md) and
# `scripts/board-fidelity.sh` (firmware.md).
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-docs/results.md}
cargo build --release -q -p mema
mema=$PWD/target/release/mema
data=../shared/data
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# The paper's Tables 2 and 4 (`mema map --paper`), and each run's time, as JSON lines.
runs=("car6.pcd 150" "bun_zipper.ply 100" "bun_zipper.ply 350" "five_people.pcd 350")
for run in "${runs[@]}"; do
  set -- $run
  /usr/bin/time -f '{"wall": %e, "rss_kb": %M}' -o "$tmp/time" \
    "$mema" map "$data/$1" -k "$2" --paper -o "$tmp/m.mema" --json 2>/dev/null > "$tmp/map.json"
  python3 - "$1" "$2" "$tmp/map.json" "$tmp/time" >> "$tmp/paper.jsonl" <<'EOF'
import json, sys
cloud, k, report, time = sys.argv[1], int(sys.argv[2]), sys.argv[3], sys.argv[4]
print(json.dumps({"cloud": cloud, "k": k, "report": json.load(open(report)),
                  "time": json.load(open(time))}))
EOF
done

# Every shared cloud read as `mema map` reads it: its slots, what was dropped, what was mapped;
# and the default map at 2,400 bytes (entities and file bytes).
for path in "$data"/*.{ply,pcd,las,laz}; do
  cloud=$(basename "$path")
  "$mema" map "$path" --bytes 2400 -o "$tmp/b.mema" --json 2>/dev/null > "$tmp/b.json"
  "$mema" info "$tmp/b.mema" --json > "$tmp/info.json"
  python3 - "$cloud" "$tmp/b.json" "$tmp/info.json" >> "$tmp/clouds.jsonl" <<'EOF'
import json, sys
print(json.dumps({"cloud": sys.argv[1], "report": json.load(open(sys.argv[2])),
                  "info": json.load(open(sys.argv[3]))}))
EOF
done

# The firmware's figures: firmware-sim/check.sh builds the 64 KiB image and the STM32F405 board,
# runs both under QEMU (-icount shift=0: instructions, not time) and prints their memory and
# instructions. MEMA_CHECK_LOG names the output of a check.sh run of this same checkout to use
# instead of running it again (it takes minutes).
if [ -n "${MEMA_CHECK_LOG:-}" ]; then
  cp "$MEMA_CHECK_LOG" "$tmp/check.txt"
else
  firmware-sim/check.sh > "$tmp/check.txt" 2>&1
fi

python3 - "$tmp/paper.jsonl" "$tmp/clouds.jsonl" "$tmp/check.txt" > "$out" <<'EOF'
import json, platform, os, sys

paper = [json.loads(l) for l in open(sys.argv[1])]
clouds = [json.loads(l) for l in open(sys.argv[2])]

def n(v):
    return f"{v:,}"

def block(name, lines):
    print(f"<!-- result {name} -->")
    print("\n".join(lines))
    print("<!-- /result -->")
    print()

print("# Results")
print()
print("Written by `scripts/results.sh` from one run; regenerate it rather than edit it. The guides")
print("copy its blocks, and `tests/tests/results.rs` checks every copy against this file.")
print()
print("## The paper's Tables 2 and 4")
print()
print("`mema map ../shared/data/<cloud> -k <k> --paper -o m.mema` (seed 0, alpha 0.8, threshold 4,")
print("DE with F 1.2, CR 0.7, population 10 and 50 generations).")
print()
rows = ["| cloud | k | points | cloud bytes | entities | map bytes | percent |",
        "|---|---|---|---|---|---|---|"]
for r in paper:
    m = r["report"]["memory"]
    rows.append(f"| `{r['cloud']}` | {r['k']} | {n(m['points'])} | {n(m['cloud_bytes'])} | "
                f"{n(m['entities'])} | {n(m['map_bytes'])} | {m['percent']:.4f}% |")
block("paper-table-2", rows)
rows = ["| cloud | k | map | mean | std | max | min | total |",
        "|---|---|---|---|---|---|---|---|"]
for r in paper:
    for i, fit in enumerate(["ellipsoidal", "spherical"]):
        e = r["report"][fit]
        head = f"| `{r['cloud']}` | {r['k']} |" if i == 0 else "| | |"
        rows.append(f"{head} {fit} | {e['mean']:.6f} | {e['std']:.6f} | {e['max']:.6f} | "
                    f"{e['min']:.6f} | {e['total']:.6f} |")
block("paper-table-4", rows)

print("## The shared clouds as `mema map` reads them, and their default maps at 2,400 bytes")
print()
print("`mema map ../shared/data/<cloud> --bytes 2400 -o m.mema --json`, then `mema info m.mema`:")
print("the input's slots, the points dropped for a NaN or infinite coordinate and by class (LAS")
print("noise and withheld), the finite points left (what `eval`, `draw` and `mema bench` read),")
print("those `map` drops as isolated (`--outliers`), the points mapped, and the map's entities and")
print("bytes in the file.")
print()
rows = ["| cloud | slots | NaN or infinite | by class | finite | isolated | mapped | entities | file bytes |",
        "|---|---|---|---|---|---|---|---|---|"]
for r in clouds:
    j, info = r["report"], r["info"]
    by_class = sum(j["dropped_by_class"].values())
    finite = j["slots"] - j["dropped_non_finite"] - by_class
    rows.append(f"| `{r['cloud']}` | {n(j['slots'])} | {n(j['dropped_non_finite'])} | "
                f"{n(by_class)} | {n(finite)} | {n(j['outliers']['dropped'])} | "
                f"{n(j['memory']['points'])} | {n(j['memory']['entities'])} | "
                f"{n(info['file_bytes'])} |")
block("clouds", rows)

check = open(sys.argv[3]).read().splitlines()

def after(line, key):
    """The number after `key` in `line`."""
    rest = line.split(key, 1)[1].strip()
    return rest.split()[0].rstrip(",;:)")

print("## The firmware (`firmware-sim/check.sh`)")
print()
print("The 64 KiB image (K = 400: 150 working + 250 frozen) under `qemu-system-arm -machine")
print("mps2-an386 -icount shift=0` on `mema scanner-sim`'s capture of car6 (10,031 points), and the")
print("STM32F405 board (K = 700: 150 working + 550 frozen) under QEMU's `netduinoplus2` behind")
print("`mema device`, on car6 and the demo drive. Instructions are counted by QEMU, not timed.")
print()
sections = {}
model = None
for line in check:
    if line.startswith("== firmware budget"):
        model = line.split("model ")[-1].rstrip(")")
        sections[model] = []
    elif model:
        sections[model].append(line)
paper_budget = sections["paper"]
rows = ["| K | working | frozen | mapper | decoder | ring | firmware state | under 64 KiB | and an 8 KiB stack |",
        "|---|---|---|---|---|---|---|---|---|"]
for line in paper_budget:
    cells = line.split()
    if len(cells) >= 13 and cells[0].isdigit() and "KiB" in line:
        k, working, frozen = cells[0], cells[1], cells[2]
        kib = [c for c in cells if c.replace(".", "").isdigit() and "." in c]
        fits, with_stack = cells[-2], cells[-1].strip("()")
        rows.append(f"| {k} | {working} | {frozen} | {kib[0]} KiB | {kib[1]} KiB | {kib[2]} KiB | "
                    f"{kib[3]} KiB | {fits} | {with_stack} |")
block("firmware-memory", rows)

rows = ["| model | flash: text | static RAM: data + bss | stack high-water: boot, ingest, finish | RAM in use |",
        "|---|---|---|---|---|"]
cost = ["| capture | model | ingest | finish | whole run |", "|---|---|---|---|---|"]
for model in ["paper", "shells"]:
    lines = sections[model]
    image = next(l for l in lines if l.startswith("image ("))
    ram = next(l for i, l in enumerate(lines) if l.strip().startswith("RAM in use") and lines[i - 1].startswith("image ("))
    stack = next(l for l in lines if "stack high-water: boot" in l)
    points = int(after(next(l for l in lines if l.startswith("QEMU mps2-an386")), f"model {model}:"))
    text = int(after(image, "(text"))
    bss = int(after(image, "(data + bss"))
    rows.append(f"| {model} | {n(text)} bytes | {n(bss)} bytes | {n(int(after(stack, 'boot')))}, "
                f"{n(int(after(stack, 'ingest ticks')))}, {n(int(after(stack, 'finish')))} B | "
                f"{after(ram, '=')} KiB |")
    per = next(l for l in lines if "instructions per ingested point:" in l)
    ingest = int(after(per, "point:"))
    finish = float(after(per, "encode):"))
    cost.append(f"| car6 ({n(points)} points) | {model} | {n(ingest)} | {finish:.2e}".replace("e+0", "e")
                + f" "
                f"({n(round(finish / points))} a point) | {n(round(ingest + finish / points))} |")
block("firmware-image", rows)
block("firmware-cost", cost)

rows = ["| capture | model | instructions a point | longest tick |", "|---|---|---|---|"]
queries = ["| model | nearest surface | ray cast |", "|---|---|---|"]
for line in check:
    if "instructions a point on the board" in line:
        capture, model = line.strip().split(":")[0].split(", ")
        name = "car6" if capture == "car6.pcd" else "demo drive"
        rows.append(f"| {name} | {model} | {n(int(after(line, ':')))} | {n(int(after(line, 'longest tick')))} |")
    if "queries on the board" in line:
        model = line.strip().split(":")[0].split(", ")[1]
        q = json.loads("{" + line.split("answer the host's: ", 1)[1] + "}")["queries"]
        queries.append(f"| {model} | {q['nearest_instructions'] / 1e6:.3g} million | "
                       f"{q['ray_instructions'] / 1e6:.3g} million |")
block("board-cost", rows)
block("board-queries", queries)

print("## Times")
print()
print("Wall time and peak resident memory of each Table 2 run (`/usr/bin/time`), on the machine")
print("below; they vary with the machine and its load, and no test asserts them.")
print()
rows = [f"Machine: {platform.machine()}, {os.cpu_count()} cores, load average "
        f"{os.getloadavg()[0]:.1f} at the end of the run.", "",
        "| cloud | k | wall | peak RSS |", "|---|---|---|---|"]
for r in paper:
    t = r["time"]
    rows.append(f"| `{r['cloud']}` | {r['k']} | {t['wall']:.2f} s | {t['rss_kb'] / 1000:.1f} MB |")
block("times", rows)
EOF
echo "wrote $out" >&2

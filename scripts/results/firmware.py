"""The firmware (docs/firmware.md): firmware-sim/check.sh's memory and instructions, the link
model's pacing, and the board's layout against the host's batch map."""

import json
import re

from common import block, n, sig, table


def after(line, key):
    """The number after `key` in `line`."""
    rest = line.split(key, 1)[1].strip()
    return rest.split()[0].rstrip(",;:)")


def budgets(check):
    """check.sh's `mema-firmware-sim budget` output, by model."""
    sections, model = {}, None
    for line in check:
        if line.startswith("== firmware budget"):
            model = line.split("model ")[-1].rstrip(")")
            sections[model] = []
        elif model:
            sections[model].append(line)
    return sections


def firmware(logs):
    check = logs.lines("check")
    out = ["## The firmware (`firmware-sim/check.sh`)", "",
           "The 64 KiB image (K = 400: 150 working + 250 frozen) under `qemu-system-arm -machine "
           "mps2-an386 -icount shift=0` on `mema scanner-sim`'s capture of car6 (10,031 points), "
           "and the STM32F405 board (K = 700: 150 working + 550 frozen) under QEMU's "
           "`netduinoplus2` behind `mema device`, on car6 and the demo drive. Instructions are "
           "counted by QEMU, not timed. " + logs.source("check"), ""]
    maps = []
    for line in check:
        m = re.match(r"\s+(\S+), (paper|shells): qemu = mema replay \((\d+) bytes\)", line)
        if m:
            capture = "car6" if m[1] == "car6.pcd" else "demo drive"
            maps.append([capture, m[2], n(int(m[3]))])
    out += block("firmware-maps", table(["capture", "model", "map bytes"], maps))
    sections = budgets(check)
    sizes = next(l for l in sections["paper"] if l.startswith("static RAM of the firmware state"))
    m = re.search(r"a working cluster is (\d+) bytes.*a frozen entity (\d+) bytes", sizes)
    out += block("firmware-sizes", table(["part (`size_of`)", "bytes"], [
        ["a working cluster", n(int(m[1]))], ["a frozen entity", n(int(m[2]))]]))
    rows = []
    for line in sections["paper"]:
        cells = line.split()
        if len(cells) >= 13 and cells[0].isdigit() and "KiB" in line:
            k, working, frozen = cells[0], cells[1], cells[2]
            kib = [c for c in cells if c.replace(".", "").isdigit() and "." in c]
            rows.append([k, working, frozen, *[f"{x} KiB" for x in kib[:4]], cells[-2],
                         cells[-1].strip("()")])
    fits = next(l for l in sections["paper"] if "K that fits 64 KiB" in l).strip()
    fits = fits.replace(" at this layout:", " with every cluster working:")
    sums = next(l for l in sections["paper"] if "the moment sums alone of" in l)
    sums = sums.split(";")[0].strip()
    out += block("firmware-memory", table(
        ["K", "working", "frozen", "mapper", "decoder", "ring", "firmware state",
         "under 64 KiB", "and an 8 KiB stack"], rows)
        + ["", f"{fits}; {sums}."])

    rows, cost = [], []
    for model in ["paper", "shells"]:
        lines = sections[model]
        image = next(l for l in lines if l.startswith("image ("))
        ram = next(l for i, l in enumerate(lines)
                   if l.strip().startswith("RAM in use") and lines[i - 1].startswith("image ("))
        stack = next(l for l in lines if "stack high-water: boot" in l)
        points = int(after(next(l for l in lines if l.startswith("QEMU mps2-an386")),
                           f"model {model}:"))
        rows.append([model, f"{n(int(after(image, '(text')))} bytes",
                     f"{n(int(after(image, '(data + bss')))} bytes",
                     f"{n(int(after(stack, 'boot')))}, {n(int(after(stack, 'ingest ticks')))}, "
                     f"{n(int(after(stack, 'finish')))} B", f"{after(ram, '=')} KiB"])
        per = next(l for l in lines if "instructions per ingested point:" in l)
        ingest = int(after(per, "point:"))
        finish = float(after(per, "encode):"))
        cost.append([f"car6 ({n(points)} points)", model, n(ingest),
                     f"{finish:.2e} ({n(round(finish / points))} a point)".replace("e+0", "e"),
                     n(round(ingest + finish / points))])
    ticks, board, board_ram = [], [], []
    for model in ["paper", "shells"]:
        lines = sections[model]
        t = next(l for l in lines if l.strip().startswith("ticks:"))
        m = re.search(r"ticks: (\d+); longest (\d+) instructions mapping points only "
                      r"\(at most (\d+)\), (\d+) with a fit", t)
        fill = next(l for l in lines if "ring fills in" in l)
        f = re.search(r"the (\d+)-byte ring fills in ([\d.]+) ms at 921,600 baud: (\d+) "
                      r"instructions at 168 MHz and 1.5 cycles each, ([\d.]+)x", fill)
        p = next(l for l in lines if l.strip().startswith("per point (point-only ticks)"))
        q = re.search(r"per point \(point-only ticks\) (\d+) instructions, per fit \(freeze or "
                      r"refit\) (\d+), per merge pass (\d+)", p)
        ticks.append([model, n(int(m[1])), n(int(m[2])), n(int(m[4])), f"{f[4]}x",
                      n(int(q[1])), n(int(q[2])), n(int(q[3]))])
        image = next(l for l in lines if l.startswith("board image ("))
        ram = next(l for i, l in enumerate(lines)
                   if l.strip().startswith("RAM in use") and lines[i - 1].startswith("board image"))
        board.append([model, f"{n(int(after(image, '(text')))} bytes",
                      f"{n(int(after(image, '(data + bss')))} bytes"])
        board_ram.append([model, f"{after(ram, 'high-water')} KiB", f"{after(ram, '=')} KiB"])
    ring = (f"The {n(int(f[1]))}-byte ring fills in {f[2]} ms at 921,600 baud: "
            f"{n(int(f[3]))} instructions at 168 MHz and 1.5 cycles an instruction.")
    out += block("firmware-ticks", table(
        ["model", "ticks", f"longest, points only (at most {m[3]})",
         "longest, with a fit or merge pass",
         "ring fill over the longest tick", "a point (point-only ticks)", "a fit",
         "a merge pass"], ticks) + ["", ring])
    out += block("board-image", table(["model", "flash: text", "static RAM: data + bss"], board))
    out += ["The board's stack high-water mark, and so its RAM in use, varies by a few bytes from "
            "run to run with QEMU's timing of its line (the 64 KiB image's, read over "
            "semihosting, does not):", ""]
    out += block("times-board-ram", [logs.machine("check"), ""] + table(
        ["model", "stack high-water", "RAM in use (of 128 KiB)"], board_ram))
    out += block("firmware-image", table(
        ["model", "flash: text", "static RAM: data + bss",
         "stack high-water: boot, ingest, finish", "RAM in use"], rows))
    out += block("firmware-cost", table(
        ["capture", "model", "ingest", "finish", "whole run"], cost))

    sessions, queries = {}, []
    for line in check:
        m = re.match(r"\s+(\S+), (paper|shells), (host|sensor): (\d+) instructions a point on the "
                     r"board, longest tick (\d+)", line)
        if m:
            capture = "car6" if m[1] == "car6.pcd" else "demo drive"
            sessions.setdefault((capture, m[2]), {})[m[3]] = (int(m[4]), int(m[5]))
        if "queries on the board" in line:
            model = line.strip().split(":")[0].split(", ")[1]
            q = json.loads("{" + line.split("answer the host's: ", 1)[1] + "}")["queries"]
            queries.append([model, f"{q['nearest_instructions'] / 1e6:#.3g} million",
                            f"{q['ray_instructions'] / 1e6:#.3g} million"])
    rows = [[capture, model, n(s["host"][0]), n(s["host"][1]),
             n(s["sensor"][0]) if "sensor" in s else "-"]
            for (capture, model), s in sessions.items()]
    out += ["The board's instructions a point and longest tick vary from run to run with QEMU's "
            "timing of the line, by a few per cent in a host's session (the carrier's passes and "
            "acknowledgements follow how the frames arrive) and by a fraction of a percent with a "
            "sensor on USART1: one run's, not asserted beyond check.sh's 10,000 a point.", ""]
    out += block("times-board-cost", [logs.machine("check"), ""] + table(
        ["capture", "model", "instructions a point", "longest tick",
         "with a sensor on USART1"], rows))
    out += block("board-queries", table(["model", "nearest surface", "ray cast"], queries))
    return out


def pacing(logs):
    out = ["## The link model's pacing", "",
           "`tests/tests/pacing.rs` (`cargo test --release -p mema-tests --test integration "
           "pacing`): each capture played at 921,600 baud into the image's layout at the "
           "prices given, the slowest rate that keeps up found by bisection; the test computes "
           "this block again and holds it equal. " + logs.source("pacing"), ""]
    lines = [l[len("pacing: "):] for l in logs.lines("pacing") if l.startswith("pacing: ")]
    return out + block("pacing", lines)


def board_fidelity(logs):
    out = ["## The board's layout against the batch map", "",
           "`scripts/board-fidelity.sh`: each shared cloud and registered set encoded as `mema "
           "scanner-sim` sends it, mapped as the board maps it (`mema replay -k K --working "
           "150`, and at K = 700 `--carve 124x512 --carve-every 2`, which the board equals byte "
           "for byte; a single cloud is one scan, which carving leaves whole, and a set's scans "
           "carve each other), then `mema map --bytes` of the same cloud or set at that map's "
           "size; both scored by `mema eval --samples 50000`, two-way Chamfer distance in mm. "
           + logs.source("board-fidelity"), ""]
    runs = {}
    for line in logs.lines("board-fidelity"):
        c = line.split()
        if len(c) == 7 and c[1].isdigit():
            runs.setdefault(c[0], {})[int(c[1])] = {
                "bytes": int(c[2]), "entities": int(c[3]), "board": float(c[4]),
                "batch": float(c[5]), "ratio": c[6]}
    rows = []
    for cloud, r in runs.items():
        a, b = r[400], r[700]
        name = cloud if cloud.endswith(".conf") else cloud.split(".")[0]
        rows.append([name, sig(a["board"]), sig(b["board"]), n(b["entities"]),
                     n(b["bytes"]), sig(b["batch"]), b["ratio"],
                     f"{b['board'] / a['board']:.2f}"])
    out += block("board-fidelity", table(
        ["cloud", "board K = 400", "board K = 700", "entities at 700", "bytes at 700",
         "batch map, same bytes", "board / batch", "K = 700 / 400"], rows))
    return out


def reference_runs(lines):
    """`mema-firmware-sim reference` runs by their arguments: per-cloud rows, worst, tolerances."""
    runs, args = {}, None
    for line in lines:
        if line.startswith("== reference"):
            args = line[len("== reference"):].strip()
            runs[args] = {"clouds": [], "worst": [], "tolerances": ""}
            continue
        c = line.split()
        r = runs.get(args)
        if r is None or not c:
            continue
        if len(c) >= 11 and c[1].isdigit():
            over = int(c[10]) if len(c) > 11 and c[11] == "over;" else 0
            r["clouds"].append({"cloud": c[0], "points": int(c[1]), "k": int(c[2]),
                                "small": int(c[3]), "flat": int(c[4]), "over": over,
                                "values": c[5:10]})
        elif line.startswith("tolerances (relative):"):
            r["tolerances"] = dict(x.strip().split(" ") for x in
                                   line.split(":", 1)[1].strip(" ;").split(";"))
        elif line.startswith("  ") and len(c) == 5 and c[2].startswith("("):
            r["worst"].append([c[0], c[1], c[2].strip("(,"), c[4].rstrip(")")])
    return runs


QUANTITIES = {
    "fitness_at_core_axes": "eq. 12 at the same semi-axes (moments vs direct sum)",
    "fitness_optimum": "eq. 12 at each side's DE optimum",
    "semi_axes": "semi-axes",
    "surface_error": "eq. 13 per cluster (own fit, own solver)",
    "surface_error_same_entity": "eq. 13, Eberly vs Newton on the same entity",
}


def reference(logs):
    runs = reference_runs(logs.lines("reference"))
    out = ["## The core against the f64 reference", "",
           "`mema-firmware-sim reference [-k K] [--working W] [--sum-bits N]`: every shared "
           "input the readers read, clustered by the streaming mapper (every point given to its "
           "nearest centre), each quantity against the independent f64 reference (nalgebra). "
           + logs.source("reference"), ""]
    base = runs[""]
    out += block("reference", table(
        ["cloud", "points", "clusters", "under 10 points", "flat optima", "over tolerance"],
        [[c["cloud"], n(c["points"]), c["k"], c["small"], c["flat"], c["over"]]
         for c in base["clouds"]]))
    out += block("reference-worst", table(
        ["quantity", "tolerance", "worst at k = 150", "where"],
        [[QUANTITIES.get(q, q), base["tolerances"].get(q, ""), v, f"{cloud.split('.')[0]}"]
         for q, v, cloud, _ in base["worst"]]))

    def over(r):
        bad = [c for c in r["clouds"] if c["over"]]
        return bad, sum(c["over"] for c in bad)

    rows = []
    for args in ["-k 400", "-k 400 --working 150"]:
        bad, entities = over(runs[args])
        rows.append([f"`reference {args}`", entities, len(bad),
                     ", ".join(f"{c['cloud'].split('.')[0]} {c['over']}" for c in bad) or "-"])
    out += block("reference-k400", table(
        ["run", "entities over tolerance", "clouds", "where"], rows))
    rows = []
    names = {24: "f32", 32: "a 40-bit float", 40: "a 48-bit float", 53: "f64, the core"}
    for bits in [24, 32, 40, 48, 52, 53]:
        bad, entities = over(runs[f"--sum-bits {bits}"])
        where = f" ({bad[0]['cloud'].split('.')[0]})" if len(bad) == 1 else ""
        rows.append([bits, names.get(bits, ""), f"{len(bad)}{where}", entities])
    out += block("reference-sum-bits", table(
        ["significant bits kept", "as in", "clouds over tolerance", "entities over"], rows))
    return out

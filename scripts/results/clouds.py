"""The paper's Tables 2 and 4 with their runs' times, and the shared clouds as `map` reads them."""

from common import block, n, table


def paper(logs):
    runs = [r for r in logs.jsonl("paper") if "cloud" in r]
    names = next(r for r in logs.jsonl("paper") if "names" in r)
    out = ["## The paper's Tables 2 and 4", "",
           "`mema map ../shared/data/<cloud> -k <k> --paper -o m.mema` (seed 0, alpha 0.8, "
           "threshold 4, DE with F 1.2, CR 0.7, population 10 and 50 generations). "
           + logs.source("paper"), ""]
    rows = []
    for r in runs:
        m = r["report"]["memory"]
        rows.append([f"`{r['cloud']}`", r["k"], n(m["points"]), n(m["cloud_bytes"]),
                     n(m["entities"]), n(m["map_bytes"]), f"{m['percent']:.4f}%"])
    out += block("paper-table-2", table(
        ["cloud", "k", "points", "cloud bytes", "entities", "map bytes", "percent"], rows))
    rows = []
    for r in runs:
        for i, fit in enumerate(["ellipsoidal", "spherical"]):
            e = r["report"][fit]
            head = [f"`{r['cloud']}`", r["k"]] if i == 0 else ["", ""]
            rows.append(head + [fit] + [f"{e[s]:.6f}" for s in
                                        ["mean", "std", "max", "min", "total"]])
    lines = table(["cloud", "k", "map", "mean", "std", "max", "min", "total"], rows)
    # Rows that continue a cloud leave its cells empty: `| | |`, as the guides have them.
    out += block("paper-table-4", [l.replace("|  |  |", "| | |") for l in lines])
    lower = [1 - r["report"]["ellipsoidal"]["total"] / r["report"]["spherical"]["total"]
             for r in runs]
    out += block("paper-table-4-summary", [
        f"The ellipsoidal total error is below the spherical one on {sum(x > 0 for x in lower)} "
        f"of {len(runs)} runs, by {100 * min(lower):.0f}-{100 * max(lower):.0f}%."])
    r, e, i = names["report"], names["eval"], names["info"]
    out += ["Two figures bear eq. 13's name, and two count bytes (`docs/command-line.md`, "
            "\"One name per figure\"): `mema map ../shared/data/bun_zipper.ply -k 150`, then "
            "`mema eval` and `mema info` of its map.", ""]
    out += block("one-figure", table(["figure", "bun_zipper.ply, k = 150"], [
        ["eq. 13 as fitted (`map`)", f"{r['ellipsoidal']['mean']:.6f} m"],
        ["eq. 13 by nearest centre (`eval`)", f"{e['mean']:.6f} m"],
        ["bytes in the file", n(i["file_bytes"])],
        ["map bytes", n(i["map_bytes"])],
        ["paper bytes", n(i["paper_bytes"])]]))
    out += ["Wall time and peak resident memory of each run (`/usr/bin/time`); they vary with "
            "the machine and its load, and no test asserts them.", ""]
    rows = [[f"`{r['cloud']}`", r["k"], f"{r['time']['wall']:.2f} s",
             f"{r['time']['rss_kb'] / 1000:.1f} MB"] for r in runs]
    out += block("times", [logs.machine("paper"), ""]
                 + table(["cloud", "k", "wall", "peak RSS"], rows))
    return out


def clouds(logs):
    out = ["## The shared clouds as `mema map` reads them, and their default maps at 2,400 bytes",
           "",
           "`mema map ../shared/data/<cloud> --bytes 2400 -o m.mema --json`, then `mema info "
           "m.mema`: the input's slots, the points dropped for a NaN or infinite coordinate and "
           "by class (LAS noise and withheld), the finite points left (what `eval`, `draw` and "
           "`mema bench` read), those `map` drops as isolated (`--outliers`), the points mapped, "
           "and the map's entities and bytes in the file. " + logs.source("clouds"), ""]
    rows = []
    for r in logs.jsonl("clouds"):
        j, info = r["report"], r["info"]
        by_class = sum(j["dropped_by_class"].values())
        finite = j["slots"] - j["dropped_non_finite"] - by_class
        rows.append([f"`{r['cloud']}`", n(j["slots"]), n(j["dropped_non_finite"]), n(by_class),
                     n(finite), n(j["outliers"]["dropped"]), n(j["memory"]["points"]),
                     n(j["memory"]["entities"]), n(info["file_bytes"])])
    out += block("clouds", table(
        ["cloud", "slots", "NaN or infinite", "by class", "finite", "isolated", "mapped",
         "entities", "file bytes"], rows))
    return out

"""The fidelity benchmark (docs/fidelity.md) and held-out rays against OctoMap (docs/queries.md)."""

import math
import re

from common import block, n, sig, table

METHODS = ["default", "paper", "gmm", "streamed"]


def cells(row):
    """A row's scored maps by method, or None for a map the budget could not make (or a run
    without that method)."""
    out = dict.fromkeys(METHODS)
    for c in row["cells"]:
        out[c["method"]] = c if "score" in c else None
    return out


def fidelity(logs):
    report = logs.json("fidelity")
    out = ["## Fidelity at equal bytes", "",
           "`scripts/bench.sh --only fidelity --gmm-cache target/gmm-cache --json`: every shared "
           "PLY, PCD, LAS and LAZ cloud (its finite points, in metres) and registered set (`.conf`: "
           "its scans in their common frame) at each budget B, as the "
           "default map (`mema map --bytes B`), the paper's (`--bytes B --paper`) and a "
           "converged Gaussian mixture of B / 40 components drawn as 2-sigma shells (these three "
           "made from the points `mema map` maps, its isolated ones left out), each "
           "written, read back and scored by `mema eval`'s two-way score (Chamfer distance in "
           "metres, phantom share of the map's area), and the streamed map a robot gets of the same "
           "input (sent as `mema scanner-sim` sends it, a set scan by scan with its poses, mapped by "
           "`mema map --stream -k B / 14`, "
           "at most 2,048 entities). " + logs.source("fidelity"), ""]
    pairs = wins_gmm = wins_paper = 0
    streamed_all = []
    for budget in report["budgets"]:
        rows, ratio_gmm, below_gmm, below_paper, streamed = [], [], 0, 0, []
        big, big_gmm, big_phantom = 0, 0, 0
        for row in (r for r in report["rows"] if r["budget"] == budget):
            c = cells(row)
            line = [f"`{row['cloud']}`", n(row["points"])]
            for m in METHODS:
                s = c[m]
                line.append("-" if s is None else
                            f"{n(s['entities'])}, {n(s['file_bytes'])}, "
                            f"{sig(s['score']['chamfer'])}, {100 * s['score']['phantom']:.0f}%")
            d, p, g, st = (c[m] and c[m]["score"] for m in METHODS)
            line.append(f"{d['chamfer'] / g['chamfer']:.2f}" if d and g else "-")
            line.append(f"{d['chamfer'] / p['chamfer']:.2f}" if d and p else "-")
            line.append(f"{st['chamfer'] / d['chamfer']:.2f}" if d and st else "-")
            if d and st:
                streamed.append((st["chamfer"] / d["chamfer"], row["cloud"]))
            rows.append(line)
            if d and g:
                ratio_gmm.append(d["chamfer"] / g["chamfer"])
                below_gmm += d["chamfer"] <= g["chamfer"]
            if d and p:
                below_paper += d["chamfer"] < p["chamfer"]
            if d and g and p and row["points"] >= 10_000:
                big += 1
                big_gmm += d["chamfer"] <= g["chamfer"]
                big_phantom += d["phantom"] < p["phantom"]
        clouds = len(rows)
        pairs += clouds
        wins_gmm += below_gmm
        wins_paper += below_paper
        mean = math.exp(sum(map(math.log, ratio_gmm)) / len(ratio_gmm))
        streamed_all += streamed
        out += [f"**B = {n(budget)} bytes**", ""]
        out += block(f"fidelity-{budget}", table(
            ["cloud", "points", "default: entities, bytes, Chamfer, phantom",
             "`--paper`: entities, bytes, Chamfer, phantom",
             "GMM: components, bytes, Chamfer, phantom",
             "streamed: entities, bytes, Chamfer, phantom", "default / GMM", "default / paper",
             "streamed / default"],
            rows) + ["", f"At {n(budget)} bytes: the default's Chamfer is at or below the GMM's "
                     f"on {below_gmm} of {clouds} inputs (geometric mean of default / GMM "
                     f"{mean:.2f}), below the paper's on {below_paper} of {clouds}; on the {big} "
                     f"inputs of at least 10,000 points it is at or below the GMM's on {big_gmm} "
                     f"and its phantom fraction below the paper's on {big_phantom}."
                     + streamed_sentence(streamed, budget)])
    over = sum(q > 1.2 for q, _ in streamed_all)
    out += block("fidelity-summary", [
        f"Over the {pairs} (input, budget) pairs the default's Chamfer distance is at or below "
        f"the GMM's on {wins_gmm} and below the paper's on {wins_paper}"
        + (f"; the streamed map's is within 1.2 times the default's on "
           f"{len(streamed_all) - over} of {len(streamed_all)}." if streamed_all else ".")])
    return out


def streamed_sentence(streamed, budget):
    """The streamed map against the default at one budget: geometric mean and worst cloud."""
    if not streamed:
        return ""
    mean = math.exp(sum(math.log(q) for q, _ in streamed) / len(streamed))
    worst, cloud = max(streamed)
    return (f" The streamed map's Chamfer is {mean:.2f} times the default's (geometric mean "
            f"over {len(streamed)} inputs; at most {worst:.2f}, `{cloud}`).")


def free_space(logs):
    out = ["## Held-out rays against OctoMap", "",
           "`scripts/bench.sh --only free-space`: `mema map` of sweeps 0 and 2 of "
           "`ouster_os1.conf`, sweep 1's rays cast at it, and OctoMap (pyoctomap) built from the "
           "same points and sensor origins at the finest resolution that fits the same bytes, "
           "both scored by one function. " + logs.source("free-space"), ""]
    rows, times, header, about = [], [], None, ""
    for line in logs.lines("free-space"):
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if line.startswith("free space:"):
            about = line
        elif line.startswith("| map |"):
            header = cells
        elif header and len(cells) == len(header) and not cells[0].startswith("---"):
            rows.append(cells[:-1])
            times.append([cells[0], n(int(round(float(cells[-1]), -3)))])
    mapped, no_returns, rays = map(int, re.search(
        r"\((\d+) points, (\d+) no-returns left out\), sweep 1's (\d+) rays", about).groups())
    out += block("free-space", [
        f"Sweeps 0 and 2 mapped: {n(mapped)} points ({n(no_returns)} no-returns left out); "
        f"sweep 1's {n(rays)} rays cast again.", ""] + table(header[:-1], rows))
    out += block("times-free-space", [logs.machine("free-space"), ""]
                 + table(["map", "ingest points/s"], times))
    return out

"""Streamed maps (docs/streaming.md): against the batch map, the bunny's posed scans, the drive."""

from common import block, n, table


def chamfers(logs, name):
    """The rows of scripts/stream_vs_batch.sh's table: input, streamed and batch Chamfer, their
    ratio, and both phantom shares (as one cell)."""
    rows = {}
    for line in logs.lines(name):
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 6 and cells[0].startswith("`"):
            rows[cells[0]] = (float(cells[1]), float(cells[2]), float(cells[4].rstrip("%")),
                              float(cells[5].rstrip("%")), cells[1], cells[2], cells[3],
                              f"{cells[4]} / {cells[5]}")
    return rows


def recast(scan, mapped, r, chamfer):
    return [scan, mapped, n(r["rays"]), n(r["rays_hit_both"]), n(r["rays_scene_only"]),
            n(r["rays_map_only"]), f"{1000 * r['range_median_abs']:.1f} mm",
            f"{1000 * r['range_p95_abs']:.1f} mm", chamfer]


def streaming(logs):
    out = ["## Streamed maps", "",
           "Every shared cloud and registration set sent as `mema scanner-sim` sends it, mapped by "
           "`mema replay -k K` and by `mema map -k K` (both shells), scored two ways by `mema eval`: "
           "two-way Chamfer distance (m), and the phantom share of each map's surface area "
           "(`scripts/stream_vs_batch.sh K`). "
           + logs.source("stream-vs-batch-400", "stream-vs-batch-150"), ""]
    at400, at150 = chamfers(logs, "stream-vs-batch-400"), chamfers(logs, "stream-vs-batch-150")
    rows = [[i, *at400[i][4:], *at150[i][4:]] for i in at400]
    summary = []
    for k, runs in [(400, at400), (150, at150)]:
        ratios = [s / b for s, b, *_ in runs.values()]
        below = sum(s < b for s, b, *_ in runs.values())
        phantom = sum(sp <= bp for _, _, sp, bp, *_ in runs.values())
        summary.append(f"at k = {k} the streamed map's Chamfer distance is {min(ratios):.2f} to "
                       f"{max(ratios):.2f} times the batch map's, below it on {below} of "
                       f"{len(ratios)} inputs, and its phantom share at or below the batch "
                       f"map's on {phantom}")
    out += block("stream-vs-batch", table(
        ["input", "streamed, k = 400", "batch, k = 400", "ratio", "phantom, streamed / batch",
         "streamed, k = 150", "batch, k = 150", "ratio", "phantom, streamed / batch"], rows)
        + ["", summary[0][0].upper() + summary[0][1:] + "; " + summary[1] + "."])

    runs = {r["run"]: r for r in logs.jsonl("streaming")}
    m = runs["multiview"]
    out += ["The bunny's five scans streamed with their poses (`mema map bun.conf --stream -k "
            "400`, the bytes `scanner-sim --conf` into `stream` gives) against the batch map of "
            "the registered scans at as many entities (`mema map bun.conf -k K`), both scored "
            "against `bun_zipper.ply` by `mema eval`; the demo drive (`mema demo --moving "
            "--json`) re-cast at its streamed map beside the static scan re-cast at its batch "
            "map (`mema query-bench --json`). " + logs.source("streaming"), ""]
    s, b = m["stream"]["chamfer"], m["batch"]["chamfer"]
    out += block("stream-multiview", table(
        ["input", "streamed entities", "streamed Chamfer", "batch Chamfer, same k", "ratio"],
        [["`bun.conf`", m["k"], f"{1000 * s:.3f} mm", f"{1000 * b:.3f} mm", f"{s / b:.2f}x"]]))
    d = runs["drive"]["demo"]
    static = runs["static"]["bench"]
    out += block("stream-drive", table(
        ["scan", "map", "rays", "hit both", "only the scene", "only the map",
         "range error median", "95th percentile", "Chamfer vs its points"],
        [recast("static (one pose)", "batch, k = 250 (`mema query-bench`)", static, ""),
         recast(f"drive ({d['stops']} poses, {n(d['points'])} points)",
                f"streamed, {d['entities']} entities (`mema demo --moving`)", d["recast"],
                f"{1000 * d['score']['chamfer']:.1f} mm")]))
    return out

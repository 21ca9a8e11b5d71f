"""Automatic k (docs/tolerance.md), queries (docs/queries.md) and the ablation (docs/design.md)."""

from common import block, n, pct, table


def tolerance(logs):
    runs = logs.jsonl("tolerance")
    by = {(r["cloud"], r["model"]): r for r in runs}
    clouds = list(dict.fromkeys(r["cloud"] for r in runs))
    out = ["## Automatic k (`--tolerance`)", "",
           "For each cloud, T is the largest per-cluster eq. 13 error of the paper's map at the "
           "cloud's fixed k (`mema map CLOUD -k K --paper --json`, `ellipsoidal.max`); then "
           "`mema map CLOUD --tolerance T [--paper] [--voronoi-rounds 4] --json -o OUT` and "
           "`mema eval CLOUD OUT --json` of each map, and `mema stream-bench CLOUD -k 2048 "
           "--tolerance T --model paper --json`. " + logs.source("tolerance"), ""]

    def k_of(r):
        return r["map"]["k"]

    def fewer(r):
        return pct(1 - k_of(r) / r["k"])

    def worst(r):
        return f"{max(r['map']['errors']):.6f}"

    rows, times, ratios = [], [], []
    for c in clouds:
        p, s, v = by[(c, "paper")], by[(c, "shells")], by[(c, "voronoi")]
        ratios.append(k_of(p) / k_of(s))
        rows.append([f"`{c}`", p["k"], f"{p['tolerance']:.6f}",
                     f"{k_of(p)}, {fewer(p)}, {worst(p)}", f"{k_of(s)}, {fewer(s)}, {worst(s)}",
                     f"{p['eval']['accuracy']['rms']:.3g} / {s['eval']['accuracy']['rms']:.3g}",
                     f"{p['eval']['chamfer']:.3g} / {s['eval']['chamfer']:.3g}",
                     k_of(v), fewer(v)])
        times.append([f"`{c}`", f"{p['time']['wall']:.1f} s", f"{s['time']['wall']:.1f} s",
                      f"{v['time']['wall']:.1f} s"])
    out += block("tolerance", table(
        ["cloud", "fixed k", "T", "`--paper`: k, fewer, max `e_i`", "shells: k, fewer, max `e_i`",
         "eval accuracy RMS, `--paper` / shells", "Chamfer, `--paper` / shells",
         "k with `--paper --voronoi-rounds 4`", "fewer"], rows)
        + ["", f"Shells meet the same T with {min(ratios):.0f} to {max(ratios):.0f} times fewer "
           "entities than the paper's fits."])
    out += block("times-tolerance", [logs.machine("tolerance"), ""] + table(
        ["cloud", "`--paper`", "shells", "`--paper --voronoi-rounds 4`"], times))

    rows, after = [], []
    for c in clouds:
        e = by[(c, "paper")]["eval"]
        rows.append([f"`{c}`", f"{e['mean']:.3g}", f"{e['max']:.3g}"])
        v = by[(c, "voronoi")]
        after.append([f"`{c}`", f"{v['eval']['max']:.4g}",
                      f"{v['eval']['max'] / v['tolerance']:.2f}"])
    out += block("tolerance-nearest-centre", table(["cloud", "eval mean", "eval max"], rows))
    out += block("tolerance-voronoi", table(
        ["cloud", "eval max after 4 rounds", "over T"], after))

    rows, times, over = [], [], []
    for c in clouds:
        b = by[(c, "stream")]["bench"]
        t = by[(c, "stream")]["tolerance"]
        over.append(b["stream_max_error"] / t)
        rows.append([f"`{c}`", b["stream_entities"], f"{b['stream_max_error']:.3g}",
                     f"{b['stream_max_error'] / t:.2f}"])
        times.append([f"`{c}`", f"{b['mapper_points_per_s'] / 1e6:.2f} M"])
    out += block("tolerance-stream", table(["cloud", "k", "eval max", "over T"], rows)
                 + ["", f"Streaming tolerance maps land within {min(over):.1f}-{max(over):.1f}x "
                    "of T by eval's rule."])
    out += block("times-tolerance-stream", [logs.machine("tolerance"), ""] + table(
        ["cloud", "stream ingest, points/s (one thread)"], times))
    return out


def queries(logs):
    out = ["## Queries", "",
           "`mema map CLOUD -k K -o MAP`, then `mema query-bench MAP --json` (100,000 random "
           "points, each asked nearest, occupancy and a ray, through the index and by brute "
           "force). " + logs.source("queries"), ""]
    rows, times = [], []
    runs = logs.jsonl("queries")
    for r in runs:
        b = r["bench"]
        name = f"{r['cloud'].split('.')[0]}, k = {n(r['k'])}"
        if r["cloud"] == "demo":
            name = "the demo scene, k = 250"
        rows.append([name, n(b["entities"]), n(b["queries"]), b["disagreements"]])
        times.append([name, n(int(round(b["index_queries_per_s"], -2))),
                      n(int(round(b["brute_force_queries_per_s"], -2))), f"{b['speedup']:.1f}x"])
    out += block("queries", table(["map", "entities", "queries", "disagreements"], rows))
    out += block("times-queries", [logs.machine("queries"), ""] + table(
        ["map", "index queries/s", "brute force queries/s", "ratio"], times))
    d = runs[-1]["bench"]
    out += ["Without a map, `mema query-bench` maps the demo scene at k = 250 and casts every ray "
            "of its scan at the map, against the scene's exact ranges (over the rays that hit "
            "both):", ""]
    out += block("queries-demo", table(
        ["rays", "hit both", "only the scene", "only the map", "range RMSE", "median",
         "95th percentile"],
        [[n(d["rays"]), n(d["rays_hit_both"]), n(d["rays_scene_only"]), n(d["rays_map_only"]),
          f"{d['range_rmse']:.2f} m", f"{100 * d['range_median_abs']:.1f} cm",
          f"{100 * d['range_p95_abs']:.0f} cm"]]))
    return out


# The ablation's variants as docs/design.md names them, in the command's order.
VARIANTS = {
    "default (spread 0.05-3 s linear, clamp, exact, seeded)":
        "**default**: spread box `[0.05 s, 3 s]`, linear, clamp, exact eq. 12, seeded",
    "bounds threshold (0.05 s to threshold, ln r)": "bounds threshold `[0.05 s, 4 m]`, in ln r",
    "bounds spread 0.05-10 s (linear)": "bounds spread `[0.05 s, 10 s]`, linear",
    "out-of-bounds reflect": "out-of-bounds reflect",
    "out-of-bounds resample": "out-of-bounds resample",
    "volume spread-relative": "volume spread-relative",
    "init random (paper)": "init random (the paper)",
    "init random, resample": "init random + resample",
}


def short(cloud):
    return {"bun_zipper": "bunny"}.get(cloud.split(".")[0], cloud.split(".")[0])


def exp1(x):
    """One significant digit in exponent form, as `1e-8`."""
    mantissa, exponent = f"{x:.0e}".split("e")
    return f"{mantissa}e{int(exponent)}"


def ablation(logs):
    runs = logs.jsonl("ablation")
    out = ["## The choices the paper leaves open", "",
           "`mema ablation ../shared/data/<cloud> -k <k> --json`: the clusters made once, each "
           "variant's fit of them. " + logs.source("ablation"), ""]
    header = ["variant"] + [f"{short(r['cloud'])} k={r['k']}" for r in runs]
    names = [v["variant"] for v in runs[0]["ablation"]]
    rows = []
    for i, name in enumerate(names):
        row = [VARIANTS.get(name, name)]
        for r in runs:
            v = r["ablation"][i]
            row.append(f"{v['ellipsoid_mean']:.6f}" if i == 0 else f"{v['change_percent']:+.1f}%")
        rows.append(row)
    out += block("ablation", table(header, rows))

    def col(name, key):
        i = names.index(name)
        return [(r, r["ablation"][i][key]) for r in runs]

    out += block("ablation-volume", table(
        ["cloud", "k", "volume share of eq. 12"],
        [[short(r["cloud"]), r["k"], exp1(x)] for r, x in col(names[0], "volume_share")]))
    random = col("init random (paper)", "ellipsoid_worse_than_sphere_percent")
    resample = col("init random, resample", "ellipsoid_worse_than_sphere_percent")
    out += block("ablation-random-starts", table(
        ["cloud", "k", "random starts", "random starts + resample"],
        [[short(r["cloud"]), r["k"], f"{a:.1f}%", f"{b:.1f}%"]
         for (r, a), (_, b) in zip(random, resample)]))

    def span(values, digits=1):
        low, high = f"{min(values):.{digits}f}", f"{max(values):.{digits}f}"
        return low if low == high else f"{low}-{high}"

    def signed(values):
        low, high = f"{min(values):+.1f}%", f"{max(values):+.1f}%"
        return low if low == high else f"{low} to {high}"

    repair = [abs(x) for name in names[1:5] for _, x in col(name, "change_percent")]
    change_random = [x for _, x in col("init random (paper)", "change_percent")]
    upper = [x for _, x in col(names[0], "on_upper_bound_percent")]
    degenerate = [x for _, x in col(names[1], "degenerated_percent")]
    threshold = [x for _, x in col(names[1], "change_percent")]
    spread_share = [x for _, x in col("volume spread-relative", "volume_share")]
    spread_change = [-x for _, x in col("volume spread-relative", "change_percent")]
    seeded_worse = [x for _, x in col(names[0], "ellipsoid_worse_than_sphere_percent")]
    out += block("ablation-summary", [
        f"- With the seeded start, the box and the repair rule move the mean eq. 13 error by at "
        f"most {max(repair):.1f}%; random starts move it by {signed(change_random)}.",
        f"- With the default box, the thinnest axis ends on the upper bound in "
        f"{span(upper, 0)}% of clusters; the threshold box lets {span(degenerate, 0)}% of "
        f"clusters degenerate, and changes the error by {signed(threshold)}.",
        f"- The spread-relative volume term is {span(spread_share, 2)} of the fitness and "
        f"lowers the mean eq. 13 error by {span(spread_change, 0)}%.",
        f"- Seeded, the ellipsoid's eq. 12 is worse than the sphere's on "
        f"{span(seeded_worse)}% of clusters."])
    return out


def surface(logs):
    runs = logs.jsonl("surface")
    out = ["## Surface following", "",
           "`mema map CLOUD --bytes 9600 -o m.mema` with its default 30 rounds of surface "
           "following and with `--surface-rounds 0` (the k-means cells), each scored by `mema "
           "eval CLOUD m.mema --json` and timed by `/usr/bin/time`. " + logs.source("surface"), ""]
    by = {(r["cloud"], r["rounds"]): r for r in runs}
    clouds = list(dict.fromkeys(r["cloud"] for r in runs))
    rows, times = [], []
    for c in clouds:
        on, off = by[(c, 30)], by[(c, 0)]
        a, b = on["eval"]["chamfer"], off["eval"]["chamfer"]
        rows.append([f"`{c}`", n(on["eval"]["points"]), f"{a:.3g}", f"{b:.3g}",
                     f"{100 * (1 - a / b):.0f}%"])
        times.append([f"`{c}`", f"{on['time']['wall']:.2f} s", f"{off['time']['wall']:.2f} s",
                      f"{on['time']['rss_kb'] / 1000:.0f} MB"])
    out += block("surface-following", table(
        ["cloud", "points", "Chamfer (m)", "`--surface-rounds 0`", "lower by"], rows))
    out += block("times-surface-following", [logs.machine("surface"), ""] + table(
        ["cloud", "`mema map --bytes 9600`", "`--surface-rounds 0`", "peak resident"], times))
    return out

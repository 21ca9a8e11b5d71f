"""`mema bench` (docs/performance.md): fitness, k-means and the pipeline; the Python route; the
targets of issue 5; pictures and meshes."""

from common import block, n, table


def section(lines, number):
    """The lines of benchmark `number` in `mema bench`'s output, heading and column line aside."""
    start = next(i for i, l in enumerate(lines) if l.startswith(f"{number}. "))
    rows = []
    for line in lines[start + 2:]:
        if not line.strip() or line[0].isdigit() and line[1] == ".":
            break
        rows.append(line)
    return rows


def fitness(lines):
    rows = []
    for line in section(lines, 1):
        c = line.split()
        if c[0].isdigit():
            rows.append({"size": int(c[0]), "direct": float(c[1]), "moments": float(c[2]),
                         "ratio": c[3], "rel": c[4], "build": float(c[5]), "fit": float(c[6]),
                         "f64": float(c[7]), "speedup": c[8]})
    return rows


def kmeans(lines):
    rows = []
    for line in section(lines, 2):
        if line.startswith("("):
            continue
        name, rest = line[:20].strip(), line[20:].split()
        full = name.endswith("(full)")
        rows.append({"cloud": name.split(" (")[0], "label": name, "n": int(rest[0]),
                     "k": int(rest[1]), "iterations": int(rest[2]), "full": full,
                     "plain": None if full else float(rest[3]), "one": float(rest[4]),
                     "two": float(rest[5]), "searched": rest[-1] if full else rest[-2],
                     "same": "" if full else rest[-1]})
    return rows


def pipeline(lines):
    rows, stages = [], {}
    for line in section(lines, 3):
        if line.startswith("("):
            continue
        c = line.split()
        if "heap peak by stage" in line:
            stages[rows[-1]["cloud"]] = [x.rstrip(",") for x in c[-7::2]]
        elif "threads:" in line:
            rows[-1]["faster"] = c[2]
        elif len(c) == 16 and c[1].isdigit():
            rows.append({"cloud": c[0], "n": int(c[1]), "k": int(c[2]), "threads": int(c[3]),
                         "wall": float(c[4]), "shares": c[5:9], "cloud_mb": c[9], "heap": c[10],
                         "heap_c": c[11], "hwm": c[12], "hwm_c": c[13], "above": c[14],
                         "same": c[15]})
    return rows, stages


def name_of(cloud):
    return f"`{cloud}`" if "." in cloud else cloud


def ms(x):
    return f"{x:,.0f} ms" if x >= 1000 else f"{x:.1f} ms"


def bench(logs):
    lines = logs.lines("bench")
    out = ["## Benchmarks 1-3 (`mema bench`)", "",
           "`mema bench --data ../shared/data`, release build; each timing the fastest of 3 runs. "
           "The benchmarks read each cloud's finite points, as `eval` does (`map`'s `--outliers` "
           "filter is not in them); the environment is nine of the shared PLY and PCD clouds side by "
           "side. " + logs.source("bench"), ""]
    fit = fitness(lines)
    out += block("bench-fitness", table(
        ["\\|S\\|", "max relative difference, moments vs direct"],
        [[n(r["size"]), r["rel"]] for r in fit]))
    out += block("times-bench-fitness", [logs.machine("bench"), ""] + table(
        ["\\|S\\|", "direct (ns/eval)", "moments (ns/eval)", "ratio",
         "building the moments (µs)", "one DE fit (µs)", "the f64 DE fit (µs)", "speedup"],
        [[n(r["size"]), f"{r['direct']:,.1f}", f"{r['moments']:.1f}", r["ratio"],
          f"{r['build']:.1f}", f"{r['fit']:.2f}", f"{r['f64']:.2f}", r["speedup"]]
         for r in fit]))

    km = kmeans(lines)
    label = {"environment": "environment (3 iterations)"}
    rows, times = [], []
    for r in km:
        cloud = ("environment (to convergence)" if r["full"]
                 else label.get(r["cloud"], name_of(r["cloud"])))
        rows.append([cloud, n(r["n"]), n(r["k"]), r["iterations"], r["searched"],
                     r["same"] or "-"])
        times.append([cloud, "-" if r["full"] else ms(r["plain"]), ms(r["one"]), ms(r["two"]),
                      "" if r["full"] else f"{r['plain'] / r['one']:.0f}x",
                      "" if r["full"] else f"{r['plain'] / r['two']:.0f}x"])
    out += block("bench-kmeans", table(
        ["cloud", "n", "k", "iterations", "visits searched", "same bits"], rows))
    out += block("times-bench-kmeans", [logs.machine("bench"), ""] + table(
        ["cloud", "plain", "accelerated, 1 thread", "accelerated, 2 threads", "ratio (1 thread)",
         "ratio (2 threads)"], times))

    runs, stages = pipeline(lines)
    rows, times = [], []
    for r in runs:
        first = r["threads"] == 1
        if first:
            twin = next(x for x in runs if x["cloud"] == r["cloud"] and x["threads"] == 2)
            rows.append([name_of(r["cloud"]), n(r["n"]), n(r["k"]), f"{r['cloud_mb']} MB",
                         twin["same"]])
        times.append([name_of(r["cloud"]) if first else "", n(r["n"]) if first else "",
                      n(r["k"]) if first else "", r["threads"], ms(r["wall"]), *r["shares"],
                      f"{r['heap']} MB", r["heap_c"], f"{r['hwm']} MB", r["hwm_c"], r["above"]])
    out += block("bench-pipeline", table(
        ["cloud", "n", "k", "cloud (12 bytes a point)", "2 threads' map = 1 thread's"], rows))
    lines_t = table(["cloud", "n", "k", "threads", "wall", "read", "k-means", "fit", "eval",
                     "heap", "heap / cloud", "VmHWM", "VmHWM / cloud",
                     "above pre-read / cloud"], times)
    out += block("times-bench-pipeline", [logs.machine("bench"), ""]
                 + [l.replace("|  |  |  |", "| | | |") for l in lines_t])
    out += block("times-bench-stages", [logs.machine("bench"), ""] + table(
        ["cloud", "2 threads over 1", "read", "k-means", "fit", "eval"],
        [[name_of(c), runs[2 * i + 1].get("faster", ""), *s]
         for i, (c, s) in enumerate(stages.items())]))
    return out


def python(logs):
    lines = logs.lines("python")
    out = ["## Against the Python route", "",
           "`scripts/bench.sh --only python`: `scripts/bench_python.py` (numpy, scikit-learn's "
           "`KMeans`, a numpy DE) against mema's read + k-means + fit on the same points, mema on "
           "2 threads. " + logs.source("python"), ""]
    rows, times = [], []
    for line in section(lines, 4):
        c = line.split()
        if len(c) != 12 or not c[1].isdigit():
            continue
        name = name_of(c[0])
        rows.append([name, n(int(c[1])), n(int(c[2])), c[7]])
        times.append([name, c[3].split(".")[0], f"{float(c[4]):.2f} s", f"{float(c[5]):.2f} s",
                      f"{float(c[6]):.2f} s", f"{float(c[8]):.3f} s", f"{float(c[9]):.3f} s",
                      f"{float(c[10]):.3f} s", c[11]])
    out += block("bench-python", table(["cloud", "n", "k", "mema: k-means iterations"], rows))
    out += block("times-bench-python", [logs.machine("python"), ""] + table(
        ["cloud", "Python: k-means iterations", "k-means", "fit", "total", "mema: k-means",
         "fit", "total", "ratio"], times))
    return out


def draw(logs):
    runs = {r["run"]: r for r in logs.jsonl("draw")}
    out = ["## Pictures and meshes", "",
           "`mema draw ../shared/data/office1.pcd MAP -o P.png --json` of its maps at k = 16,384 "
           "and 500, and `mema export` of the bunny's map at k = 4,000 to glTF, each under "
           "`/usr/bin/time`. " + logs.source("draw"), ""]
    d = runs["draw o16k"]["report"]["panels"][0]["cost"]
    out += block("draw-office1", table(
        ["map", "entities", "rays", "hits", "rows"],
        [["office1, k = 16,384", n(d["entities"]), n(d["rays"]), n(d["hits"]), n(d["rows"])]]))
    x = runs["export b4k"]["report"]
    rows = []
    for name, label in [("draw o16k", f"`draw`, {n(d['entities'])} entities"),
                        ("draw o500", "`draw`, "
                         f"{n(runs['draw o500']['report']['panels'][0]['entities'])} entities"),
                        ("export b4k", f"`export` to glTF, {n(x['entities'])} entities "
                                       f"({x['bytes'] / 1e6:.0f} MB)")]:
        t = runs[name]["time"]
        rows.append([label, f"{t['user']:.2f} s", f"{t['wall']:.2f} s",
                     f"{t['rss_kb'] / 1000:.1f} MB"])
    out += block("times-draw", [logs.machine("draw"), ""] + table(
        ["run", "CPU (user)", "wall", "peak resident"], rows))
    return out

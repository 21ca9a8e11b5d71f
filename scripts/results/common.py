"""Helpers shared by the sections of docs/results.md (scripts/results.sh, render.py)."""

import json
import math
import os


def n(v):
    """A count with thousands separated by commas, as the guides write them."""
    return f"{v:,}"


def sig(x):
    """Three significant digits, as `mema bench --only fidelity` prints its lengths."""
    if not math.isfinite(x):
        return f"{x}"
    if x == 0:
        return "0"
    magnitude = math.floor(math.log10(abs(x)))
    if not -6 <= magnitude <= 6:
        return f"{x:.2e}"
    return f"{x:.{max(2 - magnitude, 0)}f}"


def pct(x, digits=0):
    return f"{100 * x:.{digits}f}%"


def block(name, lines):
    """A result block: what a guide copies, markers and all."""
    return [f"<!-- result {name} -->", *lines, "<!-- /result -->", ""]


def table(header, rows):
    """A markdown table from a header and rows of cells."""
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return lines


class Logs:
    """The logs of one scripts/results.sh run, each with its meta (command, commit, time)."""

    def __init__(self, directory):
        self.dir = directory

    def path(self, name, ext="log"):
        return os.path.join(self.dir, f"{name}.{ext}")

    def has(self, name):
        return os.path.exists(self.path(name))

    def text(self, name):
        with open(self.path(name)) as f:
            return f.read()

    def lines(self, name):
        return self.text(name).splitlines()

    def jsonl(self, name):
        return [json.loads(line) for line in self.lines(name) if line.strip()]

    def json(self, name):
        return json.loads(self.text(name))

    def meta(self, name):
        with open(self.path(name, "meta")) as f:
            return json.load(f)

    def source(self, *names):
        """When and at which commit the logs of a section were made, and how long they took."""
        metas = [self.meta(name) for name in names]
        commits = sorted({m["commit"] for m in metas})
        dates = sorted({m["date"] for m in metas})
        seconds = sum(m["seconds"] for m in metas)
        took = f"{seconds:.0f} s" if seconds < 600 else f"{seconds / 60:.0f} minutes"
        # A log given whole (MEMA_CHECK_LOG) took no time of this run's.
        took = f"it took {took}" if seconds >= 1 else "its output given, not timed here"
        return (f"Run at commit {', '.join(commits)} on {', '.join(dates)}; {took} "
                f"(`scripts/results.sh` log{'s' if len(names) > 1 else ''} "
                f"{', '.join(f'`{x}`' for x in names)}).")

    def machine(self, *names):
        """The machine and its load during these runs, as every times block states them."""
        loads = [x for name in names for x in self.meta(name)["load"]]
        return (f"Measured on {self.meta(names[0])['machine']}, load average {min(loads):.1f} "
                f"to {max(loads):.1f} (start and end of each run).")

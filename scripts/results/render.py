"""Writes docs/results.md from the logs of one scripts/results.sh run.

Usage: render.py LOGS PREVIOUS KEEP   (KEEP: sections to copy from PREVIOUS, comma-separated)

Each section of the file sits between `<!-- section NAME -->` and `<!-- /section -->`, so a
section kept (MEMA_RESULTS_KEEP) is copied whole, with the run and commit it names."""

import os
import re
import sys

sys.path.insert(0, os.path.dirname(__file__))

import bench  # noqa: E402
import clouds  # noqa: E402
import fidelity  # noqa: E402
import firmware  # noqa: E402
import mapping  # noqa: E402
import readme  # noqa: E402
import streaming  # noqa: E402
from common import Logs  # noqa: E402


def kept_sections(text):
    return {m[1]: m[2] for m in re.finditer(
        r"<!-- section (\S+) -->\n(.*?)<!-- /section -->\n", text, re.S)}


def main():
    logs, previous, keep = Logs(sys.argv[1]), sys.argv[2], sys.argv[3].split(",")
    with open(previous) as f:
        old = kept_sections(f.read())

    sections = [
        ("paper", clouds.paper), ("clouds", clouds.clouds), ("fidelity", fidelity.fidelity),
        ("surface", mapping.surface), ("tolerance", mapping.tolerance), ("ablation", mapping.ablation),
        ("queries", mapping.queries), ("free-space", fidelity.free_space),
        ("streaming", streaming.streaming), ("board-fidelity", firmware.board_fidelity),
        ("firmware", firmware.firmware), ("pacing", firmware.pacing),
        ("reference", firmware.reference),
        ("python", bench.python), ("bench", bench.bench), ("draw", bench.draw),
    ]
    body = []
    for name, make in sections:
        if name in keep:
            if name not in old:
                sys.exit(f"render.py: MEMA_RESULTS_KEEP names `{name}`, which {previous} lacks")
            text = old[name]
        else:
            made = make(logs)
            lines = made[0] if isinstance(made, tuple) else made
            text = "\n".join(lines).rstrip("\n") + "\n\n"
        body.append(f"<!-- section {name} -->\n{text}<!-- /section -->\n\n")
    text = "".join(body)
    head = ["# Results", "",
            "Written by `scripts/results.sh` from the logs of one run; regenerate it rather than "
            "edit it. The guides copy its blocks, and `tests/tests/results.rs` checks every copy "
            "against this file. Blocks named `times-*` (and `times`) hold what varies with the "
            "machine and its load: no test asserts them. Each section names the commit and date "
            "of the run it comes from.", ""]
    print("\n".join(head))
    print("<!-- section readme -->")
    print("\n".join(readme.readme(text)))
    print("<!-- /section -->")
    print()
    print("<!-- section targets -->")
    print("\n".join(readme.targets(text)))
    print("<!-- /section -->")
    print()
    print(text.rstrip("\n"))


main()

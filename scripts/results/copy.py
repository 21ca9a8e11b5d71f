"""Copies docs/results.md's blocks into every guide that quotes them (README.md, PROTOCOL.md,
docs/*.md), and says which copies changed, so the prose around them can be read again.

Usage: python3 scripts/results/copy.py   (after scripts/results.sh)"""

import glob
import os
import re

os.chdir(os.path.join(os.path.dirname(__file__), "..", ".."))
BLOCK = re.compile(r"^([ \t]*)(<!-- result (\S+) -->\n)(.*?)^(\1<!-- /result -->)", re.S | re.M)

with open("docs/results.md") as f:
    results = {m[3]: m[4] for m in BLOCK.finditer(f.read())}

guides = ["README.md", "PROTOCOL.md"] + sorted(
    g for g in glob.glob("docs/*.md") if g != "docs/results.md")
for guide in guides:
    with open(guide) as f:
        text = f.read()
    changed = []

    def copy(m):
        indent, name = m[1], m[3]
        if name not in results:
            raise SystemExit(f"{guide}: no block `{name}` in docs/results.md")
        body = "".join(indent + line if line.strip() else line
                       for line in results[name].splitlines(keepends=True))
        if m[4] != body:
            changed.append(name)
        return indent + m[2] + body + m[5]

    new = BLOCK.sub(copy, text)
    if changed:
        with open(guide, "w") as f:
            f.write(new)
        print(f"{guide}: {', '.join(changed)}")

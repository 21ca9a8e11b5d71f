"""Holds docs/results.md's firmware figures to the firmware as built: renders the firmware
section from the output of a firmware-sim/check.sh run of this checkout and compares every
block whose figures do not vary by machine (not `times-*`) with the results file's.

Usage: held.py CHECK_LOG [RESULTS]   (scripts/test.sh, after check.sh; RESULTS defaults to
docs/results.md). Exits 1, naming each block that differs and its lines, when the firmware's
bytes or instruction counts moved and the results file was not regenerated
(`MEMA_CHECK_LOG=CHECK_LOG MEMA_RESULTS_KEEP=<every other section> scripts/results.sh`, then
`scripts/results/copy.py`)."""

import difflib
import json
import os
import shutil
import sys
import tempfile

sys.path.insert(0, os.path.dirname(__file__))

import firmware  # noqa: E402
from common import Logs  # noqa: E402
from readme import blocks  # noqa: E402


def rendered(check_log):
    """The firmware section's blocks as `scripts/results.sh` would write them from this log."""
    with tempfile.TemporaryDirectory() as logs:
        shutil.copy(check_log, os.path.join(logs, "check.log"))
        # The run's commit, date and load only go into prose and `times-*` blocks.
        with open(os.path.join(logs, "check.meta"), "w") as f:
            json.dump({"command": "check", "commit": "-", "date": "-", "seconds": 0,
                       "machine": "-", "load": [0]}, f)
        return blocks("\n".join(firmware.firmware(Logs(logs))) + "\n")


# An image's text moves by a few bytes of alignment with the checkout's path: cargo hashes a
# path dependency outside the image's own workspace (core, from firmware-sim/image and the
# board) by its absolute path, the hash goes into symbol names, and the names order the
# functions the linker lays out. Measured for one commit: the board's text 106,548 bytes built
# under /tmp/q, 106,556 under /tmp/x/mema. A code change moves it by more than this slack.
TEXT_SLACK_BYTES = 64


def same(held, made):
    """Whether two renderings of a block agree: every cell equal, but a `flash: text` cell, which
    may differ by TEXT_SLACK_BYTES."""
    held_lines, made_lines = held.splitlines(), made.splitlines()
    if len(held_lines) != len(made_lines):
        return False
    text_column = None
    for held_line, made_line in zip(held_lines, made_lines):
        held_cells, made_cells = held_line.split("|"), made_line.split("|")
        if "flash: text" in [c.strip() for c in held_cells]:
            text_column = [c.strip() for c in held_cells].index("flash: text")
        if len(held_cells) != len(made_cells):
            return False
        for column, (h, m) in enumerate(zip(held_cells, made_cells)):
            if h == m:
                continue
            if column != text_column or not (h.strip().endswith(" bytes") and m.strip().endswith(" bytes")):
                return False
            try:
                h_bytes = int(h.strip().removesuffix(" bytes").replace(",", ""))
                m_bytes = int(m.strip().removesuffix(" bytes").replace(",", ""))
            except ValueError:
                return False
            if abs(h_bytes - m_bytes) > TEXT_SLACK_BYTES:
                return False
    return True


def main():
    check_log = sys.argv[1]
    results_path = sys.argv[2] if len(sys.argv) > 2 else "docs/results.md"
    with open(results_path) as f:
        results = blocks(f.read())
    differ = 0
    made = rendered(check_log)
    held = [name for name in made if not name.startswith("times")]
    for name in held:
        if name not in results:
            print(f"held.py: {results_path} has no block `{name}`")
            differ += 1
        elif not same(results[name], made[name]):
            print(f"held.py: block `{name}` of {results_path} is not what check.sh measured:")
            sys.stdout.writelines(difflib.unified_diff(
                results[name].splitlines(keepends=True), made[name].splitlines(keepends=True),
                results_path, check_log))
            differ += 1
    if differ:
        sys.exit(1)
    print(f"held.py: the {len(held)} firmware blocks of {results_path} are check.sh's figures")


if __name__ == "__main__":
    main()

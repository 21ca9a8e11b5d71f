"""What the package's tests share: the shared real clouds, read in place, and the `mema` command
line the package is checked against (target/release/mema, or $MEMA_BIN)."""

import json
import os
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]
DATA = Path(os.environ.get("MEMA_DATA", ROOT.parent / "shared" / "data"))
CLOUDS = sorted(
    p.name for p in DATA.glob("*") if p.suffix in {".ply", ".pcd", ".las", ".laz"}
)


def guide_says(file, sentence):
    """Holds a guide (a path from the repository's root) to a sentence a test made from what it
    computed: a figure changed on either side fails until they agree (scripts/doc_digits.py
    reads these calls to tell which of a guide's numbers a test holds)."""
    text = " ".join((ROOT / file).read_text().split())
    assert " ".join(sentence.split()) in text, f"{file} does not say `{sentence}`"


def cloud(name):
    """The path of a shared cloud; never copied."""
    path = DATA / name
    assert path.is_file(), f"{path}: the tests read the shared clouds in ../shared/data"
    return str(path)


class Cli:
    """The `mema` binary, run as a user runs it."""

    def __init__(self, binary):
        self.binary = binary

    def run(self, *args):
        done = subprocess.run(
            [self.binary, *map(str, args)], capture_output=True, text=True
        )
        assert done.returncode == 0, (
            f"mema {' '.join(map(str, args))}: exit {done.returncode}\n{done.stderr}"
        )
        return done.stdout

    def json(self, *args):
        """The one JSON object (or JSON lines) a `--json` command prints."""
        out = self.run(*args, "--json").strip()
        try:
            return json.loads(out)
        except json.JSONDecodeError:
            return [json.loads(line) for line in out.splitlines()]


@pytest.fixture(scope="session")
def cli():
    binary = os.environ.get("MEMA_BIN", str(ROOT / "target" / "release" / "mema"))
    assert os.access(binary, os.X_OK), (
        f"{binary}: the tests compare the package with the command line; "
        "build it with `cargo build --release -p mema` or set MEMA_BIN"
    )
    return Cli(binary)

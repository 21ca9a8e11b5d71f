"""The README's Python example runs as written (on the shared cloud, in a scratch directory)."""

import os
import re

from conftest import DATA, ROOT


def test_the_readmes_example_runs(tmp_path):
    readme = (ROOT / "README.md").read_text()
    section = readme[readme.index("\n## Python\n"):]
    example = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    example = example.replace("../shared/data/", f"{DATA}/")
    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        exec(compile(example, "README.md (Python)", "exec"), {})
    finally:
        os.chdir(cwd)
    assert (tmp_path / "car6.mema").is_file()


def test_the_readmes_tiles_example_runs(tmp_path):
    readme = (ROOT / "README.md").read_text()
    section = readme[readme.index("\n### Archives tile by tile on Dask\n"):]
    example = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    example = example.replace("../shared/data/", f"{DATA}/")
    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        exec(compile(example, "README.md (tiles)", "exec"), {"__name__": "__main__"})
    finally:
        os.chdir(cwd)
    assert (tmp_path / "autzen.mema").is_file()

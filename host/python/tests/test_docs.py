"""Every Python example in README.md and docs/*.md runs as written (on the shared clouds, in a
scratch directory), as the documentation's shell commands do in tests/tests/docs.rs."""

import os
import re

import pytest

from conftest import DATA, ROOT

DOCUMENTS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
EXAMPLES = [
    (doc, n, code)
    for doc in DOCUMENTS
    for n, code in enumerate(re.findall(r"```python\n(.*?)```", doc.read_text(), re.S))
]


def test_the_guides_have_python_examples():
    names = {doc.name for doc, _, _ in EXAMPLES}
    assert {"README.md", "python.md"} <= names


@pytest.mark.parametrize(
    "doc, n, code", EXAMPLES, ids=[f"{doc.name}-{n}" for doc, n, _ in EXAMPLES]
)
def test_the_example_runs(tmp_path, doc, n, code):
    code = code.replace("../shared/data/", f"{DATA}/")
    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        exec(compile(code, f"{doc.name} (Python example {n})", "exec"), {"__name__": "__main__"})
    finally:
        os.chdir(cwd)
    written = re.findall(r"""save\(["']([^"']+)["']\)""", code)
    for name in written:
        assert (tmp_path / name).is_file(), f"{doc.name}: the example did not write {name}"

"""The Python examples of README.md and docs/python.md run as written: each ```python block,
in a fresh interpreter, in a scratch directory that has the repository's scenes/, with the
`tessera` command on PATH (as `cargo install --path .` leaves it)."""

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import ROOT, tessera_binary


def python_blocks(doc: Path):
    return re.findall(r"```python\n(.*?)```", doc.read_text(), re.S)


EXAMPLES = [
    (doc, i, code)
    for doc in (ROOT / "README.md", ROOT / "docs" / "python.md")
    for i, code in enumerate(python_blocks(doc))
]


def test_the_docs_have_examples():
    assert any(doc.name == "README.md" for doc, _, _ in EXAMPLES)
    assert sum(doc.name == "python.md" for doc, _, _ in EXAMPLES) >= 4


@pytest.mark.parametrize(
    "doc, index, code", EXAMPLES, ids=[f"{d.name}-{i}" for d, i, _ in EXAMPLES]
)
def test_an_example_runs_as_written(doc, index, code, tmp_path):
    (tmp_path / "scenes").symlink_to(ROOT / "scenes")
    env = dict(os.environ)
    env["PATH"] = f"{tessera_binary().parent}{os.pathsep}{env.get('PATH', '')}"
    done = subprocess.run(
        [sys.executable, "-c", code], cwd=tmp_path, env=env, capture_output=True, text=True,
        timeout=300,
    )
    assert done.returncode == 0, f"{doc.name} example {index}:\n{code}\n{done.stderr}"

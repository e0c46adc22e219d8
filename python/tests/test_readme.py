"""The Python code of the READMEs and of the user guide runs as written: every ```python block
of README.md, python/README.md and the guide's chapters (docs/book/src), in a fresh namespace,
from a scratch folder where `scenarios/` is the repository's."""

import os
import re

import pytest

from conftest import ROOT

BLOCK = re.compile(r"^```python\n(.*?)^```", re.S | re.M)


def blocks():
    out = []
    chapters = sorted((ROOT / "docs" / "book" / "src").rglob("*.md"))
    for readme in (ROOT / "README.md", ROOT / "python" / "README.md", *chapters):
        for k, code in enumerate(BLOCK.findall(readme.read_text(encoding="utf-8"))):
            out.append(pytest.param(code, id=f"{readme.relative_to(ROOT)}#{k}"))
    return out


def test_the_readmes_have_python_blocks():
    assert len(blocks()) >= 3


@pytest.mark.parametrize("code", blocks())
def test_readme_block_runs(code, tmp_path, monkeypatch):
    if "to_rerun" in code and os.environ.get("EDGEKF_REQUIRE_RERUN") != "1":
        pytest.importorskip("rerun")  # the optional rerun-sdk (CI requires it)
    (tmp_path / "scenarios").symlink_to(ROOT / "scenarios")
    monkeypatch.chdir(tmp_path)
    exec(compile(code, "README", "exec"), {"__name__": "__readme__"})

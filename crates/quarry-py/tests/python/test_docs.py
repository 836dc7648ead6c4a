"""Runs every ```python block of docs/python.md."""
import pathlib
import re

import pytest

DOC = pathlib.Path(__file__).resolve().parents[4] / "docs" / "python.md"
BLOCKS = re.findall(r"```python\n(.*?)```", DOC.read_text(), re.S) if DOC.exists() else []


@pytest.mark.parametrize("code", BLOCKS)
def test_doc_block(code):
    exec(compile(code, str(DOC), "exec"), {})

"""The README's Python quick start runs as written (its asserts are the checks)."""

import re

from conftest import REPO


def test_readme_python_quick_start():
    text = (REPO / "README.md").read_text()
    section = text.split("## Python quick start", 1)[1]
    code = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    assert "heml.System" in code  # the block found is the quick start
    exec(compile(code, "README.md (Python quick start)", "exec"), {})

"""The documentation's examples that are marked ``<!-- example: runs ... -->`` run as written."""
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
MARK = re.compile(r"<!-- example: runs[^>]*-->\n```python\n(.*?)\n```", re.S)


def _examples():
    out = []
    for md in sorted([ROOT / "README.md", *(ROOT / "docs").glob("*.md")]):
        for k, m in enumerate(MARK.finditer(md.read_text(encoding="utf-8"))):
            out.append(pytest.param(m.group(1), id=f"{md.name}#{k}"))
    return out


EXAMPLES = _examples()


def test_the_docs_have_runnable_examples():
    ids = {p.id.split("#")[0] for p in EXAMPLES}
    assert {"sensor.md", "can.md"} <= ids


@pytest.mark.parametrize("code", EXAMPLES)
def test_docs_example_runs(code, tmp_path):
    # run from a scratch directory that sees the repository's data folders, so that files the example writes stay
    # out of the repository
    (tmp_path / "can_dbc").symlink_to(ROOT / "can_dbc")
    script = tmp_path / "example.py"
    script.write_text(code, encoding="utf-8")
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    res = subprocess.run([sys.executable, str(script)], cwd=tmp_path, env=env, capture_output=True, text=True,
                         timeout=300)
    assert res.returncode == 0, res.stderr[-3000:]

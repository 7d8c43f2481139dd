"""The documentation's examples that are marked ``<!-- example: runs ... -->`` run as written; ``needs: A B`` in the
mark names optional packages (import names) without which the example skips and says so."""

import importlib.util
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
MARK = re.compile(r"<!-- example: runs([^>]*)-->\n```python\n(.*?)\n```", re.S)
NEEDS = re.compile(r"needs:\s*([\w. ]+)")


def _examples():
    out = []
    for md in sorted([ROOT / "README.md", *(ROOT / "docs").glob("*.md")]):
        for k, m in enumerate(MARK.finditer(md.read_text(encoding="utf-8"))):
            needs = NEEDS.search(m.group(1))
            missing = [n for n in (needs.group(1).split() if needs else ()) if importlib.util.find_spec(n) is None]
            marks = (
                [
                    pytest.mark.skip(
                        reason=f"{md.name} example #{k} needs the optional package(s) "
                        f"{', '.join(missing)} (pip install -e '.[fleet]')"
                    )
                ]
                if missing
                else []
            )
            out.append(pytest.param(m.group(2), id=f"{md.name}#{k}", marks=marks))
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
    res = subprocess.run(
        [sys.executable, str(script)], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300
    )
    assert res.returncode == 0, res.stderr[-3000:]


#: a `cantools decode --single-line` line of the docs: "(t) channel ID#DATA :: decoded"
DECODED = re.compile(r"^(\(\d+\.\d+\) \w+ [0-9A-F]{8}#[0-9A-F]+) :: (.+)$", re.M)
#: the plausibility limits of a temperature on the bus (docs/interfaces.md section 1.3: oil -60..250 degC)
PLAUSIBLE_DEGC = (-60.0, 250.0)


def _decode_lines():
    return [
        pytest.param(m.group(1), m.group(2), id=f"{md.name}:{m.group(1).split()[-1]}")
        for md in sorted([ROOT / "README.md", *(ROOT / "docs").glob("*.md")])
        for m in DECODED.finditer(md.read_text(encoding="utf-8"))
    ]


@pytest.mark.parametrize("frame, shown", _decode_lines())
def test_docs_decode_examples_are_what_cantools_prints_of_plausible_frames(frame, shown):
    import cantools

    res = subprocess.run(
        [sys.executable, "-m", "cantools", "decode", "--single-line", str(ROOT / "can_dbc" / "gearbox_vsensor.dbc")],
        input=frame + "\n",
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=120,
        check=True,
    )
    assert res.stdout.strip() == f"{frame} :: {shown}"
    db = cantools.database.load_file(str(ROOT / "can_dbc" / "gearbox_vsensor.dbc"))
    can_id, data = frame.split()[-1].split("#")
    message = db.get_message_by_frame_id(int(can_id, 16))
    values = message.decode(bytes.fromhex(data))
    low, high = PLAUSIBLE_DEGC
    for signal in message.signals:
        value = values[signal.name]
        if signal.unit == "degC" and isinstance(value, float):
            assert low <= value <= high, f"{signal.name} = {value} degC is no gearbox temperature"

"""Every Python package of the repo is listed in pyproject.toml, so a regular (non-editable) install ships it."""

from __future__ import annotations

from pathlib import Path

import tomllib

REPO = Path(__file__).resolve().parents[1]


def test_every_package_is_listed_in_pyproject():
    listed = set(tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    found = {
        p.parent.relative_to(REPO).as_posix().replace("/", ".")
        for top in ("firmware_model", "can_dbc", "tools")
        for p in (REPO / top).rglob("__init__.py")
    }
    assert found - listed == set(), f"packages missing from pyproject.toml: {sorted(found - listed)}"

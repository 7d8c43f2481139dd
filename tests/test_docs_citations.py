"""Every file a user reads cites only files the repository ships.

User-facing files: the README, docs/, the DBC, the parameter files, pyproject.toml and the source of the packages
and benchmarks (their docstrings, comments and --help texts). In them:

- a repository path (``docs/interfaces.md``, ``tools/cli/replay.py``, ``firmware_model/params/*.toml``) exists;
- a Markdown link to a file resolves from the linking file, and its ``#anchor`` names a heading of the target;
- ``interfaces.md ... section N`` names a numbered section of docs/interfaces.md;
- a bare upper-case Markdown name (``CONVENTIONS.md``) is a file of the repository;
- nothing cites the design notes of the project's development set-up, which are not shipped.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

#: names of files outside the repository that user-facing text must never cite (built from pieces so that this
#: file does not cite them either)
NOT_SHIPPED = re.compile("|".join(("CONTR" + "ACTS", "STY" + r"LE\.md", r"\.\./" + "shared")))
#: metavariables that look like file names in --help texts (``--report OUT.md``)
PLACEHOLDERS = {"OUT.md"}

REPO_PATH = re.compile(r"(?<![\w./@-])((?:docs|firmware_model|can_dbc|tools|tests|benchmarks|\.ci)/[\w./@*<>-]*[\w*>])")
BARE_MD = re.compile(r"(?<![\w./-])([A-Z][A-Za-z_]*\.md)\b")
MD_LINK = re.compile(r"\]\(([^)\s]+)\)")
INTERFACES_SECTION = re.compile(r"interfaces(?:\.md)?[^\n(]{0,30}?\bsections? (\d+(?:\.\d+)*)")


def user_facing_files() -> list[Path]:
    files = {ROOT / "README.md", ROOT / "pyproject.toml", *ROOT.glob("docs/**/*.md")}
    for pkg in ("firmware_model", "can_dbc", "tools", "benchmarks", "docs"):
        files.update(
            p
            for p in (ROOT / pkg).rglob("*")
            if p.suffix in (".py", ".dbc", ".toml", ".md") and "__pycache__" not in p.parts
        )
    return sorted(files)


def slug(heading: str) -> str:
    """GitHub's anchor of a Markdown heading."""
    text = re.sub(r"[`*_]", "", heading.strip().lower())
    return re.sub(r"[^\w\- ]", "", text).replace(" ", "-")


def anchors(md: Path) -> set[str]:
    return {slug(m.group(1)) for m in re.finditer(r"^#+ +(.+)$", md.read_text(encoding="utf-8"), re.M)}


def interfaces_sections() -> set[str]:
    text = (ROOT / "docs" / "interfaces.md").read_text(encoding="utf-8")
    return {m.group(1) for m in re.finditer(r"^#{2,4} +(\d+(?:\.\d+)*)\.? ", text, re.M)}


def _path_exists(cited: str) -> bool:
    cited = re.sub(r"<[^>]*>", "*", cited.split("<br")[0])  # placeholders (<name>) and table line breaks
    return any(ROOT.glob(cited)) if "*" in cited else (ROOT / cited).exists()


def citation_problems(text: str, where: Path) -> list[str]:
    """What ``text`` (the content of the file ``where``) cites that the repository does not ship."""
    problems = [f"cites {m.group(0)!r}, which is not part of the repository" for m in NOT_SHIPPED.finditer(text)]
    problems += [
        f"cites {m.group(1)}, which does not exist" for m in REPO_PATH.finditer(text) if not _path_exists(m.group(1))
    ]
    problems += [
        f"cites {m.group(1)}, which is no file of the repository"
        for m in BARE_MD.finditer(text)
        if m.group(1) not in PLACEHOLDERS and not any(ROOT.rglob(m.group(1)))
    ]
    sections = interfaces_sections()
    problems += [
        f"cites section {m.group(1)} of docs/interfaces.md, which has no such section"
        for m in INTERFACES_SECTION.finditer(text)
        if m.group(1) not in sections
    ]
    if where.suffix == ".md":
        for m in MD_LINK.finditer(text):
            target = m.group(1)
            if re.match(r"[a-z]+:", target):
                continue
            file_part, _, anchor = target.partition("#")
            dest = (where.parent / file_part) if file_part else where
            if not dest.exists():
                problems.append(f"links to {target}, which does not exist")
            elif anchor and dest.suffix == ".md" and anchor not in anchors(dest):
                problems.append(f"links to {target}, whose anchor is no heading of {file_part or where.name}")
    return problems


FILES = user_facing_files()


@pytest.mark.parametrize("path", FILES, ids=[str(p.relative_to(ROOT)) for p in FILES])
def test_user_facing_file_cites_only_what_the_repository_ships(path):
    problems = citation_problems(path.read_text(encoding="utf-8", errors="replace"), path)
    assert not problems, f"{path.relative_to(ROOT)}: " + "; ".join(problems)


BAD_CITATIONS = (
    "Run tables: " + "CONTR" + "ACTS section 3.",
    "Style: see STY" + "LE.md.",
    "Data in ../" + "shared/data.",
    "See docs/nowhere.md.",
    "[the sensor](sensor.md#no-such-heading)",
    "[x](missing.md)",
    "docs/interfaces.md section 9",
    "as the CONVENTIONS_OLD.md say",
)


@pytest.mark.parametrize("text", BAD_CITATIONS)
def test_the_check_finds_a_citation_of_what_is_not_shipped(text):
    assert citation_problems(text, ROOT / "docs" / "example.md")


def test_the_check_accepts_citations_of_what_is_shipped():
    good = (
        "Run tables: docs/interfaces.md section 3 ([interfaces](interfaces.md#3-run-tables-csv)); codes: "
        "[glossary](glossary.md#gears), docs/img/cycles_<name>.png, firmware_model/params/*.toml, "
        "docs/CONVENTIONS.md, interfaces section 2.4, `--report OUT.md`."
    )
    assert citation_problems(good, ROOT / "docs" / "example.md") == []


def test_the_data_lookup_of_the_tests_is_the_only_place_that_names_data_outside_the_checkout():
    hits = [
        p
        for p in (ROOT / "tests").rglob("*.py")
        if "__pycache__" not in p.parts
        and p.name != Path(__file__).name
        and NOT_SHIPPED.search(p.read_text(encoding="utf-8"))
    ]
    assert hits == [], hits


def test_the_readme_shows_the_component_codes():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert "](docs/glossary.md)" in readme and "](docs/img/gearbox_codes.png)" in readme
    from firmware_model.components import PUBLISHED

    codes = {c.split(".")[0] for c in PUBLISHED}
    missing = sorted(c for c in codes if f"`{c}`" not in readme and f" {c} " not in readme)
    assert not missing, f"the README's table of codes misses {missing}"

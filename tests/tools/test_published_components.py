"""The offline tools take the published components from the gearbox in hand (tools.published), not the GRS905's
constants: docs/description.md's single-stage reducer R1 publishes 7 components, none of them a GRS905 one but the
sump, and every pure function that lists, groups or labels components follows it; the GRS905 keeps its list, its
groups and its words."""

import re
from pathlib import Path

import numpy as np
import pytest

from firmware_model.components import (
    GROUP,
    IDLE_WHEELS,
    LAYSHAFT_WHEELS,
    PLANETARY,
    PUBLISHED,
    SHAFT_BEARINGS,
    WHEEL_BEARINGS,
    describe,
)
from firmware_model.description import load_description
from firmware_model.errors import InputError
from firmware_model.parameters import load_parameters
from tools import published as P
from tools.runtable import RunTable

R1_IDS = ("P", "W", "B1", "B2", "B3", "B4", "oil")


@pytest.fixture(scope="module")
def r1(tmp_path_factory):
    """The reducer of docs/description.md as written there, its output wheel named (legends take the name)."""
    text = (Path(__file__).resolve().parents[2] / "docs" / "description.md").read_text(encoding="utf-8")
    toml = re.search(r"```toml\n(.*?)```", text, re.S).group(1)
    toml = toml.replace(
        "[topology.wheel.W]\n", '[topology.wheel.W]\nname = { v = "output wheel", u = "-", src = "assumed" }\n', 1
    )
    f = tmp_path_factory.mktemp("r1") / "r1.toml"
    f.write_text(toml)
    d = load_description(f)
    assert tuple(c.id for c in d.published) == R1_IDS
    return d


class _Limits:
    """Warning limits per component from a description's published entries (Limits.of's contract)."""

    def __init__(self, desc):
        self.components = tuple(c.id for c in desc.published)
        self.warning_c = np.array([c.warning_c for c in desc.published])
        self.critical_c = np.array([c.critical_c for c in desc.published])

    def of(self, c):
        i = self.components.index(c)
        return float(self.warning_c[i]), float(self.critical_c[i]), 5.0


def _sensor_table(ids, t, hot: str, warn: str) -> RunTable:
    """A sensor output table with T_, W_ and ttl_ columns of ``ids``: ``hot`` runs hottest, ``warn`` in warning."""
    cols = {"time_s": t, "can_time_s": t, "degraded_mode": np.zeros(t.size), "degraded": np.zeros(t.size)}
    for c in ids:
        cols[f"T_{c}_c"] = np.full(t.size, 60.0)
        cols[f"W_{c}"] = np.zeros(t.size)
        cols[f"ttl_{c}_s"] = np.full(t.size, np.inf)
    cols[f"T_{hot}_c"] = np.linspace(60.0, 140.0, t.size)
    cols[f"W_{warn}"] = np.where(t >= t[t.size // 2], 1.0, 0.0)
    return RunTable(cols)


def test_the_grs905_keeps_its_list_groups_and_words():
    params = load_parameters("GRS905")
    d = P.description(params)
    assert P.ids(params) == PUBLISHED == P.ids()  # None: the default gearbox
    assert P.groups(params) == {c: GROUP[c] for c in PUBLISHED}
    assert all(P.label_of(c, d) == describe(c) for c in PUBLISHED)
    from tools.plots import panels

    assert list(panels(params).values()) == [
        [f"{w}.teeth" for w in IDLE_WHEELS],
        list(LAYSHAFT_WHEELS),
        list(PLANETARY),
        list(SHAFT_BEARINGS),
        list(WHEEL_BEARINGS),
        ["H1", "H2", "H3"],
    ]


def test_ids_groups_and_words_follow_the_description(r1):
    assert P.ids(r1) == R1_IDS
    assert P.groups(r1) == {"P": "gear", "W": "gear", "B1": "bearing", "B2": "bearing", "B3": "bearing",
                            "B4": "bearing", "oil": "oil"}  # fmt: skip
    assert P.label_of("W", r1) == "W (output wheel)"
    assert P.label_of("P", r1) == "P"  # no name given: no words, never a GRS905 code's
    assert P.housings(r1) == ("H",)


def test_the_plot_panels_follow_the_description(r1):
    from tools.plots import panels

    groups = panels(r1)
    assert groups == {"Wheels": ["P", "W"], "Shaft bearings": ["B1", "B2", "B3", "B4"], "Housings": ["H"]}


def test_the_replay_summary_and_plot_choices_follow_the_description(r1):
    from tools.replay.plot import closest_to_limits, raised_components
    from tools.replay.summary import summary_lines

    t = np.arange(0.0, 600.0, 1.0)
    # the GRS905's columns are there too, hotter and in warning: a tool taking the GRS905 list would name them
    table = _sensor_table(R1_IDS, t, hot="W", warn="B3")
    grs = _sensor_table(PUBLISHED, t, hot="PS", warn="PS")
    for c in grs.columns:
        if c not in table.columns:
            table[c] = grs[c]
    table["T_PS_c"] = table["T_PS_c"] + 100.0
    lines = summary_lines(table, limits=_Limits(r1), gearbox=r1)
    assert lines[0].startswith("closest to its limit: W (output wheel), peak 140.0 degC"), lines[0]
    assert lines[1] == "warnings: B3 in warning for 5.0 min in all (first at 5.0 min)", lines[1]
    ids = P.ids(r1)
    assert closest_to_limits(table, _Limits(r1), ids)[0] == "W" and "PS" not in closest_to_limits(
        table, _Limits(r1), ids
    )
    assert raised_components(table, ids) == ["B3"]


def test_the_limits_without_a_sensor_are_the_descriptions_own(r1):
    """A table without its sensor's limits (no meta) was summarised with the GRS905's file, which has none of the
    R1's components ('tuple.index(x): x not in tuple'): the summary takes the description's own limits file."""
    from tools.replay.summary import summary_lines

    lim = P.limits(r1)
    assert lim.components == R1_IDS and lim.of("W")[0] == 150.0 and lim.of("B3")[0] == 120.0
    assert P.limits().components == PUBLISHED  # None: the default gearbox
    lines = summary_lines(_sensor_table(R1_IDS, np.arange(0.0, 600.0, 1.0), hot="W", warn="B3"), gearbox=r1)
    assert lines[0].startswith("closest to its limit: W (output wheel), peak 140.0 degC") and "limit 150" in lines[0]


def test_fleet_rows_and_report_follow_the_description(r1):
    from tools.fleet.report import _hottest, published_in
    from tools.fleet.summary import summarize

    t = np.arange(0.0, 600.0, 0.1)
    table = _sensor_table(R1_IDS, t, hot="B2", warn="B2")
    row = summarize(table, {}, vehicle="v1", log="a.log", key="k", date="2026-01-01", gearbox=r1)
    peaks = [k for k in row if k.startswith("peak_") and k.endswith("_c")]
    assert peaks == [f"peak_{c}_c" for c in R1_IDS]
    assert row["peak_B2_c"] == pytest.approx(140.0) and row["warnings_B2"] == 1
    c = {k: [v] for k, v in row.items()}
    assert published_in(c) == R1_IDS
    lines = []
    _hottest(c, lines)
    text = "\n".join(lines)
    assert "| v1 | 140.0 degC | B2 |" in text
    rows = [ln for ln in lines if ln.startswith("| ") and "degC" in ln and "v1" not in ln]
    assert {ln.split(" | ")[0][2:] for ln in rows} == set(R1_IDS)


def test_demo_fmu_and_diagnosis_follow_the_description(r1):
    from tools.demo import component_errors, featured
    from tools.diagnosis.decide import _node_differences
    from tools.diagnosis.options import Options
    from tools.diagnosis.prepare import prepare
    from tools.export.fmu import _variables

    t = np.arange(0.0, 600.0, 1.0)
    est = _sensor_table(R1_IDS + PUBLISHED[:3], t, hot="B4", warn="B4")
    for c in R1_IDS + PUBLISHED[:3]:
        est[f"meas_T_{c}_c"] = np.asarray(est[f"T_{c}_c"]) + 1.0
    assert [e.component for e in component_errors(est, r1)] == list(R1_IDS)
    first, rest = featured(est, _Limits(r1), r1)
    assert first[-1] == "oil" and set(first + rest) <= set(R1_IDS) and first[0] == "B4"

    names = [v[0] for v in _variables(_Limits(r1), r1)]
    assert [n for n in names if n.startswith("T_")] == [f"T_{c}_c" for c in R1_IDS]
    assert [n for n in names if n.startswith("limit_warning_")] == [f"limit_warning_{c}_c" for c in R1_IDS]

    full = {f"T_{n}_c": np.arange(3.0) for n in ("P", "B1", "H", "oil", "PS")}
    other = {k: v + 1.0 for k, v in full.items()}
    assert set(_node_differences([{"full": full}], [{"full": other}], r1)) == {"P", "B1", "H", "oil"}

    drive = {
        "time_s": t,
        "engine_speed_rpm": np.full(t.size, 1200.0),
        "engine_torque_nm": np.full(t.size, 300.0),
        "gear": np.ones(t.size),
        "oil_temp_c": np.linspace(40.0, 60.0, t.size),
    }
    ds = prepare(RunTable({**drive, "meas_T_B2_c": np.linspace(40.0, 70.0, t.size)}), "r.csv", "train", Options(),
                 gearbox=r1)  # fmt: skip
    assert "B2" in ds.channels
    with pytest.raises(InputError, match='names component "PS"'):
        prepare(RunTable({**drive, "meas_T_PS_c": np.linspace(40.0, 70.0, t.size)}), "r.csv", "train", Options(),
                gearbox=r1)  # fmt: skip


def test_a_sensor_that_says_what_it_publishes_is_taken_at_its_word(r1):
    """A sensor (or anything with ``params``) that lists its published ids gives those, each with its description's
    group; one that does not gives its parameter set's description's."""
    from types import SimpleNamespace

    params = load_parameters("GRS905")
    assert P.ids(SimpleNamespace(params=params)) == PUBLISHED
    sensor = SimpleNamespace(params=params, published=("PS", "oil"))
    assert P.ids(sensor) == ("PS", "oil") and P.groups(sensor) == {"PS": "sun", "oil": "oil"}
    assert P.ids(list(r1.published)) == R1_IDS
    with pytest.raises(TypeError, match="no parameter set"):
        P.ids(42)

"""The gearbox description (firmware_model.description, docs/description.md): the shipped GRS905 and GRSO905
descriptions state exactly what the code's constants hold today (ids, orders, pairs, bearing shafts and housings,
positions, the gears' ratios), and a description that does not hold together is one sentence naming the file, the
key and why, exit 2 through `gearbox-vsensor describe`."""

from __future__ import annotations

import math
import re
from pathlib import Path

import pytest

from firmware_model import components as C
from firmware_model import network as N
from firmware_model.description import description_of, load_description, shipped_descriptions
from firmware_model.errors import ParameterError
from firmware_model.parameters import PARAM_DIR, load_parameters
from firmware_model.physics import geometry as G
from firmware_model.physics import kinematics as K
from tools.cli import main

VARIANTS = ("GRS905", "GRSO905")


@pytest.fixture(scope="module", params=VARIANTS)
def both(request):
    return load_description(request.param), load_parameters(request.param)


def test_the_components_constants_are_the_description(both):
    d, _ = both
    wheels = {w.id: w for w in d.wheels}
    assert tuple(w.id for w in d.wheels if w.mount == "idle") == C.IDLE_WHEELS
    assert tuple(w.id for w in d.wheels if w.shaft == "LS") == C.LAYSHAFT_WHEELS
    assert tuple(w.id for w in d.wheels if w.mount == "pin") == (C.REVERSE_IDLER,)
    assert tuple((ps.sun, ps.planet, ps.ring) for ps in d.planetary) == (C.PLANETARY,)
    assert tuple(b.id for b in d.bearings if b.wheel is None) == C.SHAFT_BEARINGS
    assert tuple(b.id for b in d.bearings if b.wheel is not None) == C.WHEEL_BEARINGS
    assert tuple(b.wheel for b in d.bearings if b.wheel is not None) == C.IDLE_WHEELS
    assert tuple(h.id for h in d.housings) == C.HOUSINGS
    meshes = {m.id: m.wheels for m in d.meshes}
    for pair, (iw, lw) in C.PAIRS.items():
        if pair == "R":  # the reverse pair meshes through the idler
            assert meshes["R"] == (lw, C.REVERSE_IDLER) and meshes["RI"] == (C.REVERSE_IDLER, iw)
        else:
            assert meshes[pair] == (iw, lw) and wheels[iw].mount == "idle" and wheels[lw].shaft == "LS"
    assert {i: n for i, n in d.names.items()} == {i: n for i, n in C.NAMES.items() if i in d.names}
    assert set(C.NAMES) - set(d.names) == set()  # every code components.py names is a part of the description
    assert tuple(c.id for c in d.published) == C.PUBLISHED
    assert {c.id: c.group for c in d.published} == C.GROUP


def test_the_network_and_geometry_constants_are_the_description(both):
    d, p = both
    # what network.py and geometry.py held as constants before they were built from the description
    assert {s.id: tuple(g.id for g in s.segments) for s in d.shafts} == {
        "IS": ("IS@bulk", "IS@BIF", "IS@LI"),
        "LS": ("LS@BLF", "LS@LL", "LS@3L", "LS@2L", "LS@1L", "LS@CL", "LS@RL", "LS@BLR"),
        "MS": ("MS@BIM", "MS@3M", "MS@2M", "MS@1M", "MS@CM", "MS@RM", "MS@BMR", "MS@PS"),
        "OS": ("OS@carrier", "OS@bulk", "OS@BO", "OS@EY"),
    }
    shaft_bearings = [b for b in d.bearings if b.wheel is None]
    assert {b.id: b.segment for b in shaft_bearings} == {
        "BIF": "IS@BIF",
        "BLF": "LS@BLF",
        "BLR": "LS@BLR",
        "BIM": "MS@BIM",
        "BMR": "MS@BMR",
        "BO": "OS@BO",
    }
    assert {w.id: w.segment for w in d.wheels if w.mount == "idle"} == {
        "LI": "IS@LI",
        **{w: f"MS@{w}" for w in C.IDLE_WHEELS[1:]},
    }
    assert {h.id: h.material for h in d.housings} == {"H1": "aluminium", "H2": "cast_iron", "H3": "aluminium"}
    assert tuple(b.id for b in d.boundaries) == N.BOUNDARIES
    # what geometry.py held as constants before it was built from the description
    assert {b.id: b.shaft for b in shaft_bearings} == {
        "BIF": "IS",
        "BLF": "LS",
        "BLR": "LS",
        "BIM": "MS",
        "BMR": "MS",
        "BO": "OS",
    }
    assert {b.id: b.housing for b in shaft_bearings if b.housing} == {
        "BIF": "H1",
        "BLF": "H1",
        "BLR": "H2",
        "BMR": "H2",
        "BO": "H3",
    }
    assert {b.id: b.inside for b in shaft_bearings if b.inside} == {"BIM": "IS@LI"}  # network: the pilot bearing
    assert tuple(w.id for w in d.wheels if w.mount == "cut") == ("1L", "CL", "RL")
    # positions and ends of the segments as the network computed them from the parameters, bit for bit
    geo = G.build_geometry(p)
    W = geo.wheels
    pos = {
        "IS": [0.0, p["bearing.BIF.x"], W["LI"].x],
        "LS": [p["shaft.LS.x_BLF"]] + [W[w].x for w in C.LAYSHAFT_WHEELS] + [p["shaft.LS.x_BLR"]],
        "MS": [p["bearing.BIM.x"]] + [W[w].x for w in C.IDLE_WHEELS[1:]] + [p["bearing.BMR.x"], p["shaft.MS.x_PS"]],
        "OS": [p["shaft.OS.x_carrier"], p["shaft.OS.x_bulk"], p["shaft.OS.x_BO"], p["shaft.OS.x_EY"]],
    }
    ends = {"IS": (p["shaft.IS.x_front"], p["shaft.IS.x_rear"])}
    for s in ("LS", "MS", "OS"):
        ends[s] = (pos[s][0] - p[f"shaft.{s}.overhang_front"], pos[s][-1] + p[f"shaft.{s}.overhang_rear"])
    assert {s.id: [g.x_m for g in s.segments] for s in d.shafts} == pos
    assert {s.id: (s.front_m, s.rear_m) for s in d.shafts} == ends
    for w in d.wheels:
        g = geo.wheels[w.id]
        assert (w.teeth, w.module_m, w.helix_rad, w.width_m, w.x_m) == (g.z, g.m_n, g.beta, g.width, g.x), w.id
    net = N.build_network(p)
    assert d.nodes == net.nodes

    # what dips into the sump, what the oil splashes, which wheels have covered sides: the network's links
    def linked(prefix):
        return {nm.split(":", 1)[1] for nm in net.link_name if nm.startswith(prefix)}

    assert set(d.oil.dipping) == linked("imm:")
    assert set(d.oil.splashed) == linked("splash:") - {"OS"} | {"OS@bulk", "PR"} | linked("bsplash:")
    assert tuple(w.id for w in d.wheels if w.sides == "free") == ("CM", "RM")  # network: Eq 61 for CM and RM
    assert {w.id for w in d.wheels if w.sides} == set(C.IDLE_WHEELS)
    # the housings' joints: the links across the flanges, their conductance from the description
    from firmware_model.physics.heat_transfer import linear_conductance_w_per_k

    by_id = {h.id: h for h in d.housings}
    joints = {f"cond:{h.id}-{h.joined_to}": h for h in d.housings if h.joined_to}
    assert set(joints) == {nm for nm in net.link_name if nm.startswith("cond:H")}
    for nm, h in joints.items():
        g_w_per_k = linear_conductance_w_per_k(p["housing.k_joint"], h.joint_area_m2, h.x_m, by_id[h.joined_to].x_m)
        assert net.link_G0[net.link_name.index(nm)] == g_w_per_k, nm
    # the conduction links to the boundaries: the touching nodes and their conductance
    for k, b in enumerate(d.boundaries):
        links = [i for i in range(len(net.link_b)) if net.link_b[i] == net.n + k and net.link_kind[i] == N.K_CONST]
        assert {net.nodes[net.link_a[i]] for i in links} == (set(b.touches) if b.conductance_w_per_k else set()), b.id
        assert all(net.link_G0[i] == b.conductance_w_per_k for i in links), b.id
    fed = {net.nodes[net.link_a[i]] for i in net.links_of_kind(N.K_STREAM)}
    assert set(d.oil.jets) == fed
    for b in shaft_bearings:
        assert (b.bore_m, b.outer_m, b.width_m) == tuple(p[f"bearing.{b.id}.{k}"] for k in ("d_bore", "d_out", "width"))


def test_the_kinematics_constants_and_ratios_are_the_description(both):
    d, p = both
    kin = p.kinematics
    assert tuple(m.id for m in d.meshes) == K.MESHES
    assert tuple(c.id for c in d.couplings if c.kind == "sync") == K.SYNCS
    assert {g.number: g.name for g in d.gears} == K.GEAR_NAMES
    for g in d.gears:
        row = g.number - K.GEAR_MIN
        # the meshes the path loads are the ones the kinematics loads in that gear (none in neutral)
        assert set(g.meshes) == {m for m, t in zip(K.MESHES, kin.mesh_torque[row]) if t != 0}, g.name
        # the synchronizers the path engages are the ones locked (no relative speed) in that gear
        for k, sync in enumerate(K.SYNCS[:-1]):  # PR/range: engaged on one side or the other in every gear
            assert (sync in g.engaged) == (kin.sync_rel[row, k] == 0), (g.name, sync)
        if g.number == 0:
            assert math.isinf(g.ratio) and math.isinf(K.total_ratio(kin, 0))
            continue
        assert abs(g.ratio - K.total_ratio(kin, g.number)) <= 1e-12 * abs(g.ratio), g.name
        assert g.held == (("range", "ring" if kin.low_range[row] else "locked"),), g.name
        split, main, rng = K.GEAR_TABLE[g.number]
        assert g.path[-1] == ("range/ring" if rng == "low" else "range/locked"), g.name
        st = K.gear_state(g.number, p.split_inverted)
        assert g.path[0] == ("LI/IS" if st.split_pair == "L" else "3M/IS"), g.name


def test_the_published_limits_are_the_limits_file(both):
    from firmware_model.onboard.warning_levels import load_limits

    d, _ = both
    lim = load_limits()
    for c in d.published:
        assert (c.warning_c, c.critical_c) == lim.of(c.id)[:2], c.id


def test_the_parameters_are_unchanged_by_the_topology():
    """The parameter loader passes the topology by: the same 270 values, no topology key among them."""
    for v in VARIANTS:
        p = load_parameters(v)
        assert len(p.values) == 270 and not any(k.startswith("topology.") for k in {**p.values, **p.strings})


def test_describe_prints_the_summary(capsys):
    assert main(["describe"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("gearbox GRS905 (GRS905.toml): vehicle drive, IS -> OS")
    assert "    9 4L: ratio 3.03361 (stated 3.034); path LI/IS L 1 1M/MS range/locked" in out
    assert "oil system: splash lubrication, 13.5 L, pump on LS reaching 21 parts" in out
    assert "thermostatic bypass opens at 80 degC" in out and "PS 130/150" in out and ", no heater" in out
    assert "  oil: the seed's gear oil (Appendix 2): 115 / 49.9 / 15.2 mm2/s at 40 / 60 / 100 degC" in out
    assert main(["describe", "--gearbox", "MM82"]) == 0
    out = capsys.readouterr().out
    assert "heater 3000 W below 22.3 degC (all of it below 17.3)" in out
    assert "  oil: ISO VG 320 (its data sheet): 320 / 108 / 24 mm2/s at 40 / 60 / 100 degC" in out
    assert main(["describe", "--gearbox", "GRSO905"]) == 0
    assert "   14 6H: ratio 0.807563 (stated 0.8076); path LI/IS L 3 3M/MS range/locked" in capsys.readouterr().out


def test_an_unknown_gearbox_is_one_sentence(capsys):
    assert main(["describe", "--gearbox", "GRS999"]) == 2
    err = capsys.readouterr().err
    assert err == (
        f"gearbox-vsensor describe: error: unknown gearbox 'GRS999': use one of {', '.join(shipped_descriptions())} "
        "or the path of a .toml description file\n"
    )
    assert {"GRS905", "GRSO905"} <= set(shipped_descriptions())


# ---------------------------------------------------------------------------------------------------------------
# malformed descriptions: (case, the file's body after inheriting GRS905, the key the sentence names, its reason)

ORDER = C.PUBLISHED
MALFORMED = [
    (
        "mesh modules disagree",
        '[topology.wheel.LL]\nmodule = { v = 5, u = "mm", src = "assumed" }',
        "topology.mesh.L.wheels",
        "their modules disagree (4.5 mm and 5 mm)",
    ),
    (
        "mesh centre distance",
        '[topology.mesh.3]\ncentre_distance = { v = 170, u = "mm", src = "assumed" }',
        "topology.mesh.3.centre_distance",
        "disagrees with the wheels' standard centre distance",
    ),
    (
        "mesh on an unknown wheel",
        '[topology.mesh.L]\nwheels = { v = ["LI", "LX"], u = "-", src = "seed" }',
        "topology.mesh.L.wheels",
        "names LX, which is no wheel or planetary member",
    ),
    (
        "bearing on an unknown shaft",
        '[topology.bearing.BLF]\nshaft = { v = "XS", u = "-", src = "seed" }',
        "topology.bearing.BLF.shaft",
        "'XS' is no shaft of the description",
    ),
    (
        "bearing in an unknown housing",
        '[topology.bearing.BO]\nhousing = { v = "H4", u = "-", src = "seed" }',
        "topology.bearing.BO.housing",
        "'H4' is no housing",
    ),
    (
        "bearing bore over its outer diameter",
        '[topology.bearing.BO]\nbore = { v = 150, u = "mm", src = "assumed" }',
        "topology.bearing.BO.bore",
        "must be smaller than outer",
    ),
    (
        "path misses a coupling",
        '[topology.gear.4L]\npath = { v = ["LI/IS", "L", "1", "range/locked"], u = "-", src = "seed" }',
        "topology.gear.4L.path",
        "does not close at step 'range/locked'",
    ),
    (
        "path ends short of the output",
        '[topology.gear.4L]\npath = { v = ["LI/IS", "L"], u = "-", src = "seed" }',
        "topology.gear.4L.path",
        "ends on LS, not on the output shaft OS",
    ),
    (
        "path through an unknown step",
        '[topology.gear.4L]\npath = { v = ["LI/IS", "L", "9", "1M/MS"], u = "-", src = "seed" }',
        "topology.gear.4L.path",
        "it is no mesh, coupling or planetary set",
    ),
    (
        "ratio off its stated value",
        '[topology.gear.4L]\nratio = { v = 3.2, u = "-", src = "seed" }',
        "topology.gear.4L.ratio",
        "is off the ratio of the teeth along its path, 3.03361",
    ),
    (
        "ratio zero (a division by zero before)",
        '[topology.gear.4L]\nratio = { v = 0, u = "-", src = "seed" }',
        "topology.gear.4L.ratio",
        "= 0 is no ratio of a gear that transmits power: state input/output speed, 3.03361 by the teeth",
    ),
    (
        "two gears with one number",
        '[topology.gear.4H]\nnumber = { v = 9, u = "-", src = "seed" }',
        "topology.gear.4H.number",
        "is also gear 4L's number",
    ),
    (
        "published component with no node",
        "[topology.published]\norder = { v = [" + ", ".join(f'"{c}"' for c in ORDER[:-1]) + ', "sump"], u = "-", '
        'src = "seed" }',
        "topology.published.order",
        "lists sump, which is no node of the description",
    ),
    (
        "published in an unknown limit group",
        '[topology.published]\nhot = { v = ["oil"], u = "-", src = "seed" }',
        "topology.published.hot",
        "is no limit group of limits.toml",
    ),
    (
        "zero size",
        '[topology.wheel.3M]\nwidth = { v = 0, u = "mm", src = "assumed" }',
        "topology.wheel.3M.width",
        "= 0 mm must be greater than zero",
    ),
    (
        "negative size",
        '[topology.bearing.BO]\nwidth = { v = -26, u = "mm", src = "assumed" }',
        "topology.bearing.BO.width",
        "= -26 mm must be greater than zero",
    ),
    (
        "unknown key",
        '[topology.wheel.LI]\nteth = { v = 28, u = "-", src = "seed" }',
        "topology.wheel.LI.teth",
        "is an unknown key (did you mean teeth?); known: name, shaft, segment, mount, teeth",
    ),
    (
        "unknown section",
        '[topology.shafts.XS]\nname = { v = "x", u = "-", src = "seed" }',
        "topology.shafts",
        "is an unknown section (did you mean shaft?); known: shaft, wheel",
    ),
    (
        "wheel on an unknown shaft",
        '[topology.wheel.2M]\nshaft = { v = "XS", u = "-", src = "seed" }',
        "topology.wheel.2M.shaft",
        "'XS' is no shaft of the description (mount idle)",
    ),
    (
        "wheel on a segment of another shaft",
        '[topology.wheel.LI]\nsegment = { v = "MS@3M", u = "-", src = "seed" }',
        "topology.wheel.LI.segment",
        "'MS@3M' is no segment of shaft IS",
    ),
    (
        "duplicate id",
        '[topology.bearing.LL]\nkind = { v = "needle", u = "-", src = "seed" }\nwheel = { v = "2M", u = "-", '
        'src = "seed" }\nwidth = { from = "wheel_bearing.length_roller" }',
        "topology.bearing.LL",
        "reuses the id LL of wheel LL",
    ),
    ("planetary set missing a member", None, "topology.planetary.range", "has no ring; required: sun, planet, ring"),
    (
        "planets that do not fit",
        '[topology.planetary.range]\nz_planet = { v = 27, u = "-", src = "assumed" }',
        "topology.planetary.range.z_planet",
        "does not fit between sun and ring",
    ),
    (
        "thermostat below the oil's range",
        '[topology.oil]\nthermostat_open = { v = 20, u = "degC", src = "assumed" }',
        "topology.oil.thermostat_open",
        "= 20 degC lies outside the oil's plausible working range 40..150 degC",
    ),
    (
        "thermostat full below open",
        '[topology.oil]\nthermostat_full = { v = 70, u = "degC", src = "assumed" }',
        "topology.oil.thermostat_full",
        "must lie above thermostat_open = 80 degC",
    ),
    (
        "oil volume that does not fit in the housings",  # 6 m3 where litres were meant: was accepted
        '[topology.oil]\nvolume = { v = 6, u = "m3", src = "assumed" }',
        "topology.oil.volume",
        "= 6000 L does not fit in the housings: a sphere of their outside surface (half their total area, 2.4 m2) "
        "holds 350 L; is the volume in another unit?",
    ),
    (
        "thermostat read nowhere known",
        '[topology.oil]\nthermostat_senses = { v = "cooler", u = "-", src = "assumed" }',
        "topology.oil.thermostat_senses",
        "= 'cooler' must be one of return, sump",
    ),
    (
        "a measured sump's cooler taken some unknown way",
        '[topology.oil]\nmeasured_cooler = { v = "guess", u = "-", src = "assumed" }',
        "topology.oil.measured_cooler",
        "= 'guess' must be one of thermostat, balance",
    ),
    (
        "unit of another dimension",
        '[topology.wheel.LI]\nwidth = { v = 45, u = "kg", src = "assumed" }',
        "topology.wheel.LI.width",
        "has unit 'kg' (a mass), but it is a length",
    ),
    (
        "value from a missing parameter",
        '[topology.wheel.LI]\nteeth = { from = "gear.L.z9" }',
        "topology.wheel.LI.teeth",
        "takes its value from 'gear.L.z9', which is no parameter of this file",
    ),
    (
        "provenance unknown",
        '[topology.wheel.LI]\nmount = { v = "idle", u = "-", src = "guess" }',
        "topology.wheel.LI.mount",
        "has provenance 'guess'",
    ),
    (
        "mount unknown",
        '[topology.wheel.LI]\nmount = { v = "floating", u = "-", src = "seed" }',
        "topology.wheel.LI.mount",
        "= 'floating' must be one of idle, fixed, cut, pin",
    ),
    (
        "teeth as text",
        '[topology.wheel.LI]\nteeth = { v = "28", u = "-", src = "seed" }',
        "topology.wheel.LI.teeth",
        "= '28' is not a number",
    ),
    (
        "segments out of order",
        '[topology.shaft.OS.x]\n"OS@BO" = { v = 0.6, u = "m", src = "assumed" }',
        "topology.shaft.OS.x.OS@BO",
        "= 0.6 m lies in front of OS@bulk",
    ),
    (
        "housing faces an unknown boundary",
        '[topology.housing.H3]\nfaces = { v = ["sky"], u = "-", src = "seed" }',
        "topology.housing.H3.faces",
        "names sky, which is no boundary",
    ),
    (
        "coupling of an unknown member",
        '[topology.coupling."2M/MS"]\njoins = { v = ["2X", "MS"], u = "-", src = "seed" }',
        "topology.coupling.2M/MS.joins",
        "names 2X, which is no shaft, wheel or planetary member",
    ),
    (
        "drive from an unknown shaft",
        '[topology.drive]\ninput_shaft = { v = "XS", u = "-", src = "seed" }',
        "topology.drive.input_shaft",
        "'XS' is no shaft of the description",
    ),
    (
        "oil jet at an unknown part",
        '[topology.oil]\njets = { v = ["BIF", "XX"], u = "-", src = "seed" }',
        "topology.oil.jets",
        "names XX, which is no part of the description",
    ),
    (
        "housing joined to itself",
        '[topology.housing.H2]\njoined_to = { v = "H2", u = "-", src = "seed" }',
        "topology.housing.H2.joined_to",
        "= 'H2' is no other housing",
    ),
    (
        "limits file missing",
        '[topology.published]\nlimits = { v = "nolimits.toml", u = "-", src = "assumed" }',
        "topology.published.limits",
        "= 'nolimits.toml' is no file beside the description or shipped with it",
    ),
    (
        "mesh of two wheels on one shaft",
        '[topology.mesh.C]\nwheels = { v = ["1M", "CM"], u = "-", src = "seed" }',
        "topology.mesh.C.wheels",
        "sit on one shaft (MS) and cannot mesh",
    ),
    (
        "fixed-ratio drive with many gears",
        '[topology.drive]\nkind = { v = "fixed_ratio", u = "-", src = "assumed" }',
        "topology.gear",
        "must hold exactly one gear (besides neutral) for a fixed-ratio drive",
    ),
    (
        "unknown field of an entry",
        '[topology.oil]\nvolume = { v = 13.5, u = "L", src = "assumed", nte = "x" }',
        "topology.oil.volume",
        "has an unknown field nte (did you mean note?); an entry's fields: v, u, src, ref, note, lo, hi, from",
    ),
    (
        "boundary below absolute zero",
        '[topology.boundary.ambient]\ntemperature = { v = -300, u = "degC", src = "assumed" }',
        "topology.boundary.ambient.temperature",
        "= -300 degC lies outside the plausible range -40..200 degC (the oil model's;",
    ),
    (
        "boundary hotter than any gearbox",
        '[topology.boundary.cold_surroundings]\ntemperature = { v = 500, u = "degC", src = "assumed" }',
        "topology.boundary.cold_surroundings.temperature",
        "= 500 degC lies outside the plausible range -40..200 degC",
    ),
    (
        "wheel immersion over 1",
        '[topology.wheel.LL]\nimmersion = { v = 30, u = "-", src = "assumed" }',
        "topology.wheel.LL.immersion",
        "= 30 must be greater than zero and at most 1 (a share of the whole: 0..1)",
    ),
    (
        "bearing immersion over 1",
        '[topology.bearing.BLF]\nimmersion = { v = 1.5, u = "-", src = "assumed" }',
        "topology.bearing.BLF.immersion",
        "= 1.5 must be greater than zero and at most 1",
    ),
    (
        "fixed wheel smaller than its shaft",
        '[topology.shaft.LS]\nd_out = { v = 200, u = "mm", src = "assumed" }',
        "topology.wheel.LL",
        "has a root diameter of 170.7 mm, not larger than its shaft LS's d_out 200 mm: the wheel is smaller",
    ),
    (
        "cut wheel inside its shaft",
        '[topology.shaft.LS]\nd_out = { v = 90, u = "mm", src = "assumed" }',
        "topology.wheel.CL",
        "has a tip diameter of 85.02 mm, not larger than its shaft LS's d_out 90 mm",
    ),
    (
        "idle wheel bore inside its shaft",
        '[topology.wheel.3M]\nbore = { v = 60, u = "mm", src = "assumed" }',
        "topology.wheel.3M.bore",
        "= 60 mm is not larger than its shaft MS (d_out = 70 mm): an idle wheel turns on a bearing around its shaft",
    ),
    (
        "bearing bore far below its shaft",
        '[topology.bearing.BO]\nbore = { v = 50, u = "mm", src = "assumed" }',
        "topology.bearing.BO.bore",
        "= 50 mm is too small for its shaft OS (d_out = 80 mm, 1.60 times the bore): a bearing seat is a journal",
    ),
    ("a file without a topology", ("whole", '[meta]\nvariant = "X"\n'), "[topology]", "is missing: the file describes"),
    (
        "wheel position in metres for millimetres",
        '[topology.wheel.LL]\nx = { v = 85, u = "m", src = "assumed" }',
        "topology.wheel.LL.x",
        '= 85 m lies outside shaft LS, 0.031..0.53 m (another unit? millimetres are written u = "mm")',
    ),
    (
        "bearing beyond its shaft's end",
        '[topology.bearing.BLR]\nx = { v = 0.9, u = "m", src = "assumed" }',
        "topology.bearing.BLR.x",
        "= 0.9 m lies outside shaft LS, 0.031..0.53 m",
    ),
    (
        "housing mass in tonnes written as kilograms",
        '[topology.housing.H1]\nmass = { v = 0.048, u = "kg", src = "assumed" }',
        "topology.housing.H1",
        "has a mass of 0.048 kg over 2.4 m2 of aluminium (2700 kg/m3): a wall 0.00741 mm thick",
    ),
    (
        "wheel nearer another segment than its own",
        '[topology.wheel.LL]\nx = { v = 0.3, u = "m", src = "assumed" }',
        "topology.wheel.LL.x",
        "= 0.3 m is nearer segment LS@1L (0.319 m) than its own segment LS@LL (0.085 m)",
    ),
]


def _write(tmp_path, body) -> str:
    f = tmp_path / "p.toml"
    if isinstance(body, tuple):  # a whole file that inherits nothing
        f.write_text(body[1])
    elif body is None:  # a whole copy of GRS905 without the planetary set's ring
        text = (PARAM_DIR / "GRS905.toml").read_text()
        line = 'ring = { v = "PR", u = "-", src = "seed", ref = "2.2" }\n'
        assert text.count(line) == 1
        f.write_text(text.replace(line, ""))
    else:
        f.write_text('[meta]\ninherit = "GRS905"\n\n' + body + "\n")
    return str(f)


@pytest.mark.parametrize("case, body, key, why", MALFORMED, ids=[m[0] for m in MALFORMED])
def test_a_malformed_description_is_one_sentence_naming_the_file_and_the_key(tmp_path, capsys, case, body, key, why):
    path = _write(tmp_path, body)
    with pytest.raises(ParameterError) as exc:
        load_description(path)
    msg = str(exc.value)
    assert "\n" not in msg and msg.startswith(f"p.toml: {key} "), msg
    assert why in msg, msg
    assert main(["describe", "--gearbox", path]) == 2
    captured = capsys.readouterr()
    assert captured.err == f"gearbox-vsensor describe: error: {msg}\n" and "Traceback" not in captured.err
    assert captured.out == ""


def test_there_are_at_least_twenty_distinct_malformed_descriptions():
    assert len({m[0] for m in MALFORMED}) == len(MALFORMED) >= 20
    assert len({(m[2], m[3]) for m in MALFORMED}) == len(MALFORMED)


def test_the_documented_example_loads_as_written(tmp_path):
    """docs/description.md's single-stage reducer: a description that inherits nothing, with one gear."""
    import re
    from pathlib import Path

    text = (Path(__file__).resolve().parents[2] / "docs" / "description.md").read_text(encoding="utf-8")
    f = tmp_path / "r1.toml"
    f.write_text(re.search(r"```toml\n(.*?)```", text, re.S).group(1))
    d = load_description(f)
    assert d.name == "R1" and d.drive.kind == "fixed_ratio" and [g.name for g in d.gears] == ["G"]
    assert d.gears[0].ratio == pytest.approx(-77 / 19, rel=1e-12)
    assert d.nodes == (
        "IN@B1",
        "IN@P",
        "IN@B2",
        "OUT@B3",
        "OUT@W",
        "OUT@B4",
        "P",
        "W",
        "B1",
        "B2",
        "B3",
        "B4",
        "H",
        "oil",
    )
    assert [(c.id, c.group) for c in d.published][-1] == ("oil", "oil")


def test_a_calibrated_parameter_file_keeps_the_description(tmp_path):
    """calibrate writes every entry of its base file again: the topology's lists and { from } entries too, so the
    calibrated file is the same description (with the fitted values where it takes them from parameters)."""
    from types import SimpleNamespace

    from tools.diagnosis.calibrate import calibrated_toml

    cal = SimpleNamespace(
        train=["a.csv"],
        test=["b.csv"],
        test_rms_c=(2.0, 1.0),
        thin_evidence=lambda: "",
        fitted={"wheel.x_LI": 0.09},
        sigma={"wheel.x_LI": 0.001},
        at_bound={"wheel.x_LI": False},
    )
    p = load_parameters("GRS905")
    f = tmp_path / "cal.toml"
    f.write_text(calibrated_toml("GRS905", p, cal, "2026-12-04"))
    assert load_parameters(f).values == {**p.values, "wheel.x_LI": 0.09}
    d, ref = load_description(f), load_description("GRS905")
    assert d.nodes == ref.nodes and [g.ratio for g in d.gears] == [g.ratio for g in ref.gears]
    assert d.wheel("LI").x_m == 0.09 and d.provenance["topology.wheel.LI.x"] == "fitted"


def test_the_geometry_is_built_from_the_description(tmp_path):
    """A file that inherits the GRS905 and mounts the layshaft's first-gear wheel on it instead of cutting it into
    it gets a wheel with the shaft inside (no cut-wheel web), and its meshes from the description's."""
    (tmp_path / "fixed_1L.toml").write_text(
        '[meta]\ninherit = "GRS905"\n[topology.wheel.1L]\nmount = { v = "fixed", u = "-", src = "assumed" }\n'
    )
    p0, p1 = load_parameters("GRS905"), load_parameters(tmp_path / "fixed_1L.toml")
    g0, g1 = G.build_geometry(p0), G.build_geometry(p1)
    R_ls = p0["shaft.LS.d_out"] / 2
    assert g0.wheels["1L"].R_in > R_ls and g1.wheels["1L"].R_in == R_ls
    assert g1.wheels["CL"] == g0.wheels["CL"] and g1.meshes == g0.meshes
    assert set(g0.meshes) == {m.id for m in load_description("GRS905").meshes}


def test_a_parameter_sets_description_follows_its_overrides():
    p = load_parameters("GRS905")
    q = p.with_overrides({"gear.3.width1": 0.035}).with_cooler_kind("none")
    assert description_of(p) == load_description("GRS905")
    assert description_of(q).wheel("3M").width_m == 0.035 and description_of(q).wheel("3L").width_m == 0.04
    assert (
        G.build_geometry(q).meshes["3"].face_width_m == 0.035 and G.build_geometry(p).meshes["3"].face_width_m == 0.04
    )


def test_the_network_is_built_from_the_description(tmp_path):
    """A file that inherits the GRS905 and changes its description (the bearing housing cast iron, the end yoke's
    conductance, the end yoke segment 10 mm further back) gets a network that follows; nothing else changes."""
    p0 = load_parameters("GRS905")
    x_ey = p0["shaft.OS.x_EY"] + 0.01
    (tmp_path / "changed.toml").write_text(
        '[meta]\ninherit = "GRS905"\n'
        '[topology.housing.H3]\nmaterial = { v = "cast_iron", u = "-", src = "assumed" }\n'
        '[topology.boundary.end_yoke]\nconductance = { v = 7.5, u = "W/K", src = "assumed" }\n'
        f'[topology.shaft.OS.x]\n"OS@EY" = {{ v = {x_ey!r}, u = "m", src = "assumed" }}\n'
    )
    n0, n1 = N.build_network(p0), N.build_network(load_parameters(tmp_path / "changed.toml"))
    i_h3 = n0.nodes.index("H3")
    assert n1.C_j_per_k[i_h3] == p0["housing.mass_H3"] * p0["material.cast_iron.cp"] != n0.C_j_per_k[i_h3]
    k_ey = n1.link_name.index("bc:OS@EY-end_yoke")
    assert n1.link_G0[k_ey] == 7.5 and n0.link_G0[k_ey] == p0["housing.G_OS_endyoke"]
    assert n1.segment_length_m["OS@EY"] > n0.segment_length_m["OS@EY"]
    assert n1.segment_length_m["IS@LI"] == n0.segment_length_m["IS@LI"] and n1.nodes == n0.nodes


def test_the_network_takes_the_descriptions_boundaries(tmp_path):
    """Another boundary list (the GRS905's with its ambient moved first) is the network's, in the file's order: the
    links index it. (It was renamed air too: a boundary touching nothing is refused unless a cooler reaches it, as
    the air cooler its ambient.)"""
    text = (PARAM_DIR / "GRS905.toml").read_text()
    i, j = text.index("[topology.boundary.ambient]"), text.index("# the published components")
    air = text[i:j]
    text = text[:i] + text[j:]
    k = text.index("[topology.boundary.engine_shaft]")
    (tmp_path / "other_boundaries.toml").write_text(text[:k] + air + text[k:])
    n0, n1 = (
        N.build_network(load_parameters("GRS905")),
        N.build_network(load_parameters(tmp_path / "other_boundaries.toml")),
    )
    assert n1.boundaries == ("ambient",) + N.BOUNDARIES[:-1] and n0.boundaries == N.BOUNDARIES
    assert n1.link_name == n0.link_name
    ext = n0.link_b >= n0.n
    assert [n1.boundaries[i - n1.n] for i in n1.link_b[ext]] == [n0.boundaries[i - n0.n] for i in n0.link_b[ext]]


def test_what_dips_and_what_is_splashed_comes_from_the_description(tmp_path):
    """A file whose reverse idler and rear layshaft bearing no longer dip, whose output bearing is not splashed and
    whose crawler wheel has covered sides: the network's immersion and splash links follow."""
    dips = '["LL", "3L", "2L", "1L", "CL", "RL", "BLF"]'
    splashed = '["LI.teeth", "3M.teeth", "2M.teeth", "1M.teeth", "CM.teeth", "RM.teeth", "OS@bulk", "PR", "BIF", '
    splashed += '"BLF", "BLR", "BMR"]'
    (tmp_path / "oil.toml").write_text(
        '[meta]\ninherit = "GRS905"\n'
        f'[topology.oil]\ndipping = {{ v = {dips}, u = "-", src = "assumed" }}\n'
        f'splashed = {{ v = {splashed}, u = "-", src = "assumed" }}\n'
        '[topology.wheel.CM]\nsides = { v = "covered", u = "-", src = "assumed" }\n'
    )
    n0, n1 = N.build_network(load_parameters("GRS905")), N.build_network(load_parameters(tmp_path / "oil.toml"))
    gone = set(n0.link_name) - set(n1.link_name)
    assert gone == {"imm:RI", "imm:BLR", "bsplash:BO"} and set(n1.link_name) <= set(n0.link_name)
    k_cm, k_rm = n0.link_name.index("splash:CM.teeth"), n0.link_name.index("splash:RM.teeth")
    g1 = dict(zip(n1.link_name, n1.link_G0))
    assert g1["splash:CM.teeth"] < n0.link_G0[k_cm] and g1["splash:RM.teeth"] == n0.link_G0[k_rm]


def test_what_the_pumped_oil_reaches_comes_from_the_description(tmp_path):
    """A file whose pump no longer feeds the main shaft's rear segment, the pilot bearing and one needle bearing
    loses exactly those oil-system streams."""
    d = load_description("GRS905")
    jets = [j for j in d.oil.jets if j not in ("MS@PS", "BIM", "CB")]
    (tmp_path / "jets.toml").write_text(
        f'[meta]\ninherit = "GRS905"\n[topology.oil]\njets = {{ v = {jets!r}, u = "-", src = "assumed" }}\n'.replace(
            "'", '"'
        )
    )
    n0, n1 = N.build_network(load_parameters("GRS905")), N.build_network(load_parameters(tmp_path / "jets.toml"))
    assert set(n0.link_name) - set(n1.link_name) == {"oilsys:MS@PS", "oilsys:BIM", "oilsys:CB"}
    assert set(n1.link_name) <= set(n0.link_name)


def test_describe_checks_the_parameter_values_as_every_command_does(tmp_path, capsys):
    """describe exited 0 on a copy with a steel cp of 0 or a value outside its bounds, which simulate and replay
    refuse: now the same sentence."""
    text = (PARAM_DIR / "R1.toml").read_text()
    line = next(ln for ln in text.splitlines() if ln.startswith("cp = ") and "J/(kg K)" in ln)
    bad = tmp_path / "cp0.toml"
    bad.write_text(text.replace(line, re.sub(r"v = [0-9.eE+-]+", "v = 0", line, count=1), 1))
    assert main(["describe", "--gearbox", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "cp0.toml" in err and "must be greater than zero" in err and len(err.strip().splitlines()) == 1
    assert main(["describe", "--gearbox", "R1"]) == 0


def _with_limits(tmp_path, *edits) -> str:
    """A GRS905 copy whose published.limits is the shipped limits.toml with its [oil] section edited (old, new)."""
    text = (PARAM_DIR / "limits.toml").read_text()
    head, oil = text[: text.index("[oil]")], text[text.index("[oil]") :]
    for old, new in edits:
        assert oil.count(old) == 1, old
        oil = oil.replace(old, new)
    (tmp_path / "my_limits.toml").write_text(head + oil)
    f = tmp_path / "p.toml"
    f.write_text(
        '[meta]\ninherit = "GRS905"\n\n[topology.published]\n'
        'limits = { v = "my_limits.toml", u = "-", src = "assumed" }\n'
    )
    return str(f)


OIL_WARNING = 'warning = { v = 120, u = "degC"'


@pytest.mark.parametrize(
    "old, new, why",
    [
        (OIL_WARNING, 'warning = { v = 140, u = "degC"', "limits of oil: warning 140 degC must be below critical 135"),
        (OIL_WARNING, 'warnng = { v = 90, u = "degC", src = "assumed" }\n' + OIL_WARNING, "unknown key oil.warnng"),
        ('hysteresis = { v = 3, u = "K"', 'hysteresis = { v = 3, u = "degC"', "oil.hysteresis has unit 'degC'"),
    ],
    ids=["warning above critical", "unknown key", "hysteresis in degC"],
)
def test_describe_refuses_the_limits_file_replay_refuses(tmp_path, capsys, old, new, why):
    """describe printed 'oil 140/135' for a warning above critical and passed an unknown key or a hysteresis in degC
    that replay refuses: both read the file with one loader now (firmware_model.limits.load_limits)."""
    from firmware_model.onboard.warning_levels import load_limits

    path = _with_limits(tmp_path, (old, new))
    with pytest.raises(ParameterError) as exc:
        load_description(path)
    msg = str(exc.value)
    assert "\n" not in msg and msg.startswith("p.toml: topology.published.limits = 'my_limits.toml' is refused: ")
    assert why in msg, msg
    with pytest.raises(ParameterError) as replays:  # the sensor's loader (replay, simulate) says the same
        load_limits(tmp_path / "my_limits.toml", published=load_description("GRS905").published)
    assert msg.endswith(str(replays.value))
    assert main(["describe", "--gearbox", path]) == 2
    assert capsys.readouterr().err == f"gearbox-vsensor describe: error: {msg}\n"


def test_a_warning_limit_below_every_boundary_is_a_note(tmp_path, capsys):
    """An oil warning limit of 15 degC with the coldest boundary at 25 degC is critical from t = 0: describe says so
    on stderr (a run table's ambient may be colder than the default, so it is no error)."""
    path = _with_limits(
        tmp_path, (OIL_WARNING, 'warning = { v = 15, u = "degC"'), ("critical = { v = 135,", "critical = { v = 19,")
    )
    assert main(["describe", "--gearbox", path]) == 0
    captured = capsys.readouterr()
    assert "oil 15/19" in captured.out
    assert captured.err == (
        "note: p.toml: oil's warning limit 15 degC (my_limits.toml, group oil) lies at or below every boundary's "
        "temperature (the coldest, ambient, is 25 degC): oil cannot cool below it and is critical from the start\n"
    )
    assert main(["describe"]) == 0 and capsys.readouterr().err == ""


def test_an_oil_cooler_without_a_pump_or_against_the_description_is_one_sentence(tmp_path, capsys):
    """An 'air' cooler on a splash-lubricated gearbox without a pump took no heat (the oil at 178 degC, the cooler's
    0 W, exit 0): a cooler takes its heat from the oil the pump drives through it. A run's cooler kind that asks for
    a cooler the description does not have (a configuration's [cooler] kind = "air" on R1's cooler = "none") is
    refused the same way; leaving the cooler out ("none") or holding the sump stays allowed."""
    from firmware_model.config import load_config
    from firmware_model.description import description_of
    from tools.cli.gearbox_option import with_gearbox

    text = (PARAM_DIR / "HR225.toml").read_text()
    line = next(ln for ln in text.splitlines() if ln.startswith('kind = { v = "none"'))
    air = tmp_path / "air.toml"
    air.write_text(text.replace(line, 'kind = { v = "air", u = "-", src = "assumed" }', 1))
    with pytest.raises(ParameterError, match="cooler = 'air': an oil cooler takes its heat from the oil a pump"):
        load_description(str(air))
    assert main(["describe", "--gearbox", str(air)]) == 2 and "no pump (pump_flow)" in capsys.readouterr().err
    cfg = with_gearbox(load_config(None), "R1")
    for kind, refused in (("air", True), ("liquid", True), ("none", False), ("hold", False)):
        cfg.cooler = kind
        if refused:
            with pytest.raises(ParameterError, match=f"but the run's cooler kind is '{kind}'"):
                description_of(cfg.load_params())
        else:
            description_of(cfg.load_params())


def test_unit_and_sign_mistakes_are_said_as_such(tmp_path):
    """A reverse gear written with a positive ratio was "off the ratio of the teeth by 200.00%"; a temperature in
    "K" read like a dimension error; "N m" (as the SCADA maps write it) was no unit. Now: the sign named, kelvin
    named, "N m" a torque."""
    text = (PARAM_DIR / "GRS905.toml").read_text()
    flipped = tmp_path / "flip.toml"
    flipped.write_text(text.replace('ratio = { v = -15.27, u = "-"', 'ratio = { v = 15.27, u = "-"', 1))
    with pytest.raises(
        ParameterError, match=r"topology.gear.RL.ratio = 15.27 has the wrong sign: .* against the input"
    ):
        load_description(str(flipped))
    nm = tmp_path / "nm.toml"
    nm.write_text(text.replace('max_torque = { v = 4200, u = "Nm"', 'max_torque = { v = 4200, u = "N m"', 1))
    assert load_description(str(nm)).drive.max_torque_nm == 4200.0
    r1 = (PARAM_DIR / "R1.toml").read_text()
    kelvin = tmp_path / "k.toml"
    line = next(ln for ln in r1.splitlines() if ln.startswith("temperature = ") and '"degC"' in ln)
    kelvin.write_text(r1.replace(line, line.replace('"degC"', '"K"'), 1))
    with pytest.raises(ParameterError, match=r"has unit 'K' \(a temperature difference, or kelvin\), but it is a temp"):
        load_description(str(kelvin))


def test_describe_names_every_physics_parameter_simulate_and_replay_would_ask_for(tmp_path, capsys):
    """A user's description passed describe and then simulate asked for one missing physics parameter per run
    (ten runs for ten keys). describe now builds the plant and the sensor and names them all at once."""
    src = (Path(__file__).parent / "gearboxes" / "T6.toml").read_text()
    gone = ("h_t0 = ", "side_width_in_frac = ", "sf_radial_needle = ")
    lacking = tmp_path / "T6lacking.toml"
    lacking.write_text("\n".join(ln for ln in src.splitlines() if not ln.startswith(gone)) + "\n")
    assert main(["describe", "--gearbox", str(lacking)]) == 2
    err = capsys.readouterr().err
    for key in ("oil.h_t0", "wheel.side_width_in_frac", "wheel_bearing.sf_radial_needle"):
        assert key in err, err
    assert len(err.strip().splitlines()) == 1
    assert main(["describe", "--gearbox", str(Path(__file__).parent / "gearboxes" / "T6.toml")]) == 0


def test_describe_refuses_what_simulate_cannot_build(tmp_path, capsys):
    """describe passed a file simulate then refused: a spherical bearing without the spherical kind's keys (which
    the GRS905, the first donor of missing keys, has not), and a mesh whose teeth interfere (simulate's sentence
    named neither the mesh nor the file)."""
    src = (Path(__file__).parent / "gearboxes" / "T6.toml").read_text()
    assert "bearing.f0_spherical" not in src
    f = tmp_path / "T6sph.toml"
    f.write_text(src.replace('kind = { v = "tapered"', 'kind = { v = "spherical"', 1))
    assert main(["describe", "--gearbox", str(f)]) == 2
    err = capsys.readouterr().err
    assert "T6sph.toml: simulate and replay need physics parameters the file lacks: " in err
    assert "bearing.f0_spherical" in err and "the GRS905 has none" in err and len(err.strip().splitlines()) == 1
    out = str(tmp_path / "s.csv")
    assert main(["simulate", "--gearbox", str(f), "--cycle", "steady:gear=1,rpm=1000,nm=100,s=10", "--out", out]) == 2
    capsys.readouterr()
    g = tmp_path / "T6flat.toml"  # a 14 deg normal pressure angle: the 20-tooth pinion's mesh interferes
    g.write_text(re.sub(r"^alpha_n = \{ v = 20,", "alpha_n = { v = 14,", src, count=1, flags=re.M))
    assert main(["describe", "--gearbox", str(g)]) == 2
    err = capsys.readouterr().err
    assert "T6flat.toml: simulate and replay cannot build this gearbox: mesh K (KI z 20, KC z 40): " in err, err
    assert "involute interference" in err


def test_a_sump_smaller_than_its_dipping_wheels_immersed_part_is_one_sentence(tmp_path):
    """The HR225's wheel dips 6 % of its tip diameter: 0.19 L under the oil; a volume of 0.02 L (litres for
    millilitres, or cm3 for litres) passed and cut the churning sevenfold. Its own 14 L passes."""
    f = tmp_path / "p.toml"
    f.write_text('[meta]\ninherit = "HR225"\n\n[topology.oil]\nvolume = { v = 0.02, u = "L", src = "assumed" }\n')
    with pytest.raises(ParameterError, match=r"p.toml: topology.oil.volume = 0.02 L is less than the dipping wheels' "):
        load_description(str(f))
    assert load_description("HR225").oil.volume_m3 == pytest.approx(0.014)


# ---------------------------------------------------------------------------------------------------------------
# a newcomer's trial (a two-stage helical reducer): description mistakes that passed describe and gave silently
# wrong temperatures, exit 0; each is now one sentence. The files are the HR225's, edited.


def _hr225(tmp_path, *edits, name="p.toml") -> str:
    """The HR225's file with (old, new) text replacements, each made once (and present)."""
    text = (PARAM_DIR / "HR225.toml").read_text()
    for old, new in edits:
        assert text.count(old) >= 1, old
        text = text.replace(old, new, 1)
    f = tmp_path / name
    f.write_text(text)
    return str(f)


def _refused(path, key, why, capsys):
    """load_description refuses the file with one sentence naming the key; describe says it, exit 2."""
    with pytest.raises(ParameterError) as exc:
        load_description(path)
    msg = str(exc.value)
    assert "\n" not in msg and msg.startswith(f"{Path(path).name}: {key} "), msg
    assert why in msg, msg
    assert main(["describe", "--gearbox", path]) == 2
    assert capsys.readouterr().err == f"gearbox-vsensor describe: error: {msg}\n"
    return msg


def test_positions_in_metres_for_millimetres_make_a_shaft_too_long(tmp_path, capsys):
    """Every position of the description in mm but written u = "m" (the shafts, wheels and bearings scaled alike, so
    every wheel and bearing lies on its shaft): shafts 300 m long passed and the sump read 31 degC for 55."""
    text = (PARAM_DIR / "HR225.toml").read_text()
    head, topo = text.split("[topology", 1)

    def mm_as_m(m):
        return f"{m.group(1)}{float(m.group(2)) * 1e3:g}{m.group(3)}"

    topo = re.sub(r'(= \{ v = )([0-9.]+)(, u = "m")', mm_as_m, topo)
    f = tmp_path / "p.toml"
    f.write_text(head + "[topology" + topo)
    msg = _refused(str(f), "topology.shaft.IN", "is 350 m long (its segments over 200 m, ends 140 m and 10 m", capsys)
    assert "more than 2 times the square root of its housings' total area (1.79 m, of 3.2 m2)" in msg
    assert '(another unit? millimetres are written u = "mm")' in msg, msg


def test_an_overhang_in_metres_for_millimetres_makes_a_shaft_too_long(tmp_path, capsys):
    """An output shaft end of 190 m (190 mm written u = "m") on segments 0.2 m apart."""
    path = _hr225(tmp_path, ('overhang_rear = { v = 0.19, u = "m"', 'overhang_rear = { v = 190, u = "m"'))
    _refused(path, "topology.shaft.OUT", "is 190.2 m long (its segments over 0.2 m, ends 0.01 m and 190 m", capsys)


def test_a_bearing_mass_in_grams_or_tonnes_is_one_sentence(tmp_path, capsys):
    """A 32222 bearing (110 x 200 x 56 mm) of 6900 kg (grams written kg) passed; so would 0.0069 kg (tonnes)."""
    line = 'mass = { v = 6.9, u = "kg"'
    path = _hr225(tmp_path, (line, 'mass = { v = 6900, u = "kg"'))
    msg = _refused(path, "topology.bearing.B3.mass", "= 6900 kg is 716 times what its rings would weigh", capsys)
    assert "a bearing weighs 0.1-2 times that" in msg, msg
    path = _hr225(tmp_path, (line, 'mass = { v = 0.0069, u = "kg"'), name="t.toml")
    _refused(path, "topology.bearing.B3.mass", "= 0.0069 kg is 0.000716 times what its rings would weigh", capsys)


def test_a_housing_facing_nothing_is_one_sentence(tmp_path, capsys):
    """A housing facing no boundary (faces = []) loses no heat from its outside: the sump read the shafts' ends."""
    path = _hr225(tmp_path, ('faces = { v = ["ambient"]', "faces = { v = []"))
    _refused(path, "topology.housing.H.faces", "is empty: the housing's outside", capsys)


def test_a_boundary_touching_nothing_is_one_sentence(tmp_path, capsys):
    """docs/description.md said a boundary touching no part is refused; it was not. A cooler's coolant or ambient
    may touch nothing (the cooler reaches it: the GRS905's), any other may not."""
    sky = '[topology.boundary.sky]\ntemperature = { v = 10, u = "degC", src = "assumed" }\n'
    sky += 'touches = { v = [], u = "-", src = "assumed" }\n'
    path = _hr225(tmp_path, ("[topology.boundary.ambient]", sky + "[topology.boundary.ambient]"))
    _refused(path, "topology.boundary.sky", "touches no part and no housing faces it", capsys)
    sky = sky.replace("touches = { v = []", 'touches = { v = ["IN@B2"]')  # without a conductance: no link
    path = _hr225(tmp_path, ("[topology.boundary.ambient]", sky + "[topology.boundary.ambient]"), name="s.toml")
    _refused(path, "topology.boundary.sky", "touches no part and no housing faces it", capsys)
    assert load_description("GRS905").boundaries[-1].touches == ()  # its air cooler's ambient


def test_splash_lubrication_with_nothing_in_the_oil_is_one_sentence(tmp_path, capsys):
    """Splash lubrication with nothing dipping and nothing splashed: the pinion ran at 257 degC, exit 0."""
    path = _hr225(
        tmp_path,
        ('dipping = { v = ["W"]', "dipping = { v = []"),
        ('splashed = { v = ["P", "B1", "B2", "B3", "B4"]', "splashed = { v = []"),
    )
    _refused(path, "topology.oil.dipping", "and splashed are empty: a splash-lubricated gearbox", capsys)
    assert load_description("R1").oil.dipping == ()  # what it splashes is enough


AUX = (
    '[topology.shaft.AUX]\nd_out = { v = 40, u = "mm", src = "assumed" }\n'
    'd_bore = { v = 0, u = "mm", src = "assumed" }\n'
    'overhang_front = { v = 0.01, u = "m", src = "assumed" }\noverhang_rear = { v = 0.01, u = "m", src = "assumed" }\n'
    'segments = { v = ["AUX@1"], u = "-", src = "assumed" }\n[topology.shaft.AUX.x]\n'
    '"AUX@1" = { v = 0.1, u = "m", src = "assumed" }\n'
)


def test_a_part_connected_to_nothing_is_one_sentence(tmp_path, capsys):
    """A shaft with no bearing, wheel or boundary passed with a numpy divide-by-zero warning, its node at its start
    temperature for ever; a shaft and its wheel joined to nothing else is said with both."""
    path = _hr225(tmp_path, ("[topology.wheel.P]", AUX + "[topology.wheel.P]"))
    msg = _refused(path, "topology.shaft.AUX", "is connected to nothing (no bearing, wheel, mesh, boundary", capsys)
    assert "AUX@1" in msg, msg
    wheel = (
        '[topology.wheel.X]\nshaft = { v = "AUX", u = "-", src = "assumed" }\n'
        'segment = { v = "AUX@1", u = "-", src = "assumed" }\nmount = { v = "fixed", u = "-", src = "assumed" }\n'
        'teeth = { v = 40, u = "-", src = "assumed" }\nmodule = { v = 3, u = "mm", src = "assumed" }\n'
        'helix = { v = 0, u = "deg", src = "assumed" }\nwidth = { v = 30, u = "mm", src = "assumed" }\n'
        'x = { v = 0.1, u = "m", src = "assumed" }\n'
    )
    path = _hr225(tmp_path, ("[topology.wheel.P]", AUX + wheel + "[topology.wheel.P]"), name="w.toml")
    _refused(path, "topology.shaft.AUX", "and wheel X are joined to one another but to no boundary", capsys)


@pytest.mark.parametrize("name", shipped_descriptions() + ("T6", "W3"))
def test_the_description_s_conduction_links_are_the_network_s(name):
    """The links the connectivity check follows (description.conduction_links) are the network's, node for node:
    what the check calls connected to nothing, the network leaves without a conductance."""
    from firmware_model.description import conduction_links

    src = Path(__file__).parent / "gearboxes" / f"{name}.toml"
    p = load_parameters(str(src) if src.is_file() else name)
    net = N.build_network(p)
    ends = net.nodes + tuple(net.boundaries)
    linked = {frozenset((ends[a], ends[b])) for a, b in zip(net.link_a, net.link_b)}
    assert {frozenset(x) for x in conduction_links(description_of(p))} == linked


def test_a_face_width_in_metres_is_one_sentence(tmp_path, capsys):
    """A face width of 75 m (mm written m) was refused as a node's explicit step (merge the node with a neighbour)."""
    path = _hr225(tmp_path, ('width = { v = 75, u = "mm"', 'width = { v = 75, u = "m"'))
    why = "= 75 m is 917 times its pitch diameter 81.8 mm (z 20, module 4 mm)"
    msg = _refused(path, "topology.wheel.P.width", why, capsys)
    assert "a face width is at most 3 times it" in msg, msg


def test_a_helix_angle_in_radians_is_one_sentence(tmp_path, capsys):
    """A helix angle of 10 written u = "rad" was refused as a wheel with a tip diameter of -103.2 mm."""
    path = _hr225(tmp_path, ('helix = { v = 12, u = "deg"', 'helix = { v = 10, u = "rad"'))
    _refused(path, "topology.wheel.P.helix", "= 10 rad (573 deg) lies outside 0..45 deg", capsys)


def test_a_description_without_its_own_limits_takes_the_truck_s_with_a_note(capsys):
    """A description without published.limits took the GRS905 truck's (oil warning 120 degC) in silence; describe
    now says so on stderr, exit 0. A description naming its limits (GRS905, MM82) is as before."""
    assert main(["describe", "--gearbox", "HR225"]) == 0
    err = capsys.readouterr().err
    assert err.startswith("note: HR225.toml: topology.published.limits is not given, so its components take "), err
    assert "limits.toml, the GRS905 truck's warning limits (gear 150 degC, bearing 120 degC, oil 120 degC)" in err
    for name in ("GRS905", "MM82"):
        assert main(["describe", "--gearbox", name]) == 0 and capsys.readouterr().err == ""

"""Schematic of the GRS905 range-splitter gearbox with every component code where it sits.

Writes docs/img/gearbox_codes.png (1400 px wide), the figure of docs/glossary.md:

    python docs/figures/gearbox_codes.py

A vertical section, engine (front) at the left. SCHEMATIC, NOT TO SCALE: the axial order of the wheels, bearings and
shaft segments follows the model (firmware_model/network.py and the axial positions in
firmware_model/params/GRS905.toml, checked below), and the wheels of each pair are sized by their tooth counts so
that meshing wheels touch; everything else (lengths, wall thicknesses, housing split lines, oil level) is drawn for
readability. Before saving, the script checks that every component id and shaft segment of the model is labelled.
"""

from __future__ import annotations

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.patches import Polygon, Rectangle  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
OUT = ROOT / "docs" / "img" / "gearbox_codes.png"
sys.path.insert(0, str(ROOT))

from firmware_model.components import (  # noqa: E402 (after the sys.path line above)
    HOUSINGS,
    IDLE_WHEELS,
    LAYSHAFT_WHEELS,
    PLANETARY,  # noqa: E402
    REVERSE_IDLER,
    SHAFT_BEARINGS,
    WHEEL_BEARINGS,
)
from firmware_model.description import load_description  # noqa: E402

#: the segments of each shaft, front to rear (the GRS905's description)
SHAFT_SEGMENTS = {s.id: tuple(g.id for g in s.segments) for s in load_description("GRS905").shafts}

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

# ---- colours
C_SHAFT, C_BULK, C_TEETH = "#9a9a9a", "#c9d8ec", "#3f6aa3"
C_LAY, C_LAY_EDGE = "#bfe0b5", "#3d7a32"
C_PS, C_PP, C_PR = "#d9b8e6", "#ecd7f3", "#8e5aa8"
C_BRG, C_BRG_TEXT = "#e07b00", "#9a4f00"
C_AL, C_FE = "#d6d6d6", "#9c9c9c"
C_OIL = "#6fa8dc"
C_BC = "#6b6b6b"

# ---- layout (schematic units); y: shaft axes, x: axial stations in the model's order
Y_UP, Y_LS = 38.0, 16.0  # input/main/output shaft axis, layshaft axis
GAP = Y_UP - Y_LS  # centre distance: meshing wheels touch
X = {
    "IS@bulk": 3.5,
    "BIF": 9.5,
    "BLF": 11.0,
    "LI": 16.0,
    "BIM": 23.5,
    "3M": 31.0,
    "2M": 40.0,
    "1M": 49.0,
    "CM": 58.0,
    "RM": 67.0,
    "RI": 72.0,
    "BLR": 76.0,
    "BMR": 76.0,
    "PS": 84.0,
    "carrier": 88.0,
    "OS@bulk": 94.0,
    "BO": 99.5,
    "EY": 105.5,
}
#: tooth counts (GRS905.toml): input/main-shaft wheel, layshaft wheel
TEETH = {"L": (28, 38), "3": (31, 34), "2": (35, 24), "1": (38, 17), "C": (42, 13), "R": (42, 14)}
#: face widths [mm] (GRS905.toml) -> drawn width / 10
WIDTH = {"L": 45, "3": 40, "2": 48, "1": 58, "C": 55, "R": 45}
HOUSING_SPAN = {"H1": (6.0, 45.0), "H2": (45.0, 90.0), "H3": (90.0, 100.5)}  # split lines approximate
TOP, BOTTOM, WALL = 58.0, 0.0, 2.0

LABELLED: set[str] = set()


def text(ax, x, y, s, *, size=11, color="black", weight="bold", box=True, ha="center", va="center", **kw):
    bbox = dict(boxstyle="round,pad=0.15", fc="white", ec="none", alpha=0.85) if box else None
    ax.text(x, y, s, fontsize=size, color=color, fontweight=weight, ha=ha, va=va, bbox=bbox, zorder=20, **kw)
    for token in s.replace("\n", " ").replace(",", " ").split():
        LABELLED.add(token)


def bearing_mark(ax, x, y, w=1.5, h=1.8):
    ax.add_patch(Rectangle((x - w / 2, y - h / 2), w, h, fc=C_BRG, ec="#6a3a00", lw=0.8, zorder=12))
    ax.plot([x - w / 2, x + w / 2], [y - h / 2, y + h / 2], color="#6a3a00", lw=0.8, zorder=13)
    ax.plot([x - w / 2, x + w / 2], [y + h / 2, y - h / 2], color="#6a3a00", lw=0.8, zorder=13)


def shaft_bearing(ax, name, x, y_axis, half, label_side):
    for s in (1, -1):
        bearing_mark(ax, x, y_axis + s * (half + 1.0))
    text(ax, x, y_axis + label_side * (half + 3.6), name, size=10.5, color=C_BRG_TEXT)


def draw_housing(ax):
    for h, (x0, x1) in HOUSING_SPAN.items():
        fc = C_FE if h == "H2" else C_AL
        for y0 in (BOTTOM, TOP):
            ax.add_patch(Rectangle((x0, y0), x1 - x0, WALL, fc=fc, ec="#555555", lw=1.0, zorder=3))
        name = {
            "H1": "H1  front housing (aluminium)",
            "H2": "H2  rear housing (cast iron)",
            "H3": "H3  bearing\nhousing (Al)",
        }[h]
        text(ax, (x0 + x1) / 2, TOP + WALL + (3.4 if h == "H3" else 2.2), name, size=11.5, box=False)
    for x0, x1, fc in ((6.0, 8.0, C_AL), (98.5, 100.5, C_AL), (75.2, 76.8, C_FE)):  # front, rear walls, H2 web
        ax.add_patch(Rectangle((x0, BOTTOM), x1 - x0, TOP + WALL - BOTTOM, fc=fc, ec="#555555", lw=1.0, zorder=3))
    for xs in (45.0, 90.0):  # split lines
        ax.plot([xs, xs], [BOTTOM - 1.0, BOTTOM + WALL + 0.5], color="black", lw=1.6, zorder=4)
        ax.plot([xs, xs], [TOP - 0.5, TOP + WALL + 1.0], color="black", lw=1.6, zorder=4)
    # oil sump: surface below the layshaft axis, rising to the rear (5 deg powertrain angle)
    ax.add_patch(
        Polygon(
            [(8.0, WALL), (98.5, WALL), (98.5, 14.3), (8.0, 8.2)],
            closed=True,
            fc=C_OIL,
            ec="#2f6fa8",
            lw=1.0,
            alpha=0.40,
            zorder=2,
        )
    )
    text(ax, 23.3, 5.0, "oil\n(sump)", size=11, color="#1d4f80")


def draw_shafts(ax):
    spans = {
        "IS": (1.0, Y_UP, 25.0, 2.6),
        "MS": (22.0, Y_UP, 86.0, 2.2),
        "LS": (9.5, Y_LS, 78.0, 2.6),
        "OS": (87.0, Y_UP, 109.0, 3.0),
    }
    for _name, (x0, y, x1, th) in spans.items():
        ax.add_patch(Rectangle((x0, y - th / 2), x1 - x0, th, fc=C_SHAFT, ec="#444444", lw=0.8, zorder=5))
    # segment boundaries as ticks on the shafts (the model's shaft discretisation)
    for shaft, (_x0, y, _x1, th) in spans.items():
        for b in segment_bounds(shaft)[1:-1]:
            ax.plot([b, b], [y - th / 2 - 0.4, y + th / 2 + 0.4], color="#333333", lw=0.9, zorder=6)
    text(ax, 3.5, Y_UP + 3.2, "IS", size=11.5, box=False)
    text(ax, 27.0, Y_UP + 2.6, "MS", size=11.5, box=False)
    text(ax, 35.5, Y_LS + 2.7, "LS", size=11.5, box=False)
    text(ax, 93.5, Y_UP + 3.2, "OS", size=11.5, box=False)


def idle_wheel(ax, wid, pair, wb):
    """Input/main-shaft wheel: teeth band (outer) and bulk; its needle bearing between bore and shaft."""
    z1, z2 = TEETH[pair]
    r = GAP * z1 / (z1 + z2)
    w = WIDTH[pair] / 10
    x = X[wid]
    band = 0.17 * r
    ax.add_patch(Rectangle((x - w / 2, Y_UP - r), w, 2 * r, fc=C_BULK, ec="#27466e", lw=1.0, zorder=7))
    for y0 in (Y_UP + r - band, Y_UP - r):
        ax.add_patch(Rectangle((x - w / 2, y0), w, band, fc=C_TEETH, ec="#27466e", lw=1.0, zorder=8))
    for s in (1, -1):
        bearing_mark(ax, x, Y_UP + s * 2.2, w=min(w - 0.8, 2.6), h=1.2)
    text(ax, x, Y_UP + 0.55 * r, wid, size=12)
    text(ax, x, Y_UP - 0.55 * r, wb, size=10.5, color=C_BRG_TEXT)
    return r


def layshaft_wheel(ax, wid, pair):
    z1, z2 = TEETH[pair]
    r = GAP * z2 / (z1 + z2)
    w = WIDTH[pair] / 10
    x = X[{"L": "LI", "3": "3M", "2": "2M", "1": "1M", "C": "CM", "R": "RM"}[pair]]
    ax.add_patch(Rectangle((x - w / 2, Y_LS - r), w, 2 * r, fc=C_LAY, ec=C_LAY_EDGE, lw=1.2, zorder=7))
    text(ax, x, Y_LS + max(0.55 * r, 3.1), wid, size=12)


def reverse_idler(ax):
    r, w, y = 4.2, 3.4, Y_LS + GAP * 14 / 56
    ax.add_patch(Rectangle((X["RI"] - w / 2, y - r), w, 2 * r, fc=C_LAY, ec=C_LAY_EDGE, lw=1.2, ls="--", zorder=7))
    text(ax, X["RI"], y, "RI", size=12)
    ax.annotate(
        "",
        xy=(X["RI"] - w / 2, y + 1.5),
        xytext=(X["RM"] + 2.3, y + 2.5),
        arrowprops=dict(arrowstyle="-", ls=":", color=C_LAY_EDGE, lw=1.2),
        zorder=6,
    )
    ax.annotate(
        "",
        xy=(X["RI"] - w / 2, y - 1.5),
        xytext=(X["RM"] + 2.3, Y_LS + 3.0),
        arrowprops=dict(arrowstyle="-", ls=":", color=C_LAY_EDGE, lw=1.2),
        zorder=6,
    )


def planetary(ax):
    """Sun on the main shaft, planets on the carrier (front of the output shaft), ring around them."""
    x, w = X["PS"], 4.5
    r_s = 5.0
    r_r = r_s * 88 / 32  # ring / sun tooth counts
    r_p = (r_r - r_s) / 2
    ax.add_patch(Rectangle((x - w / 2, Y_UP - r_s), w, 2 * r_s, fc=C_PS, ec="#5b2f73", lw=1.1, zorder=9))
    text(ax, x, Y_UP + 2.9, "PS", size=12)
    for s in (1, -1):
        yc = Y_UP + s * (r_s + r_p)
        ax.add_patch(Rectangle((x - w / 2, yc - r_p), w, 2 * r_p, fc=C_PP, ec="#5b2f73", lw=1.1, zorder=9))
        ax.add_patch(
            Rectangle(
                (x - w / 2 - 0.6, yc - 0.35), X["carrier"] - x + w / 2 + 0.6, 0.7, fc="#555555", ec="none", zorder=10
            )
        )  # planet pin
        text(ax, x - 0.6, yc + s * 1.8, "PP", size=12)
        ax.add_patch(
            Rectangle(
                (x - w / 2 - 0.3, Y_UP + s * r_r - (0 if s > 0 else 1.8)),
                w + 0.6,
                1.8,
                fc=C_PR,
                ec="#3d1f4d",
                lw=1.1,
                zorder=9,
            )
        )
        text(ax, x - w / 2 - 2.4, Y_UP + s * (r_r + 0.9), "PR", size=12)
    yc = r_s + r_p
    ax.add_patch(
        Rectangle(
            (X["carrier"] - 0.6, Y_UP - yc - 1.0), 1.2, 2 * yc + 2.0, fc="#7a7a7a", ec="#333333", lw=0.8, zorder=8
        )
    )  # carrier plate
    text(ax, X["carrier"] + 0.2, Y_UP + yc + 3.2, "carrier", size=9.5, weight="normal", box=False)


def boundaries(ax):
    kw = dict(size=9.5, color=C_BC, weight="normal", style="italic")
    for label, y_text, y_tip in (("LI.teeth", 55.0, Y_UP + 8.4), ("LI.bulk", 50.0, Y_UP + 5.0)):
        ax.annotate(
            label,
            xy=(X["LI"] - 1.6, y_tip),
            xytext=(-0.5, y_text),
            fontsize=10,
            fontweight="bold",
            color="#27466e",
            va="center",
            zorder=21,
            arrowprops=dict(arrowstyle="->", color="#27466e", lw=1.0, shrinkA=2, shrinkB=0),
        )
    text(ax, -0.6, Y_UP - 4.6, "engine_shaft\n(clutch side)", ha="left", box=False, **kw)
    text(ax, 4.3, 14.0, "flywheel_cover", rotation=90, box=False, **kw)
    text(ax, 60.0, TOP + WALL + 5.4, "support_beam (on top of H2)", box=False, **kw)
    ax.add_patch(Rectangle((103.5, Y_UP - 6.0), 4.0, 12.0, fc="#bdbdbd", ec="#444444", lw=1.0, zorder=4))
    text(ax, 105.5, Y_UP + 8.6, "EY end yoke\n(end_yoke)", size=9.5, color=C_BC, weight="normal", box=False)
    text(
        ax,
        105.5,
        14.0,
        "hot_surroundings,\ncold_surroundings:\nair around\nH1, H2, H3",
        size=9,
        color=C_BC,
        weight="normal",
        style="italic",
        box=False,
    )


def segment_bounds(shaft):
    lay_to_idle = dict(zip(LAYSHAFT_WHEELS, IDLE_WHEELS))  # a layshaft wheel sits below its pair partner
    pos = []
    for n in SHAFT_SEGMENTS[shaft]:
        where = n.split("@")[1]
        pos.append(X[n] if n in X else X[lay_to_idle.get(where, where)])
    ends = {"IS": (1.0, 25.0), "LS": (9.5, 78.0), "MS": (22.0, 86.0), "OS": (87.0, 109.0)}[shaft]
    return [ends[0]] + [(a + b) / 2 for a, b in zip(pos, pos[1:])] + [ends[1]]


def segment_strips(ax):
    """One strip per shaft below the section, aligned in x with it: the model's shaft segments."""
    names = {"IS": "input shaft", "LS": "layshaft", "MS": "main shaft", "OS": "output shaft"}
    y = -6.0
    for shaft in ("IS", "MS", "LS", "OS"):
        b = segment_bounds(shaft)
        for nm, x0, x1 in zip(SHAFT_SEGMENTS[shaft], b, b[1:]):
            ax.add_patch(Rectangle((x0, y - 5.0), x1 - x0, 5.0, fc="#eeeeee", ec="#555555", lw=0.8, zorder=3))
            s, where = nm.split("@")
            text(ax, (x0 + x1) / 2, y - 2.5, f"{s}@\n{where}", size=8.6, weight="normal", box=False, linespacing=0.95)
            LABELLED.add(nm)
        if shaft == "IS":  # row name right of the IS strip, left of the others
            text(ax, b[-1] + 0.8, y - 2.5, f"{shaft}  {names[shaft]}", size=10, ha="left", box=False)
        else:
            text(ax, b[0] - 0.8, y - 2.5, f"{shaft}  {names[shaft]}", size=10, ha="right", box=False)
        y -= 5.8
    text(
        ax,
        44.0,
        y - 0.6,
        "shaft segments <shaft>@<what it sits under>, aligned with the section above "
        "(ticks on the shafts mark their boundaries)",
        size=10,
        weight="normal",
        box=False,
    )


def legend(ax):
    y = -35.0
    items = [
        ((C_BULK, C_TEETH), "input/main-shaft wheel:  X.teeth = dark outer band,  X.bulk = hub/web"),
        ((C_LAY, None), "layshaft wheel, reverse idler RI (dashed: beside the layshaft, out of this plane)"),
        ((C_BRG, None), "bearing: shaft bearings BIF ... BO, wheel bearings LB ... RB"),
        ((C_PS, None), "planetary range unit"),
        ((C_OIL, None), "oil sump"),
    ]
    pos = [(1.0, y), (1.0, y - 3.6), (62.0, y), (62.0, y - 3.6), (88.0, y - 3.6)]
    for ((fc, band), label), (x, yy) in zip(items, pos):
        ax.add_patch(Rectangle((x, yy - 1.3), 2.2, 2.6, fc=fc, ec="#444444", lw=0.8, alpha=0.9, zorder=3))
        if band:
            ax.add_patch(Rectangle((x, yy + 0.7), 2.2, 0.6, fc=band, ec="none", zorder=4))
        text(ax, x + 3.0, yy, label, size=10, weight="normal", ha="left", box=False)


def check_axial_order() -> None:
    """The drawing's axial order must be the model's (GRS905.toml positions)."""
    with open(ROOT / "firmware_model" / "params" / "GRS905.toml", "rb") as fh:
        p = tomllib.load(fh)
    real = {w: p["wheel"][f"x_{w}"]["v"] for w in IDLE_WHEELS}
    real |= {b: p["bearing"][b]["x"]["v"] for b in ("BIF", "BIM", "BMR", "BO")}
    real |= {
        "BLF": p["shaft"]["LS"]["x_BLF"]["v"],
        "BLR": p["shaft"]["LS"]["x_BLR"]["v"],
        "PS": p["shaft"]["MS"]["x_PS"]["v"],
        "carrier": p["shaft"]["OS"]["x_carrier"]["v"],
        "OS@bulk": p["shaft"]["OS"]["x_bulk"]["v"],
        "EY": p["shaft"]["OS"]["x_EY"]["v"],
    }
    by_real = sorted(real, key=lambda k: (real[k], k))
    by_drawn = sorted(real, key=lambda k: (X[k], k))
    if by_real != by_drawn:
        raise SystemExit(f"axial order differs from GRS905.toml: drawn {by_drawn}, model {by_real}")


def main() -> Path:
    check_axial_order()
    fig, ax = plt.subplots(figsize=(14, 10), dpi=100)
    ax.set_xlim(-1, 111)
    ax.set_ylim(-42, 71)
    ax.axis("off")
    draw_housing(ax)
    draw_shafts(ax)
    for wid, wb, (pair, _) in zip(IDLE_WHEELS, WHEEL_BEARINGS, TEETH.items()):
        idle_wheel(ax, wid, pair, wb)
    for lw_, pair in zip(LAYSHAFT_WHEELS, TEETH):
        layshaft_wheel(ax, lw_, pair)
    reverse_idler(ax)
    planetary(ax)
    shaft_bearing(ax, "BIF", X["BIF"], Y_UP, 1.3, +1)
    shaft_bearing(ax, "BIM", X["BIM"], Y_UP, 1.1, +1)
    shaft_bearing(ax, "BMR", X["BMR"], Y_UP, 1.1, +1)
    shaft_bearing(ax, "BO", X["BO"], Y_UP, 1.5, +1)
    shaft_bearing(ax, "BLF", X["BLF"], Y_LS, 1.3, -1)
    shaft_bearing(ax, "BLR", X["BLR"], Y_LS, 1.3, -1)
    boundaries(ax)
    segment_strips(ax)
    legend(ax)
    ax.set_title(
        "GRS905 range-splitter gearbox: where each component code sits\n"
        "vertical section, engine (front) at the left — schematic, NOT to scale "
        "(axial order and tooth-count ratios as in the model)",
        fontsize=13,
        fontweight="bold",
    )
    expected = set(
        IDLE_WHEELS + LAYSHAFT_WHEELS + PLANETARY + SHAFT_BEARINGS + WHEEL_BEARINGS + HOUSINGS + (REVERSE_IDLER, "oil")
    ) | {s for segs in SHAFT_SEGMENTS.values() for s in segs}
    missing = expected - LABELLED
    if missing:
        raise SystemExit(f"not labelled in the figure: {sorted(missing)}")
    fig.subplots_adjust(left=0.005, right=0.995, top=0.93, bottom=0.005)
    OUT.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(OUT, dpi=100)
    plt.close(fig)
    return OUT


if __name__ == "__main__":
    import argparse

    argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter).parse_args()
    print(main().relative_to(ROOT))

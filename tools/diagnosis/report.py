"""Markdown report of a gap diagnosis with PNG plots next to it (`gearbox-vsensor diagnose --report OUT.md`).

Everything is rendered into memory / a staging directory first and moved into place only when complete, so a failure
never leaves a half-written report.
"""

from __future__ import annotations

import math
import os
import shutil
import tempfile
from pathlib import Path
from typing import NamedTuple

import numpy as np

from firmware_model.effects import CATALOG
from tools.diagnosis.options import OIL
from tools.diagnosis.regimes import PRIMARY, cell_inputs, gear_group, speed_bin, torque_bin
from tools.diagnosis.result import PlotData
from tools.outputs import cannot_write
from tools.plots import pyplot, save_figure

GROUPS = ("low range", "high range", "reverse", "neutral")
TORQUES = ("engine braking (torque < 0)", "torque 0-800 Nm", "torque 800-1500 Nm", "torque > 1500 Nm")


def _chan_label(cid):
    return "oil sensor (oil_temp_c)" if cid == OIL else f"{cid} (meas_T_{cid}_c)"


class Row(NamedTuple):
    """One (dataset, channel) of a role: the residual before and after the verdict, the model before and after
    (after: None for 'none' and 'unexplained')."""

    ds: object
    cid: str
    ch: object
    r0: np.ndarray
    r1: np.ndarray | None
    p0: np.ndarray
    p1: np.ndarray | None


def _series(pd: PlotData, role: str) -> list:
    """Per (dataset, channel) of the training or the test files: a Row."""
    dsets = pd.train if role == "train" else pd.test
    obs = pd.obs_tr if role == "train" else pd.obs_te
    p0 = pd.p0_tr if role == "train" else pd.p0_te
    after = pd.after_tr if role == "train" else pd.after_te
    out = []
    k = 0
    for ds in dsets:
        for cid, ch in ds.channels.items():
            out.append(
                Row(
                    ds,
                    cid,
                    ch,
                    obs[k] - p0[k],
                    None if after is None else obs[k] - after[k],
                    p0[k],
                    None if after is None else after[k],
                )
            )
            k += 1
    return out


def plot_residuals(pd: PlotData, path):
    plt = pyplot()
    rows = _series(pd, "train") + _series(pd, "test")
    files = []
    for row in rows:
        if row.ds.name not in [f.name for f in files]:
            files.append(row.ds)
    fig, axes = plt.subplots(len(files), 1, figsize=(11, 2.6 * len(files)), squeeze=False, sharex=False)
    for ax, ds in zip(axes[:, 0], files):
        for row in rows:
            if row.ds is not ds:
                continue
            ax.plot((row.ch.cell_t_s - ds.t_start_s) / 60.0, row.r0, lw=0.8, label=f"{row.cid} before")
            if row.r1 is not None:
                ax.plot((row.ch.cell_t_s - ds.t_start_s) / 60.0, row.r1, lw=0.8, ls="--", label=f"{row.cid} after")
        ax.axhline(0, color="k", lw=0.5)
        ax.set_title(f"{ds.name} ({ds.role})", fontsize=9)
        ax.set_ylabel("measured - model [degC]", fontsize=8)
        ax.legend(fontsize=7, ncol=4, loc="best")
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("time [min]")
    save_figure(fig, path, dpi=90)


SPEEDS = ("speed < 1000 rpm", "speed 1000-1400 rpm", "speed 1400-1800 rpm", "speed > 1800 rpm")


class CellBins(NamedTuple):
    """The regime bins of a channel's cells."""

    gear_group: np.ndarray
    torque: np.ndarray
    speed: np.ndarray


def _cell_bins(ds, ch) -> CellBins:
    gear, tq, rpm = cell_inputs(ds, ch)
    return CellBins(gear_group(gear), torque_bin(tq), speed_bin(rpm))


class RegimeGrid(NamedTuple):
    """Over (row label, torque bin): sum of r^2, sum of r, cells."""

    sq: np.ndarray
    sum: np.ndarray
    n: np.ndarray


def _regime_grid(rows: list, cid: str, labels_y: tuple, by_speed: bool) -> RegimeGrid:
    """The training residual of channel `cid` accumulated over gear group (or engine speed) x torque."""
    M = np.zeros((len(labels_y), len(TORQUES)))
    MEAN = np.zeros_like(M)
    N = np.zeros_like(M)
    for row in rows:
        if row.cid != cid:
            continue
        bins = _cell_bins(row.ds, row.ch)
        ylab, tb = (bins.speed if by_speed else bins.gear_group), bins.torque
        for i, g in enumerate(labels_y):
            for j, tq in enumerate(TORQUES):
                if g == "neutral":
                    if j > 0:
                        continue
                    m = ylab == g
                else:
                    m = (ylab == g) & (tb == tq)
                M[i, j] += float(np.sum(row.r0[m] ** 2))
                MEAN[i, j] += float(np.sum(row.r0[m]))
                N[i, j] += m.sum()
    return RegimeGrid(M, MEAN, N)


def _draw_regime_grid(fig, ax, g: RegimeGrid, labels_y: tuple, title: str | None) -> None:
    share = g.sq / max(g.sq.sum(), 1e-12)
    im = ax.imshow(share, cmap="Reds", vmin=0, vmax=max(share.max(), 1e-6), aspect="auto")
    for i in range(len(labels_y)):
        for j in range(len(TORQUES)):
            if g.n[i, j]:
                ax.text(
                    j,
                    i,
                    f"{100 * share[i, j]:.0f} %\n{g.sum[i, j] / g.n[i, j]:+.2f}",
                    ha="center",
                    va="center",
                    fontsize=7,
                )
    ax.set_xticks(range(len(TORQUES)), ["< 0", "0-800", "800-1500", "> 1500"], fontsize=8)
    ax.set_yticks(
        range(len(labels_y)),
        [x.replace("speed ", "").replace("neutral", "neutral\n(any torque)") for x in labels_y],
        fontsize=8,
    )
    ax.set_xlabel("engine torque [Nm]", fontsize=8)
    if title:
        ax.set_title(title, fontsize=9)
    fig.colorbar(im, ax=ax, fraction=0.046)


def plot_regime_map(pd: PlotData, path):
    """Per channel: the share of the squared residual (colour) and the mean residual (text) over gear range x
    torque (top) and engine speed x torque (bottom), training files."""
    plt = pyplot()
    rows = _series(pd, "train")
    chans = []
    for row in rows:
        if row.cid not in chans:
            chans.append(row.cid)
    fig, axes = plt.subplots(2, len(chans), figsize=(4.2 * len(chans) + 1, 6.8), squeeze=False)
    for col, cid in enumerate(chans):
        for r, (labels_y, by_speed) in enumerate(((GROUPS, False), (SPEEDS, True))):
            title = f"{cid}: share of squared residual\n(mean residual degC)" if r == 0 else None
            _draw_regime_grid(fig, axes[r, col], _regime_grid(rows, cid, labels_y, by_speed), labels_y, title)
    save_figure(fig, path, dpi=90)


def plot_ranking(res, path):
    plt = pyplot()
    c = res["candidates"]
    names = [x["effect"] for x in c][::-1]
    scores = [x["score"] for x in c][::-1]
    fig, ax = plt.subplots(figsize=(8.5, 0.32 * len(c) + 1.2))
    colors = [
        "tab:green"
        if x["effect"] == res["verdict"]["effect"]
        else ("tab:orange" if x["effect"] in res["verdict"].get("confusable_with", []) else "tab:gray")
        for x in c
    ][::-1]
    ax.barh(names, scores, color=colors)
    ax.set_xscale("symlog", linthresh=10)
    ax.axvline(res["criterion"]["evidence_min"], color="k", ls=":", lw=1)
    for i, x in enumerate(c[::-1]):
        ax.text(
            max(x["score"], 0) if x["score"] > 0 else 0,
            i,
            f"  {100 * (x['explained_share'] or 0):.0f} %",
            va="center",
            fontsize=7,
        )
    ax.set_xlabel("score = -dBIC (effective sample size); dotted: strong evidence; label: share explained")
    ax.set_title(f"candidate ranking (verdict: {res['verdict']['effect']})", fontsize=10)
    save_figure(fig, path, dpi=90)


def plot_test(pd: PlotData, res, path):
    plt = pyplot()
    rows = _series(pd, "test")
    fig, axes = plt.subplots(len(rows), 1, figsize=(11, 2.6 * len(rows)), squeeze=False)
    for ax, row in zip(axes[:, 0], rows):
        tm = (row.ch.cell_t_s - row.ds.t_start_s) / 60.0
        ax.plot(tm, row.ch.cell_y_c, color="k", lw=0.8, label="measured")
        ax.plot(tm, row.p0, lw=0.9, label="model before")
        if row.p1 is not None:
            ax.plot(tm, row.p1, lw=0.9, ls="--", label=f"model with {res['verdict']['effect']}")
        ax.set_title(f"{row.ds.name}: {_chan_label(row.cid)}", fontsize=9)
        ax.set_ylabel("degC", fontsize=8)
        ax.legend(fontsize=7)
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("time [min]")
    save_figure(fig, path, dpi=90)


def plot_heat(pd: PlotData, path) -> bool:
    """The oil's unexplained heat flow per file; False (nothing drawn) without an oil channel."""
    if not pd.heat_series:
        return False
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(11, 3.2))
    for hs in pd.heat_series:
        ds = hs.dataset
        ax.plot((hs.t_s - ds.t_start_s) / 60.0, hs.Q_w / 1000.0, lw=0.9, label=f"{ds.name} ({ds.role})")
    ax.axhline(0, color="k", lw=0.5)
    ax.set_xlabel("time [min]")
    ax.set_ylabel("unexplained heat into the oil [kW]")
    ax.set_title("heat flow implied by the oil residual: C_eff d(r)/dt + G_eff r (r smoothed over 120 s)", fontsize=9)
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    save_figure(fig, path, dpi=90)
    return True


def _fmt(x, nd=3):
    if x is None:
        return "-"
    if isinstance(x, float) and not math.isfinite(x):
        return "-"
    return f"{x:.{nd}f}"


# ----------------------------------------------------------------------------------------------------------------
# the Markdown, section by section


def _md_header(res: dict, title: str | None) -> list:
    L = [f"# {title or 'Gap diagnosis'}\n"]
    delegated = res["model"].get("delegated_to_plant")
    L.append(
        f"Model under diagnosis: **{res['model'].get('model')}**"
        + (f" (requested {res['model']['requested']}; {res['model']['note']})" if res["model"].get("note") else "")
        + (
            f" (effects the onboard model cannot represent were fitted with the reference plant: "
            f"{', '.join(delegated)})"
            if delegated
            else ""
        )
        + f", cooler `{res.get('cooler')}`. Training files: {', '.join(f'`{x}`' for x in res['train'])}; "
        f"test files: {', '.join(f'`{x}`' for x in res['test'])}.\n"
    )
    return L


def _md_starts(res: dict) -> list:
    """How each file starts (tools/diagnosis/start.py), when some file started running."""
    starts = res.get("starts") or {}
    if not any(st["start"] == "running" for st in starts.values()):
        return []
    L = [
        "Some files began while the gearbox was already running: they are scored after their first minutes, and "
        'their housings\' start is fitted (docs/diagnosis.md, "Files that start while the gearbox runs").\n',
        "| file | role | start | why |",
        "|---|---|---|---|",
    ]
    for name, st in starts.items():
        L.append(f"| `{name}` | {st['role']} | {st['start']} | {st['reason']} |")
    return L + [""]


def _md_not_excluded(v: dict) -> list:
    """A table of the effects the data cannot rule out beside the verdict (verdict.not_excluded)."""
    items = v.get("not_excluded") or []
    if not items:
        return []
    L = [
        "Beside the verdict the training files have no strong evidence against these effects over the range given "
        "(the verdict's effects refitted at each value); *indicated*: neutral is outside the range, the data point "
        "to the effect although the verdict does not claim it.\n",
        "| effect | parameter | not excluded over | fits best at | indicated | evidence for adding it |",
        "|---|---|---|---|---|---|",
    ]
    for n in items:
        L.append(
            f"| {n['effect']} | {n['parameter']} | {n['range'][0]:.4g} .. {n['range'][1]:.4g} | {n['best']:.4g} | "
            f"{'yes' if n['indicated'] else 'no'} | "
            f"{'-' if n['evidence'] is None else format(n['evidence'], '.0f')} |"
        )
    return L + [""]


def _md_verdict(res: dict) -> list:
    v = res["verdict"]
    L = ["## Verdict\n"]
    if v["effect"] in CATALOG:
        unit = CATALOG[v["effect"]].unit
        p = ", ".join(f"{k} = {val:g}" + (f" {unit}" if unit != "-" else "") for k, val in v["parameters"].items())
        L.append(f"**{v['effect']}** ({p}): {v['reason']}.")
        if v.get("confusable_with"):
            L.append(f" Confusable with: {', '.join(v['confusable_with'])}.")
    elif v.get("evidence") == "thin":
        text = v["thin_evidence"]["text"].removeprefix("thin evidence ")
        L.append(f"**{v['effect']}, thin evidence** {text}.\n\nReason: {v['reason']}.")
    else:
        L.append(f"**{v['effect']}**: {v['reason']}.")
    L.append(
        f"\n\nOn the test files the pooled RMS residual goes from **{_fmt(v['test_rms_before_c'])} degC** to "
        f"**{_fmt(v['test_rms_after_c'])} degC** (shrink {100 * (v['shrink'] or 0):.0f} %), the largest "
        f"residual from {_fmt(v['test_max_before_c'])} to {_fmt(v['test_max_after_c'])} degC.\n"
    )
    L += _md_not_excluded(v)
    for s in res.get("measurement_suggestions", []):
        L.append(f"- {s['text']}.")
    if res.get("measurement_suggestions"):
        L.append("")
    if res.get("warnings"):
        L.append("Warnings: " + "; ".join(res["warnings"]) + "\n")
    return L


def _md_channels(res: dict) -> list:
    L = ["## Channels\n"]
    L.append(
        "| channel | noise per sample | sensor lag (nuisance) | systematic (train) | 'none' threshold "
        "| train RMS / max | test RMS / max | test RMS after |\n|---|---|---|---|---|---|---|---|"
    )
    for cid, c in res["channels"].items():
        L.append(
            f"| {_chan_label(cid)} | {_fmt(c['noise_c'])} | {_fmt(c['sensor_lag_s'], 1)} s | "
            f"{_fmt(c['systematic_train_c'])} | {_fmt(c['none_threshold_c'])} | {_fmt(c['train_rms_c'])} / "
            f"{_fmt(c['train_max_c'])} | {_fmt(c['test_rms_c'])} / {_fmt(c['test_max_c'])} | "
            f"{_fmt(c['test_rms_after_c'])} |"
        )
    L.append(
        "\nAll temperatures in degC; residual = measured - model on the "
        f"{res['criterion']['grid_dt_s']:g}-s analysis grid.\n"
    )
    return L


def _md_where(res: dict, images: dict) -> list:
    L = ["## Where the model misses\n"]
    L.append(f"![residuals over time]({images['residuals']})\n")
    L.append(f"![regime map]({images['regimes']})\n")
    L.append("Regimes ranked by their share of the squared residual (training files, range x torque):\n")
    L.append("| channel | regime | share | time share | RMS | mean |\n|---|---|---|---|---|---|")
    for w in res["where"][:12]:
        L.append(
            f"| {w['channel']} | {w['regime']} | {100 * w['share']:.0f} % | {100 * w['time_share']:.0f} % | "
            f"{_fmt(w['rms_c'])} | {_fmt(w['mean_c'], 3)} |"
        )
    L.append("\nOther partitions (share of the squared residual vs share of the time):\n")
    for cid, parts in res["where_by"].items():
        for part, lst in parts.items():
            if part in (PRIMARY, "gear", "speed x torque"):
                continue
            items = ", ".join(f"{x['regime']} {100 * x['share']:.0f} % / {100 * x['time_share']:.0f} %" for x in lst)
            L.append(f"- {cid}, {part}: {items}")
    if res["episodes"]:
        L.append("\nEpisodes (120-s windows) with the largest share:\n")
        L.append("| channel | file | from [s] | to [s] | share | mean residual |\n|---|---|---|---|---|---|")
        for e in res["episodes"][:6]:
            L.append(
                f"| {e['channel']} | {e['file']} | {e['t_start_s']:.0f} | {e['t_end_s']:.0f} | "
                f"{100 * e['share']:.0f} % | {_fmt(e['mean_c'])} |"
            )
    return L


def _md_heat(res: dict, images: dict) -> list:
    h = res["unexplained_heat"]
    if not images.get("heat"):
        return []
    L = ["\n### Unexplained heat flow into the oil\n"]
    L.append(f"![unexplained heat]({images['heat']})\n")
    L.append(
        f"C_eff = {h['C_eff_j_per_k'] / 1000:.1f} kJ/K (oil and housings), G_eff = "
        f"{_fmt(h['G_eff_w_per_k'], 0)} W/K (heat to the outside per kelvin of oil, from a re-simulation "
        f"with a 2 K warmer start). {h['sign']}.\n"
    )
    L.append("| file | mean [W] | 5 % [W] | 95 % [W] |\n|---|---|---|---|")
    for f in h["files"]:
        L.append(
            f"| {f['file']} ({f['role']}) | {_fmt(f['mean_w'], 0)} | {_fmt(f['p5_w'], 0)} | {_fmt(f['p95_w'], 0)} |"
        )
    return L


def _md_which(res: dict, images: dict) -> list:
    L = ["\n## Which effect\n"]
    L.append(f"![candidate ranking]({images['ranking']})\n")
    cr = res["criterion"]
    L.append(
        f"Score = -dBIC with the effective sample size n_eff = {cr['n_eff']:.0f} of n = {cr['n']} grid cells "
        f"(lag-1 autocorrelation of the best candidate's residual: "
        + ", ".join(f"{k} {v_:.2f}" for k, v_ in cr["rho_lag1"].items())
        + f"); >= {cr['evidence_min']:g} is strong evidence.\n"
    )
    L.append(
        "| effect | fitted | score | share explained | train RMS after | test RMS after | confusable with | "
        "identifiable |\n|---|---|---|---|---|---|---|---|"
    )
    for c in res["candidates"]:
        ((pn, pv),) = c["parameters"].items()
        ident = res["identifiability"][c["effect"]]
        idt = "yes" if ident["identifiable"] else (ident["note"] or "no")
        unit = f" {c['unit']}" if c["unit"] != "-" else ""
        L.append(
            f"| {c['effect']} | {pn} = {pv:.4g}{unit}{' (bound)' if c['at_bound'] else ''} | "
            f"{c['score']:.1f} | {100 * (c['explained_share'] or 0):.0f} % | {_fmt(c['train_rms_after_c'])} | "
            f"{_fmt(c['test_rms_after_c'])} | {', '.join(c['confusable_with']) or '-'} | {idt} |"
        )
    return L


def _md_test(res: dict, images: dict) -> list:
    L = ["\n## Before and after on the test files\n"]
    L.append(f"![test before/after]({images['test']})\n")
    L.append(
        "| channel | partition | regime | RMS before | RMS after | max before | max after |\n"
        "|---|---|---|---|---|---|---|"
    )
    for r in res["test_regimes"]:
        L.append(
            f"| {r['channel']} | {r['partition']} | {r['regime']} | {_fmt(r['rms_before_c'])} | "
            f"{_fmt(r['rms_after_c'])} | {_fmt(r['max_before_c'])} | {_fmt(r['max_after_c'])} |"
        )
    L.append(
        f"\n---\nMethod: docs/diagnosis.md. {res['timing']['simulations']} re-simulations in "
        f"{res['timing']['total_s']:.0f} s.\n"
    )
    return L


def render_markdown(res: dict, images: dict, title: str | None = None) -> str:
    """The report's Markdown from the diagnosis JSON; `images`: plot name -> file name next to it."""
    return "\n".join(
        _md_header(res, title)
        + _md_starts(res)
        + _md_verdict(res)
        + _md_channels(res)
        + _md_where(res, images)
        + _md_heat(res, images)
        + _md_which(res, images)
        + _md_test(res, images)
    )


def write_report(res: dict, pd: PlotData, out, title: str | None = None) -> Path:
    """Render the Markdown report and its PNGs (staged, then moved into place). Returns the Markdown path.
    `pd`: the diagnosis's plot data (``diagnose(..., keep=True)[1].plot_data``)."""
    out = Path(out)
    if out.suffix.lower() != ".md":
        out = out.with_suffix(out.suffix + ".md") if out.suffix else out.with_suffix(".md")
    parent = out.parent
    stem = out.stem
    names = {
        "residuals": f"{stem}_residuals.png",
        "regimes": f"{stem}_regimes.png",
        "ranking": f"{stem}_ranking.png",
        "test": f"{stem}_test.png",
        "heat": f"{stem}_heat.png",
    }
    try:
        parent.mkdir(parents=True, exist_ok=True)
        stage = Path(tempfile.mkdtemp(prefix=".diag-report-", dir=parent))
    except OSError as exc:  # named after the report, not after the staging folder it could not make
        raise cannot_write("--report", out, exc) from None
    try:
        plot_residuals(pd, stage / names["residuals"])
        plot_regime_map(pd, stage / names["regimes"])
        plot_ranking(res, stage / names["ranking"])
        plot_test(pd, res, stage / names["test"])
        if not plot_heat(pd, stage / names["heat"]):
            names.pop("heat")
        (stage / out.name).write_text(render_markdown(res, names, title))
        for n in list(names.values()) + [out.name]:
            os.replace(stage / n, parent / n)
    except OSError as exc:  # a full disk while staging: the report's name, not the staging folder's
        raise cannot_write("--report", out, exc) from None
    finally:
        shutil.rmtree(stage, ignore_errors=True)
    return out

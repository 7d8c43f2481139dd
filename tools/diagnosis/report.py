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

import numpy as np

from firmware_model.effects import CATALOG

from tools.diagnosis.core import OIL, PRIMARY, _gear_group, _speed_bin, _torque_bin

GROUPS = ("low range", "high range", "reverse", "neutral")
TORQUES = ("engine braking (torque < 0)", "torque 0-800 Nm", "torque 800-1500 Nm", "torque > 1500 Nm")


def _mpl():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _chan_label(cid):
    return "oil sensor (oil_temp_c)" if cid == OIL else f"{cid} (meas_T_{cid}_c)"


def _series(d, role):
    """Per (dataset, channel): (ds, cid, ch, residual before, residual after or None)."""
    pd = d._plotdata
    dsets = pd["train"] if role == "train" else pd["test"]
    obs = pd["obs_tr"] if role == "train" else pd["obs_te"]
    p0 = pd["p0_tr"] if role == "train" else pd["p0_te"]
    top = pd["cands"][0] if pd["cands"] else None
    after = None
    if pd["verdict"] in CATALOG and top is not None:
        after = top["fit"].preds_train if role == "train" else top["p_te"]
    out = []
    k = 0
    for ds in dsets:
        for cid, ch in ds.channels.items():
            out.append((ds, cid, ch, obs[k] - p0[k], None if after is None else obs[k] - after[k], p0[k],
                        None if after is None else after[k]))
            k += 1
    return out


def plot_residuals(d, path):
    plt = _mpl()
    rows = _series(d, "train") + _series(d, "test")
    files = []
    for ds, *_ in rows:
        if ds.name not in [f.name for f in files]:
            files.append(ds)
    fig, axes = plt.subplots(len(files), 1, figsize=(11, 2.6 * len(files)), squeeze=False, sharex=False)
    for ax, ds in zip(axes[:, 0], files):
        for d_, cid, ch, r0, r1, *_ in rows:
            if d_ is not ds:
                continue
            ax.plot((ch.cell_t - ds.t_start) / 60.0, r0, lw=0.8, label=f"{cid} before")
            if r1 is not None:
                ax.plot((ch.cell_t - ds.t_start) / 60.0, r1, lw=0.8, ls="--", label=f"{cid} after")
        ax.axhline(0, color="k", lw=0.5)
        ax.set_title(f"{ds.name} ({ds.role})", fontsize=9)
        ax.set_ylabel("measured - model [degC]", fontsize=8)
        ax.legend(fontsize=7, ncol=4, loc="best")
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("time [min]")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


SPEEDS = ("speed < 1000 rpm", "speed 1000-1400 rpm", "speed 1400-1800 rpm", "speed > 1800 rpm")


def _cell_inputs(ds, ch):
    tin = ds.inputs["time_s"]
    idx = np.clip(np.searchsorted(tin, ch.cell_t, side="right") - 1, 0, tin.size - 1)
    gg = _gear_group(ds.inputs["gear"][idx].astype(int))
    tb = _torque_bin(np.interp(ch.cell_t, tin, ds.inputs["engine_torque_nm"]))
    sb = _speed_bin(np.interp(ch.cell_t, tin, ds.inputs["engine_speed_rpm"]))
    return gg, tb, sb


def plot_regime_map(d, path):
    """Per channel: the share of the squared residual (colour) and the mean residual (text) over gear range x
    torque (top) and engine speed x torque (bottom), training files."""
    plt = _mpl()
    rows = _series(d, "train")
    chans = []
    for _, cid, *_ in rows:
        if cid not in chans:
            chans.append(cid)
    fig, axes = plt.subplots(2, len(chans), figsize=(4.2 * len(chans) + 1, 6.8), squeeze=False)
    for col, cid in enumerate(chans):
        for row, (labels_y, key) in enumerate(((GROUPS, 0), (SPEEDS, 2))):
            ax = axes[row, col]
            M = np.zeros((len(labels_y), len(TORQUES)))
            MEAN = np.zeros_like(M)
            N = np.zeros_like(M)
            for ds, c, ch, r0, *_ in rows:
                if c != cid:
                    continue
                lab = _cell_inputs(ds, ch)
                ylab, tb = lab[key], lab[1]
                for i, g in enumerate(labels_y):
                    for j, tq in enumerate(TORQUES):
                        if g == "neutral":
                            if j > 0:
                                continue
                            m = ylab == g
                        else:
                            m = (ylab == g) & (tb == tq)
                        M[i, j] += float(np.sum(r0[m] ** 2))
                        MEAN[i, j] += float(np.sum(r0[m]))
                        N[i, j] += m.sum()
            share = M / max(M.sum(), 1e-12)
            im = ax.imshow(share, cmap="Reds", vmin=0, vmax=max(share.max(), 1e-6), aspect="auto")
            for i in range(len(labels_y)):
                for j in range(len(TORQUES)):
                    if N[i, j]:
                        ax.text(j, i, f"{100 * share[i, j]:.0f} %\n{MEAN[i, j] / N[i, j]:+.2f}", ha="center",
                                va="center", fontsize=7)
            ax.set_xticks(range(len(TORQUES)), ["< 0", "0-800", "800-1500", "> 1500"], fontsize=8)
            ax.set_yticks(range(len(labels_y)), [x.replace("speed ", "").replace("neutral", "neutral\n(any torque)")
                                                 for x in labels_y], fontsize=8)
            ax.set_xlabel("engine torque [Nm]", fontsize=8)
            if row == 0:
                ax.set_title(f"{cid}: share of squared residual\n(mean residual degC)", fontsize=9)
            fig.colorbar(im, ax=ax, fraction=0.046)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def plot_ranking(res, path):
    plt = _mpl()
    c = res["candidates"]
    names = [x["effect"] for x in c][::-1]
    scores = [x["score"] for x in c][::-1]
    fig, ax = plt.subplots(figsize=(8.5, 0.32 * len(c) + 1.2))
    colors = ["tab:green" if x["effect"] == res["verdict"]["effect"] else
              ("tab:orange" if x["effect"] in res["verdict"].get("confusable_with", []) else "tab:gray")
              for x in c][::-1]
    ax.barh(names, scores, color=colors)
    ax.set_xscale("symlog", linthresh=10)
    ax.axvline(res["criterion"]["evidence_min"], color="k", ls=":", lw=1)
    for i, x in enumerate(c[::-1]):
        ax.text(max(x["score"], 0) if x["score"] > 0 else 0, i, f"  {100 * (x['explained_share'] or 0):.0f} %",
                va="center", fontsize=7)
    ax.set_xlabel("score = -dBIC (effective sample size); dotted: strong evidence; label: share explained")
    ax.set_title(f"candidate ranking (verdict: {res['verdict']['effect']})", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def plot_test(d, res, path):
    plt = _mpl()
    rows = _series(d, "test")
    fig, axes = plt.subplots(len(rows), 1, figsize=(11, 2.6 * len(rows)), squeeze=False)
    for ax, (ds, cid, ch, r0, r1, p0, p1) in zip(axes[:, 0], rows):
        tm = (ch.cell_t - ds.t_start) / 60.0
        ax.plot(tm, ch.cell_y, color="k", lw=0.8, label="measured")
        ax.plot(tm, p0, lw=0.9, label="model before")
        if p1 is not None:
            ax.plot(tm, p1, lw=0.9, ls="--", label=f"model with {res['verdict']['effect']}")
        ax.set_title(f"{ds.name}: {_chan_label(cid)}", fontsize=9)
        ax.set_ylabel("degC", fontsize=8)
        ax.legend(fontsize=7)
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("time [min]")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def plot_heat(d, path):
    plt = _mpl()
    series = getattr(d, "_heat_series", [])
    if not series:
        return False
    fig, ax = plt.subplots(figsize=(11, 3.2))
    for ds, tg, Q, _ in series:
        ax.plot((tg - ds.t_start) / 60.0, Q / 1000.0, lw=0.9, label=f"{ds.name} ({ds.role})")
    ax.axhline(0, color="k", lw=0.5)
    ax.set_xlabel("time [min]")
    ax.set_ylabel("unexplained heat into the oil [kW]")
    ax.set_title("heat flow implied by the oil residual: C_eff d(r)/dt + G_eff r (r smoothed over 120 s)", fontsize=9)
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return True


def _fmt(x, nd=3):
    if x is None:
        return "-"
    if isinstance(x, float) and not math.isfinite(x):
        return "-"
    return f"{x:.{nd}f}"


def render_markdown(res: dict, images: dict, title: str | None = None) -> str:
    v = res["verdict"]
    L = []
    L.append(f"# {title or 'Gap diagnosis'}\n")
    delegated = res["model"].get("delegated_to_plant")
    L.append(f"Model under diagnosis: **{res['model'].get('model')}**" +
             (f" (requested {res['model']['requested']}; {res['model']['note']})" if res["model"].get("note") else "") +
             (f" (effects the onboard model cannot represent were fitted with the reference plant: "
              f"{', '.join(delegated)})" if delegated else "") +
             f", cooler `{res.get('cooler')}`. Training files: {', '.join(f'`{x}`' for x in res['train'])}; "
             f"test files: {', '.join(f'`{x}`' for x in res['test'])}.\n")
    L.append("## Verdict\n")
    if v["effect"] in CATALOG:
        unit = CATALOG[v["effect"]].unit
        p = ", ".join(f"{k} = {val:g}" + (f" {unit}" if unit != "-" else "") for k, val in v["parameters"].items())
        L.append(f"**{v['effect']}** ({p}): {v['reason']}.")
        if v.get("confusable_with"):
            L.append(f" Confusable with: {', '.join(v['confusable_with'])}.")
    else:
        L.append(f"**{v['effect']}**: {v['reason']}.")
    L.append(f"\n\nOn the test files the pooled RMS residual goes from **{_fmt(v['test_rms_before_c'])} degC** to "
             f"**{_fmt(v['test_rms_after_c'])} degC** (shrink {100 * (v['shrink'] or 0):.0f} %), the largest "
             f"residual from {_fmt(v['test_max_before_c'])} to {_fmt(v['test_max_after_c'])} degC.\n")
    for s in res.get("measurement_suggestions", []):
        L.append(f"- {s['text']}.")
    if res.get("measurement_suggestions"):
        L.append("")
    if res.get("warnings"):
        L.append("Warnings: " + "; ".join(res["warnings"]) + "\n")
    L.append("## Channels\n")
    L.append("| channel | noise per sample | sensor lag (nuisance) | systematic (train) | 'none' threshold | train RMS / max "
             "| test RMS / max | test RMS after |\n|---|---|---|---|---|---|---|---|")
    for cid, c in res["channels"].items():
        L.append(f"| {_chan_label(cid)} | {_fmt(c['noise_c'])} | {_fmt(c['sensor_lag_s'], 1)} s | "
                 f"{_fmt(c['systematic_train_c'])} | {_fmt(c['none_threshold_c'])} | {_fmt(c['train_rms_c'])} / "
                 f"{_fmt(c['train_max_c'])} | {_fmt(c['test_rms_c'])} / {_fmt(c['test_max_c'])} | "
                 f"{_fmt(c['test_rms_after_c'])} |")
    L.append("\nAll temperatures in degC; residual = measured - model on the "
             f"{res['criterion']['grid_dt_s']:g}-s analysis grid.\n")
    L.append("## Where the model misses\n")
    L.append(f"![residuals over time]({images['residuals']})\n")
    L.append(f"![regime map]({images['regimes']})\n")
    L.append("Regimes ranked by their share of the squared residual (training files, range x torque):\n")
    L.append("| channel | regime | share | time share | RMS | mean |\n|---|---|---|---|---|---|")
    for w in res["where"][:12]:
        L.append(f"| {w['channel']} | {w['regime']} | {100 * w['share']:.0f} % | {100 * w['time_share']:.0f} % | "
                 f"{_fmt(w['rms_c'])} | {_fmt(w['mean_c'], 3)} |")
    L.append("\nOther partitions (share of the squared residual vs share of the time):\n")
    for cid, parts in res["where_by"].items():
        for part, lst in parts.items():
            if part in (PRIMARY, "gear", "speed x torque"):
                continue
            items = ", ".join(f"{x['regime']} {100 * x['share']:.0f} % / {100 * x['time_share']:.0f} %"
                              for x in lst)
            L.append(f"- {cid}, {part}: {items}")
    if res["episodes"]:
        L.append("\nEpisodes (120-s windows) with the largest share:\n")
        L.append("| channel | file | from [s] | to [s] | share | mean residual |\n|---|---|---|---|---|---|")
        for e in res["episodes"][:6]:
            L.append(f"| {e['channel']} | {e['file']} | {e['t_start_s']:.0f} | {e['t_end_s']:.0f} | "
                     f"{100 * e['share']:.0f} % | {_fmt(e['mean_c'])} |")
    h = res["unexplained_heat"]
    if images.get("heat"):
        L.append("\n### Unexplained heat flow into the oil\n")
        L.append(f"![unexplained heat]({images['heat']})\n")
        L.append(f"C_eff = {h['C_eff_j_per_k'] / 1000:.1f} kJ/K (oil and housings), G_eff = "
                 f"{_fmt(h['G_eff_w_per_k'], 0)} W/K (heat to the outside per kelvin of oil, from a re-simulation "
                 f"with a 2 K warmer start). {h['sign']}.\n")
        L.append("| file | mean [W] | 5 % [W] | 95 % [W] |\n|---|---|---|---|")
        for f in h["files"]:
            L.append(f"| {f['file']} ({f['role']}) | {_fmt(f['mean_w'], 0)} | {_fmt(f['p5_w'], 0)} | "
                     f"{_fmt(f['p95_w'], 0)} |")
    L.append("\n## Which effect\n")
    L.append(f"![candidate ranking]({images['ranking']})\n")
    cr = res["criterion"]
    L.append(f"Score = -dBIC with the effective sample size n_eff = {cr['n_eff']:.0f} of n = {cr['n']} grid cells "
             f"(lag-1 autocorrelation of the best candidate's residual: "
             + ", ".join(f"{k} {v_:.2f}" for k, v_ in cr["rho_lag1"].items())
             + f"); >= {cr['evidence_min']:g} is strong evidence.\n")
    L.append("| effect | fitted | score | share explained | train RMS after | test RMS after | confusable with | "
             "identifiable |\n|---|---|---|---|---|---|---|---|")
    for c in res["candidates"]:
        (pn, pv), = c["parameters"].items()
        ident = res["identifiability"][c["effect"]]
        idt = "yes" if ident["identifiable"] else (ident["note"] or "no")
        unit = f" {c['unit']}" if c["unit"] != "-" else ""
        L.append(f"| {c['effect']} | {pn} = {pv:.4g}{unit}{' (bound)' if c['at_bound'] else ''} | "
                 f"{c['score']:.1f} | {100 * (c['explained_share'] or 0):.0f} % | {_fmt(c['train_rms_after_c'])} | "
                 f"{_fmt(c['test_rms_after_c'])} | {', '.join(c['confusable_with']) or '-'} | {idt} |")
    L.append("\n## Before and after on the test files\n")
    L.append(f"![test before/after]({images['test']})\n")
    L.append("| channel | partition | regime | RMS before | RMS after | max before | max after |\n"
             "|---|---|---|---|---|---|---|")
    for r in res["test_regimes"]:
        L.append(f"| {r['channel']} | {r['partition']} | {r['regime']} | {_fmt(r['rms_before_c'])} | "
                 f"{_fmt(r['rms_after_c'])} | {_fmt(r['max_before_c'])} | {_fmt(r['max_after_c'])} |")
    L.append(f"\n---\nMethod: docs/diagnosis.md. {res['timing']['simulations']} re-simulations in "
             f"{res['timing']['total_s']:.0f} s.\n")
    return "\n".join(L)


def write_report(res: dict, d, out, title: str | None = None) -> Path:
    """Render the Markdown report and its PNGs (staged, then moved into place). Returns the Markdown path."""
    out = Path(out)
    if out.suffix.lower() != ".md":
        out = out.with_suffix(out.suffix + ".md") if out.suffix else out.with_suffix(".md")
    parent = out.parent
    parent.mkdir(parents=True, exist_ok=True)
    stem = out.stem
    names = {"residuals": f"{stem}_residuals.png", "regimes": f"{stem}_regimes.png",
             "ranking": f"{stem}_ranking.png", "test": f"{stem}_test.png", "heat": f"{stem}_heat.png"}
    stage = Path(tempfile.mkdtemp(prefix=".diag-report-", dir=parent))
    try:
        plot_residuals(d, stage / names["residuals"])
        plot_regime_map(d, stage / names["regimes"])
        plot_ranking(res, stage / names["ranking"])
        plot_test(d, res, stage / names["test"])
        if not plot_heat(d, stage / names["heat"]):
            names.pop("heat")
        (stage / out.name).write_text(render_markdown(res, names, title))
        for n in list(names.values()) + [out.name]:
            os.replace(stage / n, parent / n)
    finally:
        shutil.rmtree(stage, ignore_errors=True)
    return out

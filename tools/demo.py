"""The main job on an embedded default, end to end on python-can's virtual bus (`gearbox-vsensor demo`).

1. The reference plant runs the bundled synthetic uphill drive (the truth): :func:`simulate_truth`.
2. Its inputs become J1939 frames (EEC1, ETC2, TRF1, ET1, AMB, CCVS1, EC1 via TP.BAM) and its true component
   temperatures become rig thermocouple frames, as a real bus would carry them: :func:`drive_frames`.
3. Those frames are played onto a python-can `virtual` bus; the onboard sensor's live CAN service (the same code
   as `gearbox-vsensor run`) decodes them, steps the sensor every 100 ms of frame time and publishes GBX_* frames:
   :func:`run_on_virtual_bus`.
4. A monitor on the same bus decodes the sensor's frames with the gearbox's DBC (:func:`gearbox_dbc`: the shipped one
   for the GRS905, else the one `export-dbc` writes) and prints temperatures, warnings and time to limit
   (:func:`print_published`); at the end the estimates are compared with and plotted against the
   plant's truth (:func:`print_accuracy`, :func:`plot_demo`).

:func:`run_demo` does it all; every step prints through ``echo`` (stdout by default).
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple

import numpy as np

from firmware_model.components import (
    LEVEL_CRITICAL,
    LEVEL_NA,
    LEVEL_NORMAL,
    LEVEL_WARNING,
    MODE_HOLDING,
    MODE_NOT_INITIALISED,
    MODE_OIL_MODEL,
)
from firmware_model.errors import InputError
from tools.progress import progress
from tools.published import description, ids, label_of
from tools.published import limits as gearbox_limits
from tools.runtable import RunTable, write_run_table

#: how the demo prints a warning level and a degraded mode
LEVEL_LABEL = {LEVEL_NORMAL: "ok", LEVEL_WARNING: "WARNING", LEVEL_CRITICAL: "CRITICAL", LEVEL_NA: "n/a"}
DEGRADED_LABEL = {
    MODE_OIL_MODEL: "oil from the model",
    MODE_HOLDING: "inputs missing, holding",
    MODE_NOT_INITIALISED: "not initialised",
}
#: frames played onto the virtual bus between two short pauses that let the service's notifier keep up
SEND_BURST_FRAMES = 20000
#: how long the demo waits at most for the service to consume the frames [s]
DRAIN_TIMEOUT_S = 120.0
#: the demo's run tables (plant.csv, sensor.csv) keep one row per this many seconds: the 10 Hz tables of a 40-min
#: drive are 44 MB, the 1 s rows 4.5 MB (drive.log keeps every frame: `gearbox-vsensor replay` gives 10 Hz again)
CSV_ROW_S = 1.0
#: what the demo writes into its --out-dir
DEMO_FILES = ("plant.csv", "drive.log", "sensor.csv", "demo.png")


def every(table: RunTable, seconds: float = CSV_ROW_S) -> RunTable:
    """The rows of ``table`` at whole multiples of ``seconds`` of its time; without such rows (irregular time), the
    first row of each ``seconds`` interval."""
    x = np.asarray(table["time_s"], dtype=float) / seconds
    on_grid = np.abs(x - np.round(x)) < 1e-6
    if on_grid.sum() < 2:
        on_grid = np.r_[True, np.diff(np.floor(x + 1e-6)) > 0] if x.size else on_grid
    return table.select(on_grid)


@dataclass(frozen=True)
class DemoOptions:
    cycle: str = "uphill"  # named cycle or CSV run table
    minutes: float = 40.0  # how much of the cycle to run
    out_dir: Path = Path("demo_out")
    print_every_s: float = 300.0  # print the sensor's outputs every this many seconds of drive time
    gearbox: str = "GRS905"  # a shipped description's NAME or a parameter FILE (tools.cli.gearbox_option)


class Truth(NamedTuple):
    """The drive (inputs) and the reference plant's run over it."""

    cycle: RunTable
    table: RunTable
    wall_s: float


class BusRun(NamedTuple):
    """What happened on the virtual bus."""

    outputs: list  # the sensor's GBX_* frames the monitor received
    frames_in: int
    steps: int
    wall_s: float
    send_errors: int
    recorded: RunTable  # the service's recorded outputs (its run table)


def simulate_truth(params, cycle_spec: str, minutes: float) -> Truth:
    """The first `minutes` of a cycle through the reference plant at 10 Hz (read for the gearbox ``params``: its
    gears, its drive limits, a fixed-ratio drive's columns)."""
    from firmware_model.description import description_of
    from tools.cycles.named import get_cycle
    from tools.plant.reference import ReferencePlant

    cyc = get_cycle(cycle_spec, description=description_of(params))
    keep = cyc["time_s"] <= minutes * 60.0
    cyc = RunTable({c: np.asarray(cyc[c])[keep] for c in cyc.columns}, meta=dict(getattr(cyc, "meta", {}) or {}))
    res = ReferencePlant(params).run(cyc, out_dt_s=0.1, progress=None)
    return Truth(cyc, res.table, res.wall_s)


def gearbox_dbc(params):
    """The DBC of the gearbox ``params`` (its sensor's frames, as the CAN service and `simulate --can-log` lay them
    out): the shipped one for the GRS905's published components, else the one `export-dbc` writes for its own."""
    from can_dbc.dbc import for_components
    from firmware_model.description import description_of
    from firmware_model.onboard.reduce import published_ids

    return for_components(published_ids(description_of(params)))


def gbx_pgns(db) -> frozenset:
    """The PGNs (PDU2, data page 0) of the sensor's per-step output frames in the DBC ``db``: GBX_TEMP_1 ..
    GBX_STATUS (GBX_DM1 aside: it is sent on change and every second, not every step)."""
    return frozenset(db.message_pgn(m.name) for m in db.database.messages if m.name.startswith("GBX_")) - {
        db.message_pgn("GBX_DM1")
    }


def drive_frames(truth: Truth, log_path: Path, db=None):
    """J1939 frames of the drive (inputs) and rig thermocouple frames (truth), also written as a candump -L log;
    ``db``: the gearbox's DBC, whose RIG_TC messages carry its components (None: the shipped GRS905 one)."""
    from tools.can.logsynth import synth_frames, write_frames

    frames, _counts = synth_frames(truth.cycle, truth.table, rig=True, db=db)
    write_frames(frames, log_path)
    return frames


def _monitor(bus, outs: list, stop: threading.Event, pgns: frozenset) -> threading.Thread:
    """A thread that collects the sensor's GBX_* frames (``pgns``, :func:`gbx_pgns`) from `bus` until `stop` is
    set."""

    def loop():
        while not stop.is_set():
            m = bus.recv(timeout=0.1)
            if m is not None and (m.arbitration_id >> 8) & 0xFFFF in pgns:
                outs.append(m)

    th = threading.Thread(target=loop, daemon=True)
    th.start()
    return th


def _send_all(bus, frames, channel: str) -> int:
    """Play the frames onto the bus (a progress bar on a terminal); returns how many were sent."""
    n_sent = 0
    with progress(len(frames), "demo: frames onto the bus", unit="frame") as bar:
        for msg in frames.messages(channel=channel):
            bus.send(msg)
            n_sent += 1
            if n_sent % SEND_BURST_FRAMES == 0:
                bar.update(SEND_BURST_FRAMES)
                time.sleep(0.01)  # let the service's notifier keep up (bounded memory)
        bar.update(n_sent - bar.n)
    return n_sent


def _wait_until_consumed(service, timeout_s: float = DRAIN_TIMEOUT_S) -> None:
    """Wait until the service's step count stops moving (it has consumed everything), at most `timeout_s`."""
    deadline = time.perf_counter() + timeout_s
    last = -1
    while time.perf_counter() < deadline:
        time.sleep(0.5)
        steps = service.counters["steps"]
        if steps == last:
            break
        last = steps


def run_on_virtual_bus(params, frames, db=None) -> BusRun:
    """The sensor's CAN service on a python-can virtual bus fed with `frames`; a monitor collects its outputs (the
    per-step frames of ``db``, the gearbox's DBC; None: :func:`gearbox_dbc` of ``params``)."""
    import can

    from firmware_model.onboard.sensor import VirtualSensor
    from firmware_model.service import SensorService, ServiceOptions, serve

    channel = f"gbx-demo-{id(frames)}"
    sender, svc_bus, monitor = (
        can.Bus(interface="virtual", channel=channel, preserve_timestamps=True) for _ in range(3)
    )
    service = SensorService(VirtualSensor(params), ServiceOptions.from_config(None), record=True)
    stop, mon_stop = threading.Event(), threading.Event()
    result = {}
    th = threading.Thread(target=lambda: result.setdefault("r", serve(svc_bus, service, stop=stop)), daemon=True)
    th.start()
    outs: list = []
    mth = _monitor(monitor, outs, mon_stop, gbx_pgns(db or gearbox_dbc(params)))
    t0 = time.perf_counter()
    n_sent = _send_all(sender, frames, channel)
    _wait_until_consumed(service)
    stop.set()
    th.join(timeout=300)  # serve() drains its queue and sends the last outputs before it returns
    time.sleep(0.5)
    mon_stop.set()
    mth.join(timeout=5)
    for b in (sender, svc_bus, monitor):
        b.shutdown()
    r = result.get("r")
    return BusRun(
        outs,
        n_sent,
        service.counters["steps"],
        time.perf_counter() - t0,
        r.send_errors if r is not None else 0,
        RunTable(service.recorded()),
    )


def _ttl_words(ttl_s) -> str:
    """A time to limit as words: over the limit (0), never (inf), not available (NaN or absent), else seconds."""
    if ttl_s is None or (isinstance(ttl_s, float) and math.isnan(ttl_s)):
        return "not available"
    if ttl_s == math.inf:
        return "never at this load"
    if ttl_s <= 0.0:
        return "over the limit now"
    return f"{ttl_s:.0f} s to its limit"


def _status_line(t_s: float, d: dict, warn: dict, limits, published: tuple) -> str:
    """One printed line of what the sensor published at drive time `t_s` (`d`: decoded outputs of one step): the
    components closest to their own warning limits (the limits differ: bearings, sun wheel, gears), with the margin;
    ``published``: the gearbox's published component ids."""
    temps = d.get("temps_c", {})
    ttl = d.get("ttl_s", {})
    margins = sorted(
        (limits.of(c)[0] - v, c, v)
        for c, v in temps.items()
        if c in published and c in limits.components and v is not None and not math.isnan(v)
    )[:3]
    st = d.get("status", {})
    if st.get("degraded_mode") in (MODE_HOLDING, MODE_NOT_INITIALISED) and t_s < 1.0:
        return (
            f"  t={t_s:6.0f} s  starting: no engine speed, torque and gear received yet "
            f"(degraded: {DEGRADED_LABEL.get(st.get('degraded_mode'))})"
        )
    oil = temps.get("oil")  # None: not available on the bus (or no oil published)
    line = (
        f"  t={t_s:6.0f} s  oil {float('nan') if oil is None else oil:5.1f} C | closest to their limits: "
        + ", ".join(
            f"{c} {v:5.1f} C ({f'{m:.1f} K below' if m > 0 else f'{-m:.1f} K OVER'} {limits.of(c)[0]:.0f})"
            for m, c, v in margins
        )
    )
    if margins:
        c = margins[0][1]
        line += f" | {c}: {_ttl_words(ttl.get(c))}"
    line += f" | warnings: {', '.join(f'{c} {LEVEL_LABEL[v]}' for c, v in warn.items()) or 'none'}"
    if st.get("degraded_mode"):
        dm = st.get("degraded_mode")
        line += f" | degraded: {DEGRADED_LABEL.get(dm, dm)}"
    return line


def _level_events(t_s: float, d: dict, last: dict, limits, desc=None) -> list[str]:
    """Lines for every component whose warning level changed at this step, with why (limit, early warning,
    hysteresis); ``last`` (component -> level) is updated; ``desc``: the gearbox's description (the components'
    words)."""
    lines = []
    temps, ttl = d.get("temps_c", {}), d.get("ttl_s", {})
    for c, lv in d.get("levels", {}).items():
        before = last.get(c, LEVEL_NORMAL)
        if lv == before or lv == LEVEL_NA or before == LEVEL_NA:
            last[c] = lv
            continue
        warn_c, crit_c, hyst_k = limits.of(c)
        T = temps.get(c, float("nan"))
        if lv > before:
            why = (
                f"at or above its critical limit {crit_c:.0f} C"
                if lv == LEVEL_CRITICAL
                else f"at or above its warning limit {warn_c:.0f} C"
                if T >= warn_c
                else f"early warning: {_ttl_words(ttl.get(c))} of {warn_c:.0f} C at this load"
            )
            lines.append(f"  t={t_s:6.0f} s  {LEVEL_LABEL[lv]} raised: {label_of(c, desc)} {T:.1f} C, {why}")
        else:
            edge = (crit_c if before == LEVEL_CRITICAL else warn_c) - hyst_k
            lines.append(
                f"  t={t_s:6.0f} s  {LEVEL_LABEL[before]} cleared: {c} {T:.2f} C, below "
                f"{edge + hyst_k:.0f} - {hyst_k:g} K hysteresis = {edge:.0f} C"
            )
        last[c] = lv
    return lines


def print_published(
    outs: list, print_every_s: float, echo: Callable[[str], None], limits=None, gearbox=None, db=None
) -> dict:
    """Decode the sensor's frames per 100 ms step; print a line every `print_every_s` of drive time and at the end
    of the drive, and a line whenever a warning is raised or cleared (with why); returns component -> drive time of
    its first warning. ``gearbox``: the sensor's parameter set or description (None: the default gearbox);
    ``limits``: None for the gearbox's own; ``db``: the DBC the frames are laid out by (None: the shipped one)."""
    from can_dbc.adapter import decode_outputs

    limits = limits or gearbox_limits(gearbox)
    desc, published = description(gearbox), ids(gearbox)
    by_t: dict = {}
    for m in outs:
        by_t.setdefault(round(m.timestamp, 3), []).append(m)
    times = sorted(by_t)
    t_first = times[0] if times else 0.0
    next_print, first_warn, last_level = 0.0, {}, {}
    for k, ts in enumerate(times):
        d = decode_outputs(by_t[ts], database=db)
        warn = {c: v for c, v in d.get("levels", {}).items() if v in (LEVEL_WARNING, LEVEL_CRITICAL)}
        for c in warn:
            first_warn.setdefault(c, ts - t_first)
        for line in _level_events(ts - t_first, d, last_level, limits, desc):
            echo(line)
        if ts - t_first + 1e-9 >= next_print or k == len(times) - 1:
            next_print += print_every_s
            echo(_status_line(ts - t_first, d, warn, limits, published))
    if first_warn:
        echo(
            "  first warnings (drive time): "
            + ", ".join(f"{c} at {t:.0f} s" for c, t in sorted(first_warn.items(), key=lambda kv: kv[1]))
        )
    else:
        echo("  no warnings on this drive")
    return first_warn


class ComponentError(NamedTuple):
    max_abs_k: float
    rms_k: float
    component: str


def component_errors(est: RunTable, gearbox=None) -> list[ComponentError]:
    """Sensor minus truth per published component of ``gearbox`` (a parameter set or description; None: the default
    gearbox) (the rig thermocouples travelled on the bus as meas_T_ columns)."""
    errs = []
    for c in ids(gearbox):
        if est.has(f"T_{c}_c") and est.has(f"meas_T_{c}_c"):
            e = np.asarray(est[f"T_{c}_c"]) - np.asarray(est[f"meas_T_{c}_c"])
            e = e[np.isfinite(e)]
            if e.size:
                errs.append(ComponentError(float(np.max(np.abs(e))), float(np.sqrt(np.mean(e**2))), c))
    return errs


def print_accuracy(est: RunTable, echo: Callable[[str], None], gearbox=None) -> None:
    errs = component_errors(est, gearbox)
    if not errs:
        return
    worst = max(errs)
    worst_rms = max(errs, key=lambda e: e.rms_k)
    echo(
        f"  sensor vs plant truth over {len(errs)} components: worst max |error| {worst.max_abs_k:.2f} K "
        f"({worst.component}), worst RMS {worst_rms.rms_k:.2f} K ({worst_rms.component})"
    )
    echo(
        "  (the plant also sees engine-side boundary temperatures, seed Table 11, that no CAN signal carries: "
        "the bearings next to the engine and end yoke show that gap; set [boundary] in --config when known)"
    )


def featured(est: RunTable, limits, gearbox=None) -> tuple:
    """The two groups of published components the demo's figure draws: the planetary members the gearbox publishes
    and the sump (without a planetary set: the sump and the three closest to their warning limits), then the five
    others closest to their warning limits over the drive (tools.replay.plot.closest_to_limits)."""
    from tools.replay.plot import closest_to_limits

    desc, pub = description(gearbox), ids(gearbox)
    members = {m for ps in desc.planetary for m in (ps.sun, ps.planet, ps.ring)} if desc is not None else set()
    first = [c for c in pub if c in members]
    oil = ["oil"] if "oil" in pub else []
    rest = [c for c in pub if c not in first and c not in oil]
    if not first:
        first = closest_to_limits(est, limits, rest)[:3]
        rest = [c for c in rest if c not in first]
    return tuple(first + oil), tuple(closest_to_limits(est, limits, rest)[:5])


def plot_demo(est: RunTable, truth: RunTable, path, gearbox=None) -> Path:
    """The demo's figure: the inputs; sensor estimates (solid) with the plant's truth on top (black dashed) and each
    component's warning limit (dotted), in two panels (:func:`featured`); the error sensor - truth; the warning
    level of every component that raised one, as words. ``gearbox``: the parameter set or description (None: the
    default gearbox)."""
    from tools.plots import input_panel, level_axis, outside_legend, pyplot, save_figure, time_axis

    limits = gearbox_limits(gearbox)  # the gearbox's own, not the GRS905's file (whose components it has not)
    desc = description(gearbox)
    plt = pyplot()
    t, t_label = time_axis(est["time_s"])
    tt = time_axis(truth["time_s"])[0] if truth.n else t
    fig, axes = plt.subplots(5, 1, figsize=(16, 15), sharex=True, gridspec_kw={"height_ratios": [1.2, 3, 3, 1.5, 1.3]})
    input_panel(axes[0], tt, truth)
    axes[0].set_title(
        "Virtual sensor on the CAN bus (solid) vs the reference plant's truth (black dashed); dotted: warning limits"
    )
    groups = featured(est, limits, gearbox)
    for ax, comps in zip(axes[1:3], groups):
        for i, c in enumerate(comps):
            if est.has(f"T_{c}_c"):
                ax.plot(t, est[f"T_{c}_c"], color=f"C{i}", lw=1.8, label=f"{label_of(c, desc)}: sensor")
            if truth.has(f"T_{c}_c"):
                ax.plot(
                    tt, truth[f"T_{c}_c"], color="k", lw=0.9, ls="--", zorder=5, label="plant truth" if i == 0 else None
                )
            if c != "oil" and c in limits.components:
                ax.axhline(limits.of(c)[0], color=f"C{i}", lw=0.8, ls=":")
        ax.set_ylabel("degC")
        ax.grid(alpha=0.3)
        outside_legend(ax)
    ax = axes[3]
    for i, c in enumerate(tuple(c for c in groups[0] if c != "oil") + groups[1]):
        if est.has(f"T_{c}_c") and est.has(f"meas_T_{c}_c"):
            ax.plot(
                t, np.asarray(est[f"T_{c}_c"]) - np.asarray(est[f"meas_T_{c}_c"]), lw=0.9, color=f"C{i % 10}", label=c
            )
    ax.axhline(0.0, color="k", lw=0.5)
    ax.set_ylabel("sensor - truth [K]")
    ax.grid(alpha=0.3)
    outside_legend(ax, ncol=2)
    ax = axes[4]
    raised = [
        c for c in ids(gearbox) if est.has(f"W_{c}") and np.any(np.isin(est[f"W_{c}"], (LEVEL_WARNING, LEVEL_CRITICAL)))
    ]
    for i, c in enumerate(raised[:8]):
        lv = np.where(np.asarray(est[f"W_{c}"]) == LEVEL_NA, -1, est[f"W_{c}"])
        ax.step(t, lv, where="post", lw=1.4, color=f"C{i}", label=label_of(c, desc))
    if raised:
        outside_legend(ax)
    else:
        ax.text(0.5, 0.5, "no warning on this drive", transform=ax.transAxes, ha="center", va="center")
    level_axis(ax)
    ax.set_ylabel("warning level")
    ax.set_xlabel(t_label)
    ax.grid(alpha=0.3)
    return save_figure(fig, path, dpi=90)


def run_demo(opts: DemoOptions, echo: Callable[[str], None] | None = None) -> BusRun:
    """The four steps, printed through `echo`; writes plant.csv, drive.log, sensor.csv and demo.png to out_dir."""
    from can_dbc.dbc import shipped
    from firmware_model.parameters import load_parameters

    echo = echo or (lambda line: print(line, flush=True))
    if not 1.0 <= opts.minutes <= 600.0:
        raise InputError(f"--minutes {opts.minutes} must be in 1..600")
    from firmware_model.description import description_of
    from tools.cycles.named import get_cycle

    # the gearbox, its frames and the cycle read for it are refused before the output directory is made
    params = load_parameters(opts.gearbox)
    db = gearbox_dbc(params)  # the frames of this gearbox's sensor, as the service lays them out
    get_cycle(opts.cycle, description=description_of(params))
    out = Path(opts.out_dir)
    if out.exists() and not out.is_dir():
        raise InputError(f"--out-dir {out} is a file, not a directory")
    out.mkdir(parents=True, exist_ok=True)
    echo(f"[1/4] reference plant: {opts.minutes:.0f} min of the synthetic '{opts.cycle}' drive ...")
    truth = simulate_truth(params, opts.cycle, opts.minutes)
    write_run_table(every(truth.table), out / "plant.csv")
    echo(f"      done in {truth.wall_s:.1f} s; truth written to {out / 'plant.csv'}")
    echo("[2/4] J1939 frames of the drive (inputs) and rig thermocouple frames (truth) ...")
    frames = drive_frames(truth, out / "drive.log", db)
    echo(
        f"      {len(frames)} frames -> {out / 'drive.log'} (candump -L; replay it with canplayer or "
        f"`gearbox-vsensor replay`)"
    )
    echo("[3/4] sensor service on python-can's virtual bus (frame time drives the 10 Hz steps) ...")
    bus = run_on_virtual_bus(params, frames, db)
    echo(
        f"      {bus.frames_in} frames in, {len(bus.outputs)} GBX frames out on the bus "
        f"({len(gbx_pgns(db))} per step; DM1 aside), "
        f"{bus.steps} steps "
        f"in {bus.wall_s:.1f} s wall"
    )
    dbc_words = (
        "can_dbc/gearbox_vsensor.dbc"
        if db is shipped()
        else f"the {params.variant}'s DBC, as `gearbox-vsensor export-dbc --gearbox` writes it"
    )
    echo(
        f"[4/4] what the sensor published (decoded from the bus with {dbc_words}), every "
        f"{opts.print_every_s:.0f} s of drive time:"
    )
    print_published(bus.outputs, opts.print_every_s, echo, gearbox=params, db=db)
    write_run_table(every(bus.recorded), out / "sensor.csv")
    print_accuracy(bus.recorded, echo, params)
    plot_demo(bus.recorded, truth.table, out / "demo.png", params)
    echo(f"plots: {out / 'demo.png'}; sensor outputs: {out / 'sensor.csv'}")
    size_mb = sum(f.stat().st_size for f in out.glob("*") if f.name in DEMO_FILES) / 1e6
    echo(f"wrote {size_mb:.0f} MB to {out.resolve()}: {', '.join(DEMO_FILES)} (run tables with {CSV_ROW_S:g} s rows)")
    return bus

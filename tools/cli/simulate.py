"""`gearbox-vsensor simulate`: run the reference plant over a named drive cycle or a run table."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from firmware_model.components import meaning
from firmware_model.config import load_config
from firmware_model.effects import CATALOG, CHANNEL_EFFECTS, parse_effect
from firmware_model.errors import InputError
from firmware_model.physics.oil import check_temperature_c
from tools.cli.paths import check_paths, figure_path
from tools.outputs import naming, outputs


def add_subparser(sub):
    from tools.cycles.named import CYCLE_NAMES

    # the channel effects (a rig thermocouple's offset) act on a reading: the plant writes true temperatures
    effects = "; ".join(
        f"{e.id}:{e.param}=<{e.low:g}..{e.high:g}{'' if e.unit == '-' else ' ' + e.unit}>"
        for e in CATALOG.values()
        if e.id not in CHANNEL_EFFECTS
    )
    p = sub.add_parser(
        "simulate",
        help="run the reference plant (the thesis's full network) over a drive cycle",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Run the reference thermal plant (61 thermal masses, every loss and heat path of the seed) "
        "over a drive cycle and write a run table with every node temperature, every loss and every "
        "heat flow to the outside.\n\nNamed cycles are SYNTHETIC, modelled on the thesis's load cases: "
        + ", ".join(CYCLE_NAMES)
        + "; or 'steady:gear=4L,rpm=1300,nm=2000,s=3600,oil=100'; or a CSV "
        "run table (docs/interfaces.md section 3). Component codes (PS, BLR, LS@1L ...): "
        "docs/glossary.md.",
        epilog="examples:\n  gearbox-vsensor simulate --cycle uphill --out uphill.csv --plot uphill.png\n"
        "  gearbox-vsensor simulate --cycle steady:gear=4L,rpm=1300,nm=2000,s=3600 --cooler hold --out s.csv\n"
        "  gearbox-vsensor simulate --cycle mining --effect retarder_heat:fraction=0.05 --out m.csv\n\n"
        "effects (docs/interfaces.md section 6): " + effects,
    )
    p.add_argument(
        "--cycle", required=True, metavar="NAME_OR_CSV", help="named cycle, steady:... spec, or a CSV run table"
    )
    p.add_argument("--config", metavar="TOML", help="project configuration (gearbox variant, cooler, boundaries, CAN)")
    p.add_argument("--variant", choices=("GRS905", "GRSO905"), help="gearbox variant (overrides --config)")
    p.add_argument(
        "--effect",
        action="append",
        default=[],
        metavar="ID:PARAM=VALUE",
        help="switch an unmodelled effect on (repeatable), e.g. retarder_heat:fraction=0.05",
    )
    p.add_argument(
        "--cooler",
        choices=("none", "liquid", "air", "hold", "measured"),
        help="cooling: none, liquid, air, hold (sump held constant), measured (oil_temp_c column as the "
        "sump); default from the parameters (liquid)",
    )
    p.add_argument(
        "--hold-oil",
        type=float,
        metavar="DEGC",
        help="hold the sump at this temperature, -40..200 degC (implies --cooler hold; the other nodes "
        "start as --initial-temp says: a steady: spec's own start is 20 degC unless it has oil=)",
    )
    p.add_argument(
        "--initial-temp",
        type=float,
        metavar="DEGC",
        help="initial temperature of every node (default: the cycle's own, else the first oil reading, "
        "else the held sump with --cooler hold, else the parameters' [boundary] initial, 60 degC)",
    )
    p.add_argument("--rate", type=float, metavar="HZ", help="sample rate of named cycles (default 10)")
    p.add_argument("--noise", action="store_true", help="add measurement-like noise to named cycles")
    p.add_argument("--seed", type=int, help="random seed of the named cycles (default 0)")
    p.add_argument("--dt", type=float, default=0.5, metavar="S", help="plant time step (default 0.5 s, BDF2)")
    p.add_argument("--out-dt", type=float, default=1.0, metavar="S", help="output sample period (default 1 s)")
    p.add_argument("--out", required=True, metavar="RUN.csv", help="output run table")
    p.add_argument(
        "--plot",
        metavar="PNG",
        help="temperature plot: the inputs, then the temperatures by component group, names spelled out, "
        "warning limits dashed; the heat budget goes to <stem>_heat.png",
    )
    p.add_argument(
        "--can-log",
        metavar="RUN.log",
        help="also write the plant's inputs as J1939 frames and its true "
        "temperatures as rig thermocouple frames (candump -L)",
    )
    p.add_argument(
        "--start-time",
        metavar="ISO",
        help="with --can-log: the UTC time of the log's first frame, e.g. 2026-01-05T08:00:00Z or "
        "2026-01-05 (midnight; no zone: UTC); its frame times are then Unix time, as a logger's, "
        "and `fleet` takes each log's date from them (default: frame times from 0 s)",
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar or summary")
    p.add_argument(
        "--allow-untrusted",
        action="store_true",
        help="simulate a CSV cycle whose units look wrong (time_s in milliseconds, engine speed in rad/s) "
        "anyway; without it such a cycle is refused before anything runs",
    )
    p.set_defaults(func=run)
    return p


def refuse_unused_options(args) -> None:
    """InputError for an option that would do nothing: --rate/--noise/--seed on a CSV run table, --hold-oil with
    another --cooler than hold. Then the defaults of --rate and --seed."""
    from tools.cycles.named import CYCLE_NAMES

    named = args.cycle.strip().lower().split(":")[0] in CYCLE_NAMES
    given = [
        o for o, v in (("--rate", args.rate), ("--noise", args.noise or None), ("--seed", args.seed)) if v is not None
    ]
    if given and not named:
        raise InputError(
            f"{', '.join(given)} {'applies' if len(given) == 1 else 'apply'} only to named cycles; "
            f"{args.cycle} is a run table, simulated as it is"
        )
    if args.hold_oil is not None and args.cooler not in (None, "hold"):
        raise InputError(
            f"--hold-oil holds the sump, which --cooler {args.cooler} does not: use --cooler hold or leave --cooler out"
        )
    args.rate = 10.0 if args.rate is None else args.rate
    args.seed = 0 if args.seed is None else args.seed
    if args.start_time is not None and not args.can_log:
        raise InputError("--start-time sets the time stamps of the CAN log, which only --can-log writes")
    args.start_time = parse_start_time(args.start_time)


def parse_start_time(text: str | None) -> float:
    """Unix time [s] of an ISO 8601 date or date-time (no zone: UTC); 0 for None."""
    import datetime as dt

    if text is None:
        return 0.0
    try:
        t = dt.datetime.fromisoformat(text.strip().replace("Z", "+00:00").replace("z", "+00:00"))
    except ValueError:
        raise InputError(
            f"--start-time {text!r} is not an ISO 8601 date or time: give e.g. 2026-01-05T08:00:00Z or 2026-01-05"
        ) from None
    if t.tzinfo is None:
        t = t.replace(tzinfo=dt.timezone.utc)
    stamp = t.timestamp()
    if not 1e8 <= stamp < 4102444800:  # 1973 .. 2100: what a logger's clock gives (fleet takes >= 1e8 as a date)
        raise InputError(f"--start-time {text!r} lies outside 1973-2099, where a log's frame times are Unix time")
    return stamp


def run(args) -> int:
    from tools.cycles.named import get_cycle

    refuse_unused_options(args)
    from tools.plant.reference import ReferencePlant

    cfg = load_config(args.config)
    if args.variant:
        cfg.variant = args.variant
        cfg.params_path = None
    params = cfg.load_params()
    parsed = [parse_effect(e) for e in args.effect]
    effects = dict(parsed)
    if len(effects) < len(parsed):
        twice = sorted({e for e, _ in parsed if sum(x == e for x, _ in parsed) > 1})
        raise InputError(f"--effect {', '.join(twice)} is given twice; give each effect once")
    if args.rate <= 0 or args.rate > 1000:
        raise InputError(f"--rate {args.rate} must be in (0, 1000] Hz")
    if not 0.01 <= args.out_dt <= 3600:
        raise InputError(f"--out-dt {args.out_dt} must be within 0.01..3600 s")
    if args.seed < 0:
        raise InputError(f"--seed {args.seed} must be a non-negative integer")
    for opt, value_c in (("--initial-temp", args.initial_temp), ("--hold-oil", args.hold_oil)):
        if value_c is not None:
            check_temperature_c(opt, value_c)
    cycle_file = args.cycle if Path(args.cycle).is_file() else None
    check_paths(
        [("the --cycle", cycle_file), ("the --config", args.config)],
        {"--out": args.out, "--plot": args.plot, "--can-log": args.can_log},
        plots=("--plot",),
        tables=("--out",),
        can_logs=("--can-log",),
    )
    plot, heat = plot_paths(args.plot)
    # every output to a temporary file first: a failure (a full disk, a bad [can] value) leaves none of them
    with outputs(("--out", args.out), ("--can-log", args.can_log), ("--plot", plot), ("--plot", heat)) as tmp:
        table = get_cycle(args.cycle, rate_hz=args.rate, noise=args.noise, seed=args.seed)
        if cycle_file is not None and not args.allow_untrusted:
            _refuse_unit_mistakes(table, cycle_file, oil_used=(args.cooler or cfg.cooler) == "measured")
        plant = ReferencePlant(params, effects, cooler=args.cooler or cfg.cooler, dt_s=args.dt)
        try:
            res = plant.run(
                table,
                initial_temp_c=args.initial_temp,
                hold_oil_c=args.hold_oil,
                out_dt_s=args.out_dt,
                progress=None if not args.quiet else False,
            )
        except InputError as exc:  # the plant checks the rows: name the file they came from (cycles.md)
            if cycle_file is None or str(cycle_file) in str(exc):
                raise
            raise InputError(f"{cycle_file}: {exc}") from None
        _write_outputs(args, table, res, params, cfg, tmp)
    out = Path(args.out)
    if not args.quiet:
        eb = res.energy_balance()
        tb = res.table
        hot = sorted(
            ((float(tb[c].max()), c[2:-2]) for c in tb.columns if c.startswith("T_") and c.endswith("_c")), reverse=True
        )[:5]
        print(f"simulated {tb['time_s'][-1] - tb['time_s'][0]:.0f} s of '{args.cycle}' in {res.wall_s:.1f} s -> {out}")
        print("hottest:\n" + "\n".join(f"  {n:10s} {v:6.1f} degC  {meaning(n) or ''}" for v, n in hot))
        net_in = " (negative: the cooler and boundaries heated the gearbox on balance)" if eb["rejected_j"] < 0 else ""
        print(
            f"energy: generated {eb['generated_j'] / 1e6:.2f} MJ = stored {eb['stored_j'] / 1e6:.2f} MJ + rejected "
            f"{eb['rejected_j'] / 1e6:.2f} MJ{net_in} (closure {eb['closure_rel']:.1e})"
        )
        for w in res.warnings:
            print(f"note: {w}", file=sys.stderr)
    return 0


#: a CSV cycle whose rows lie further apart than this (median) over at least UNIT_CHECK_MIN_ROWS rows is taken for
#: time_s in milliseconds [s] (the sensor's hold time: rows further apart are too sparse for it anyway) ...
SPARSE_ROWS_S = 60.0
UNIT_CHECK_MIN_ROWS = 20
#: ... and so is one longer than LONG_CYCLE_S whose rows lie at least LONG_ROWS_S apart: a 20-100 Hz logger in
#: milliseconds (rows 10-50 "s" apart; a 10-minute file spans about 7 days)
LONG_CYCLE_S, LONG_ROWS_S = 86400.0, 10.0


def _refuse_unit_mistakes(table, name: str, oil_used: bool = False) -> None:
    """InputError for a CSV cycle whose units look wrong, before the plant runs, as replay refuses them: a 10-minute
    file with time_s in milliseconds would simulate 7 days and write a 600 MB table and a 4.3 GB CAN log, and
    rad/s speed would run as a stalled engine."""
    from firmware_model.service.degraded import unit_findings

    t = np.asarray(table["time_s"], dtype=float)
    if t.size >= UNIT_CHECK_MIN_ROWS:
        spacing_s = float(np.median(np.diff(t)))
        if spacing_s > SPARSE_ROWS_S or (t[-1] - t[0] > LONG_CYCLE_S and spacing_s >= LONG_ROWS_S):
            raise InputError(
                f"{name}: its rows lie a median {spacing_s:.0f} s apart ({t[-1] - t[0]:.0f} s in all): "
                f"if time_s is in milliseconds, give seconds; if the rows really lie that far apart, "
                f"pass --allow-untrusted"
            )
    from firmware_model.service.plausibility import record_findings

    speed = unit_findings(0, 0, [], table["engine_speed_rpm"], table["engine_torque_nm"])
    # the whole-record rules (oil only when the plant takes it as its sump: --cooler measured)
    cols = {c: table[c] for c in table.columns if c != "oil_temp_c" or oil_used}
    whole = record_findings(cols, float(np.median(np.diff(t)))) if t.size > 1 else []
    if speed or whole:
        raise InputError(f"{name}: {(speed + whole)[0].sentence} (pass --allow-untrusted to simulate it as it is)")


def plot_paths(plot):
    """The two figures of --plot: the temperatures (matplotlib appends .png to a name without a suffix) and the
    heat budget, <stem>_heat<suffix>; (None, None) without --plot."""
    if not plot:
        return None, None
    pp = Path(plot)
    return figure_path(plot), pp.with_name(pp.stem + "_heat" + (pp.suffix or ".png"))


def _write_outputs(args, table, res, params, cfg, tmp) -> None:
    """The run table, the CAN log and the figures, to the temporary files ``tmp`` (tools.outputs)."""
    from tools.runtable import write_run_table

    out_tmp, log_tmp, plot_tmp, heat_tmp = tmp
    with naming(out_tmp):
        write_run_table(res.table, out_tmp)
    if log_tmp:
        from tools.can.logsynth import write_can_log

        with naming(log_tmp):
            write_can_log(table, res.table, log_tmp, params, config=cfg, start_timestamp_s=args.start_time)
    if plot_tmp:
        from tools.plots import plot_heat_budget, plot_simulation

        title = f"{params.variant} reference plant, cycle {args.cycle}" + (
            f", effects {args.effect}" if args.effect else ""
        )
        with naming(plot_tmp):
            plot_simulation(res.table, plot_tmp, title)
        with naming(heat_tmp):
            plot_heat_budget(res.table, heat_tmp, title)

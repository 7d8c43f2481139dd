"""`gearbox-vsensor simulate`: run the reference plant over a named drive cycle or a run table."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from firmware_model.effects import CATALOG, CHANNEL_EFFECTS, parse_effect
from firmware_model.errors import InputError
from firmware_model.physics.oil import check_temperature_c
from tools.cli.gearbox_option import add_gearbox_option, resolve_gearbox
from tools.cli.paths import check_paths, figure_path
from tools.cli.settings import add_hidden, given, setting
from tools.outputs import naming, outputs


def _help_texts() -> tuple[str, str]:
    """The description (the named cycles) and the epilog (examples, the effects) of `simulate --help`."""
    from tools.cycles.named import CYCLE_NAMES

    # the channel effects (a rig thermocouple's offset) act on a reading: the plant writes true temperatures
    effects = "; ".join(
        f"{e.id}:{e.param}=<{e.low:g}..{e.high:g}{'' if e.unit == '-' else ' ' + e.unit}>"
        for e in CATALOG.values()
        if e.id not in CHANNEL_EFFECTS
    )
    description = (
        "Run the reference thermal plant (the GRS905's 61 thermal masses, or the --gearbox description's; every loss "
        "and heat path of the seed) "
        "over a drive cycle and write a run table with every node temperature, every loss and every "
        "heat flow to the outside.\n\nNamed cycles are SYNTHETIC, modelled on the thesis's load cases: "
        + ", ".join(CYCLE_NAMES)
        + "; or 'steady:gear=4L,rpm=1300,nm=2000,s=3600,oil=100' (oil=: the sump held at that temperature "
        "in place of the gearbox's cooler, as a rig's oil conditioning does; all_gears holds it at 100 degC; "
        "with a --config [cooler] kind other than hold, or a [simulate] hold_oil_c of another temperature, "
        "either is an error); a fixed-ratio gearbox (--gearbox HR225, MM82, R1) takes 'steady:rpm=N,nm=N,s=3600' "
        "(its input shaft held, in its description's ambient air or ambient=N degC, no gear=); or a CSV "
        "run table (docs/interfaces.md section 3). Component codes (PS, BLR, LS@1L ...): "
        "docs/glossary.md."
    )
    epilog = (
        "examples:\n  gearbox-vsensor simulate --cycle uphill --out uphill.csv --plot uphill.png\n"
        "  gearbox-vsensor simulate --cycle steady:gear=4L,rpm=1300,nm=2000,s=3600,oil=100 --config rig.toml "
        '--out s.csv   # rig.toml: [cooler] kind = "hold"\n'
        "  gearbox-vsensor simulate --cycle mining --effect retarder_heat:fraction=0.05 --out m.csv\n\n"
        "effects (docs/interfaces.md section 6): " + effects
    )
    return description, epilog


def add_subparser(sub):
    description, epilog = _help_texts()
    p = sub.add_parser(
        "simulate",
        help="run the reference plant (the thesis's full network) over a drive cycle",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description=description,
        epilog=epilog,
    )
    p.add_argument(
        "--cycle", required=True, metavar="NAME_OR_CSV", help="named cycle, steady:... spec, or a CSV run table"
    )
    p.add_argument(
        "--config",
        metavar="TOML",
        help="project configuration: gearbox variant, cooler ([cooler] kind: none, liquid, air, hold, measured), "
        "boundaries, [can], and [simulate]: rate_hz (10) and noise (false) of named cycles, dt_s (plant step, "
        "0.5 s), out_dt_s (output period, 1 s), initial_temp_c (every node's start), hold_oil_c (the held sump) "
        "(docs/interfaces.md section 8)",
    )
    add_gearbox_option(p)
    p.add_argument(
        "--effect",
        action="append",
        default=[],
        metavar="ID:PARAM=VALUE",
        help="switch an unmodelled effect on (repeatable), e.g. retarder_heat:fraction=0.05",
    )
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
    p.add_argument(
        "--seed",
        type=int,
        metavar="N",
        help="random seed of a named cycle (default 0; one per run, e.g. the logs of a synthetic fleet); an error "
        "with a CSV run table",
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar or summary")
    p.add_argument(
        "--allow-untrusted",
        action="store_true",
        help="simulate a CSV cycle whose units look wrong (time_s in milliseconds, engine speed in rad/s, a "
        "torque negated or in percent or kN m; a fixed-ratio drive's rows over an hour apart, its torque in percent "
        "or kN m, not its speed in rad/s or time_s in minutes, which nothing in a cycle tells apart from a slower "
        "or faster run) anyway; without it such a cycle is refused before anything runs",
    )
    _add_hidden_options(p)
    p.set_defaults(func=run)
    return p


#: the [simulate] settings of the configuration (firmware_model.config.SETTINGS)
SIMULATE_KEYS = (
    "simulate.rate_hz",
    "simulate.noise",
    "simulate.dt_s",
    "simulate.out_dt_s",
    "simulate.initial_temp_c",
    "simulate.hold_oil_c",
)
#: those that only apply to named cycles
CYCLE_KEYS = ("simulate.rate_hz", "simulate.noise")


def _add_hidden_options(p) -> None:
    """The options that moved to the configuration, still accepted (hidden) and overriding it: --cooler ([cooler]
    kind) and the [simulate] settings."""
    p.add_argument("--cooler", choices=("none", "liquid", "air", "hold", "measured"), help=argparse.SUPPRESS)
    for key in SIMULATE_KEYS:
        add_hidden(p, key)


def resolve_settings(args, cfg) -> SimpleNamespace:
    """The [simulate] settings (hidden option, else the configuration, else the default) and the cooler; InputError
    for a named-cycle option on a CSV run table, a held sump with another cooler, --start-time without --can-log."""
    from tools.cycles.named import CYCLE_NAMES

    s = SimpleNamespace(**{k.split(".")[1]: setting(args, cfg, k) for k in SIMULATE_KEYS})
    s.cooler = args.cooler or cfg.cooler
    named = args.cycle.strip().lower().split(":")[0] in CYCLE_NAMES
    on_table = given(args, CYCLE_KEYS) + (["--seed"] if args.seed is not None else [])
    in_file = [f"[{k.replace('.', '] ')}" for k in CYCLE_KEYS if k in cfg.settings]
    if in_file and not named:  # a project's configuration serves named cycles and tables alike: said, not refused
        print(
            f"warning: {', '.join(in_file)} in {cfg.origin} {'applies' if len(in_file) == 1 else 'apply'} only to "
            f"named cycles: {'it is' if len(in_file) == 1 else 'they are'} ignored for the run table {args.cycle}",
            file=sys.stderr,
        )
    if on_table and not named:
        raise InputError(
            f"{', '.join(on_table)} {'applies' if len(on_table) == 1 else 'apply'} only to named cycles; "
            f"{args.cycle} is a run table, simulated as it is"
        )
    if named and args.allow_untrusted:
        raise InputError(
            f"--allow-untrusted applies only to CSV run tables (whose units may look wrong); {args.cycle} is a "
            "named cycle, made in the right units"
        )
    if s.hold_oil_c is not None and s.cooler not in (None, "hold"):
        held = given(args, ("simulate.hold_oil_c",)) or ["simulate.hold_oil_c"]
        raise InputError(
            f"{held[0]} holds the sump, which cooler {s.cooler} does not: use cooler hold ([cooler] kind = "
            f'"hold" or --cooler hold) or leave the cooler out'
        )
    args.seed = 0 if args.seed is None else args.seed
    if args.seed < 0:
        raise InputError(f"--seed {args.seed} must be a non-negative integer")
    if args.start_time is not None and not args.can_log:
        raise InputError("--start-time sets the time stamps of the CAN log, which only --can-log writes")
    s.start_time = parse_start_time(args.start_time)
    for opt, value_c in (("--initial-temp", s.initial_temp_c), ("--hold-oil", s.hold_oil_c)):
        if value_c is not None:
            check_temperature_c(opt, value_c)
    return s


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
    from firmware_model.description import description_of
    from tools.cycles.named import boundaries_a_log_cannot_carry, check_cycle_hold, get_cycle
    from tools.plant.reference import ReferencePlant
    from tools.replay.table import drive_limits

    cfg = resolve_gearbox(args)
    s = resolve_settings(args, cfg)
    params = cfg.load_params()
    effects = _effects(args.effect)
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
        table = get_cycle(
            args.cycle, rate_hz=s.rate_hz, noise=s.noise, seed=args.seed, description=description_of(params)
        )
        check_cycle_hold(table.meta, s.hold_oil_c, s.cooler)  # a held sump against the configured cooler
        fixed_ratio = table.meta.get("drive") == "fixed_ratio"
        if table.meta.get("fitted"):  # a GRS905 cycle fitted to another gearbox: said once (tools.cycles.fit)
            print(f"note: {table.meta['fitted']}", file=sys.stderr)
        if args.can_log:  # a torque EEC1 cannot carry is refused before the plant runs
            from tools.can.logsynth import reference_torques_nm

            reference_torques_nm(table, cfg)
            note = boundaries_a_log_cannot_carry(table, description_of(params))
            if note:
                print(f"note: the CAN log {note}", file=sys.stderr)
        if cycle_file is not None and not args.allow_untrusted:
            # the oil column is used as the sump (--cooler measured) or, without --initial-temp, as every node's start
            oil_used = s.cooler == "measured" or (s.initial_temp_c is None and table.has("oil_temp_c"))
            limits = drive_limits(description_of(params)) if fixed_ratio else None
            _refuse_unit_mistakes(table, cycle_file, oil_used=oil_used, sparse_ok=fixed_ratio, drive=limits)
        if cycle_file is not None and not fixed_ratio:  # (a fixed-ratio table's row holds one period: interfaces.md)
            gaps = gap_note(table, cycle_file)
            if gaps:
                print(f"note: {gaps}", file=sys.stderr)
        if fixed_ratio:  # one output row per input row of a table slower than the output period (a SCADA table)
            s.out_dt_s = max(s.out_dt_s, table.meta["row_period_s"])
        plant = ReferencePlant(params, effects, cooler=s.cooler, dt_s=s.dt_s)
        _refuse_idle_effects(effects, plant.kind, description_of(params))
        try:
            res = plant.run(
                table,
                initial_temp_c=s.initial_temp_c,
                hold_oil_c=s.hold_oil_c,
                out_dt_s=s.out_dt_s,
                progress=None if not args.quiet else False,
            )
        except InputError as exc:  # the plant checks the rows: name the file they came from (cycles.md)
            if cycle_file is None or str(cycle_file) in str(exc):
                raise
            raise InputError(f"{cycle_file}: {exc}") from None
        _write_outputs(args, table, res, params, cfg, tmp, s.start_time)
    if not args.quiet:
        _print_summary(args, res, description_of(params))
    else:  # the plant's notes say where the run left its model: quiet or not
        for w in res.warnings:
            print(f"note: {w}", file=sys.stderr)
    held_c = (
        s.hold_oil_c if s.hold_oil_c is not None else (plant.p["cooler.hold_temp"] if plant.kind == "hold" else None)
    )
    _note_cold_parts_beside_a_held_sump(res.table, held_c)
    return 0


def _note_cold_parts_beside_a_held_sump(table, hold_c: float | None) -> None:
    """A note when the sump is held warm while the other parts start far colder (a [simulate] hold_oil_c without
    initial_temp_c): the first minutes are a warm-up, which a run that meant a warm gearbox would not want."""
    if hold_c is None or not table.n:
        return
    first = [float(table[c][0]) for c in table.columns if c.startswith("T_") and c.endswith("_c") and c != "T_oil_c"]
    if first and hold_c - min(first) > 20.0:
        print(
            f"note: the sump is held at {hold_c:g} degC while the other parts start at {min(first):.0f} degC: the "
            "run begins with their warm-up; [simulate] initial_temp_c starts them warm",
            file=sys.stderr,
        )


#: the effects that act on a cooler only of these kinds (firmware_model.physics.cooler.cooler_heat): elsewhere they
#: change nothing, and a run that asked for one would pass for a run with it
EFFECT_COOLERS = {"thermostat_offset": ("air",), "cooler_effectiveness_scale": ("liquid", "air")}


#: the effects that act on a part of the gearbox only (its description): on a gearbox without it they change nothing
EFFECT_PARTS = {
    "planetary_loss_scale": ("a planetary set", lambda d: bool(d.planetary)),
    "planet_oil_h_scale": ("a planetary set", lambda d: bool(d.planetary)),
    "hot_surroundings_offset": (
        "a hot_surroundings boundary",
        lambda d: any(b.id == "hot_surroundings" for b in d.boundaries),
    ),
    "synchronizer_shift_heat": ("a synchronizer", lambda d: any(c.kind == "sync" for c in d.couplings)),
}


def _refuse_idle_effects(effects: dict, cooler: str, description=None) -> None:
    """InputError for an --effect that the run's cooler, or the gearbox (``description``), makes act on nothing: a
    run that asked for one would pass for a run with it (planetary_loss_scale on a 6-speed gearbox without a
    planetary set: 0.0000 K of difference, exit 0)."""
    for eid, kinds in EFFECT_COOLERS.items():
        if eid in effects and cooler not in kinds:
            raise InputError(
                f"--effect {eid} acts on {' or '.join(kinds)} coolers, and this run's cooler is {cooler}: it would "
                f'change nothing; choose the cooler ([cooler] kind = "{kinds[0]}") or leave the effect out'
            )
    for eid, (what, has) in EFFECT_PARTS.items():
        if eid in effects and description is not None and not has(description):
            raise InputError(
                f"--effect {eid} acts on {what}, and gearbox {description.name} has none: it would change nothing; "
                "leave the effect out"
            )


def _effects(given_effects) -> dict:
    """The --effect values, each effect once."""
    parsed = [parse_effect(e) for e in given_effects]
    effects = dict(parsed)
    if len(effects) < len(parsed):
        twice = sorted({e for e, _ in parsed if sum(x == e for x, _ in parsed) > 1})
        raise InputError(f"--effect {', '.join(twice)} is given twice; give each effect once")
    return effects


def _print_summary(args, res, description=None) -> None:
    """The span simulated, the five hottest nodes (named as ``description`` names them) and the energy balance; the
    plant's warnings on stderr."""
    from tools.published import words

    eb = res.energy_balance()
    tb = res.table
    hot = sorted(
        ((float(tb[c].max()), c[2:-2]) for c in tb.columns if c.startswith("T_") and c.endswith("_c")), reverse=True
    )[:5]
    print(f"simulated {tb['time_s'][-1] - tb['time_s'][0]:.0f} s of '{args.cycle}' in {res.wall_s:.1f} s -> {args.out}")
    print("hottest:\n" + "\n".join(f"  {n:10s} {v:6.1f} degC  {words(n, description) or ''}" for v, n in hot))
    net_in = " (negative: the cooler and boundaries heated the gearbox on balance)" if eb["rejected_j"] < 0 else ""
    print(
        f"energy: generated {eb['generated_j'] / 1e6:.2f} MJ = stored {eb['stored_j'] / 1e6:.2f} MJ + rejected "
        f"{eb['rejected_j'] / 1e6:.2f} MJ{net_in} (closure {eb['closure_rel']:.1e})"
    )
    for w in res.warnings:
        print(f"note: {w}", file=sys.stderr)


def _refuse_unit_mistakes(
    table, name: str, oil_used: bool = False, sparse_ok: bool = False, drive: tuple | None = None
) -> None:
    """InputError for a CSV cycle whose units look wrong, before the plant runs, as replay refuses them: a 10-minute
    file with time_s in milliseconds would simulate 7 days and write a 600 MB table and a 4.3 GB CAN log, and
    rad/s speed would run as a stalled engine. ``sparse_ok``: rows far apart are expected (a fixed-ratio drive's
    SCADA averages), not taken for milliseconds; ``drive``: a fixed-ratio drive's (max speed [rpm], max torque [N m])
    for its kN m rule."""
    from firmware_model.service.degraded import unit_findings
    from tools.runtable import milliseconds_sentence

    t = np.asarray(table["time_s"], dtype=float)
    ms = milliseconds_sentence(t, name, sparse_ok)
    if ms:
        raise InputError(f"{ms}; if the rows really lie that far apart, pass --allow-untrusted")
    from firmware_model.service.plausibility import record_findings

    engine = table.meta.get("drive") != "fixed_ratio"
    speed = unit_findings(0, 0, [], table["engine_speed_rpm"], table["engine_torque_nm"], engine=engine)
    # the whole-record rules (oil only when the plant takes it as its sump: --cooler measured)
    cols = {c: table[c] for c in table.columns if c != "oil_temp_c" or oil_used}
    whole = record_findings(cols, float(np.median(np.diff(t))), engine=engine, drive_limits=drive) if t.size > 1 else []
    if speed or whole:
        raise InputError(f"{name}: {(speed + whole)[0].sentence} (pass --allow-untrusted to simulate it as it is)")


#: a CSV cycle's step longer than this many median row spacings (and GAP_NOTE_MIN_S) is a gap the note names
GAP_NOTE_PERIODS, GAP_NOTE_MIN_S = 2.0, 10.0


def gap_note(table, name: str) -> str:
    """A sentence on a CSV cycle's gaps ('' without): the plant holds the row before each gap through all of it
    (rows at load in the output where the table has none), while the sensor holds the inputs over a time jump for
    60 s and then takes the engine as off, so the two part there (a validation trial: 5 minutes cut from a climb,
    simulated at load in silence, replayed 35 K apart)."""
    t = np.asarray(table["time_s"], dtype=float)
    if t.size < 3:
        return ""
    dt = np.diff(t)
    gap = (dt > GAP_NOTE_PERIODS * float(np.median(dt))) & (dt > GAP_NOTE_MIN_S)
    if not gap.any():
        return ""
    k = int(np.argmax(np.where(gap, dt, -np.inf)))
    return (
        f"{name}: {int(gap.sum())} gap{'s' if gap.sum() > 1 else ''} between rows (the longest {dt[k]:.0f} s after "
        f"{t[k]:.1f} s): the plant holds the row before a gap through all of it, while the sensor (replay) holds the "
        "inputs 60 s and then takes the engine as off, so their outputs part there; fill the gap or split the cycle"
    )


def plot_paths(plot):
    """The two figures of --plot: the temperatures (matplotlib appends .png to a name without a suffix) and the
    heat budget, <stem>_heat<suffix>; (None, None) without --plot."""
    if not plot:
        return None, None
    pp = Path(plot)
    return figure_path(plot), pp.with_name(pp.stem + "_heat" + (pp.suffix or ".png"))


def _write_outputs(args, table, res, params, cfg, tmp, start_time_s: float) -> None:
    """The run table, the CAN log and the figures, to the temporary files ``tmp`` (tools.outputs)."""
    from tools.runtable import write_run_table

    out_tmp, log_tmp, plot_tmp, heat_tmp = tmp
    written = res.table
    if table.meta.get("drive") == "fixed_ratio":  # named as its input table: a replay input as it stands
        from tools.drive_table import as_fixed_ratio_output

        written = as_fixed_ratio_output(res.table)
    with naming(out_tmp):
        write_run_table(written, out_tmp)
    if log_tmp:
        from tools.can.logsynth import write_can_log

        with naming(log_tmp):
            write_can_log(table, res.table, log_tmp, params, config=cfg, start_timestamp_s=start_time_s)
    if plot_tmp:
        from tools.plots import plot_heat_budget, plot_simulation

        title = f"{params.variant} reference plant, cycle {args.cycle}" + (
            f", effects {args.effect}" if args.effect else ""
        )
        with naming(plot_tmp):
            plot_simulation(res.table, plot_tmp, title, gearbox=params)
        with naming(heat_tmp):
            plot_heat_budget(res.table, heat_tmp, title)

"""`gearbox-vsensor bench-diagnosis`: the withheld-effect benchmark of the gap diagnosis (tools/diagnosis/bench.py)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from types import SimpleNamespace

from firmware_model.errors import InputError
from tools.cli.gearbox_option import add_gearbox_option, gearbox_of, require_vehicle_drive, resolve_gearbox
from tools.cli.settings import add_hidden, given, setting


def add_subparser(sub):
    p = sub.add_parser(
        "bench-diagnosis",
        help="withheld-effect benchmark of the gap diagnosis (synthetic scenarios)",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description=(
            "Generate scenarios with the reference plant: one catalog effect (or none) at a random magnitude, at "
            "least 30 % of the way from neutral to a bound, on SYNTHETIC training cycles and different test "
            "cycles; measure them like real sensors (lag 0.5-5 s, noise 0.1-0.2 degC, J1939 quantisation "
            "0.03125 degC, 0.5 % dropped samples, noisy torque and speed) with the channels of a truck (oil only) "
            "or a rig (oil plus meas_T_PS_c, meas_T_LI.teeth_c, meas_T_BLR_c); diagnose them with the effect "
            "withheld and print the score table: top-1 identification, false alarms on null scenarios, test-set "
            "RMS shrink, seconds per scenario."
        ),
        epilog="examples:\n  gearbox-vsensor bench-diagnosis --scenarios 40 --seed 1 --out bench/\n"
        "  gearbox-vsensor bench-diagnosis --effect planetary_loss_scale:factor=1.3 --write-scenarios --out ex/",
    )
    p.add_argument("--scenarios", type=int, metavar="N", help="number of scenarios (default 40: 8 null)")
    p.add_argument("--seed", type=int, default=1, metavar="S", help="random seed (default 1)")
    p.add_argument("--out", metavar="DIR", help="write bench.md, bench.csv and one JSON per scenario here")
    p.add_argument("--only", metavar="I,J,...", help="run only these scenario indices of the plan")
    p.add_argument(
        "--family",
        choices=("single", "sensor", "pair", "model-form"),
        help="the plan's scenario family: single (default: one physical catalog effect, or none), "
        "sensor (the oil sensor's offset or gain, or none), pair (two effects at once, a physical "
        "one and a physical or sensor one, each at least half-way to a bound; or none) or model-form "
        "(four assumed values of the parameter file moved within their bounds: the diagnosis, then "
        "calibrate --auto, on the same files)",
    )
    p.add_argument(
        "--effect",
        metavar="ID:PARAM=VALUE|none",
        help="one custom scenario with this effect instead of the plan (its set-up and cooler: [bench] setup "
        "and cooler)",
    )
    p.add_argument(
        "--write-scenarios",
        action="store_true",
        help="also write each scenario's measured run tables (train1.csv, train2.csv, test1.csv) under "
        "DIR/scenario_NN/, to run `diagnose` on them by hand",
    )
    p.add_argument(
        "--config",
        metavar="TOML",
        help="a configuration with a [bench] section: model under diagnosis (plant), training and test cycle "
        "lengths (1500 s), the custom scenario's set-up (rig) and cooler (liquid), how the files start "
        "(auto) (docs/interfaces.md section 8)",
    )
    for key in BENCH_KEYS:  # moved to the configuration, still accepted (hidden) and overriding it
        add_hidden(p, key)
    add_gearbox_option(p)
    p.set_defaults(func=run)
    return p


#: the [bench] settings of the configuration (firmware_model.config.SETTINGS)
BENCH_KEYS = ("bench.model", "bench.train_s", "bench.test_s", "bench.setup", "bench.cooler", "bench.start")


def _check(args, s) -> None:
    """InputError for options of the other mode (a plan, or the custom scenario of --effect) and numbers out of
    range; then the default of --scenarios."""
    plan_only = [
        o
        for o, v in (("--scenarios", args.scenarios), ("--only", args.only), ("--family", args.family))
        if v is not None
    ]
    custom_only = given(args, ("bench.setup", "bench.cooler"))
    if args.effect and plan_only:
        raise InputError(
            f"{', '.join(plan_only)} {'selects' if len(plan_only) == 1 else 'select'} scenarios of the "
            f"plan, which --effect replaces by one custom scenario"
        )
    if not args.effect and custom_only:
        raise InputError(
            f"{', '.join(custom_only)} {'applies' if len(custom_only) == 1 else 'apply'} only to the "
            f"custom scenario of --effect"
        )
    args.scenarios = 40 if args.scenarios is None else args.scenarios
    if args.scenarios < 1:
        raise InputError(f"--scenarios {args.scenarios} must be at least 1")
    if args.seed < 0:
        raise InputError(f"--seed {args.seed} must be a non-negative integer")
    if args.family == "model-form" and s.start != "auto":
        named = (given(args, ("bench.start",)) or ["bench.start"])[0]
        raise InputError(
            f"{named} applies to the diagnosis of the single, sensor and pair families; the model-form "
            "family's files start at rest"
        )
    if args.write_scenarios and not args.out:
        raise InputError("--write-scenarios needs --out DIR")


def _only(args):
    """The scenario numbers of --only (None: all), each within the plan."""
    if not args.only:
        return None
    try:
        only = {int(x) for x in args.only.split(",") if x.strip()}
    except ValueError:
        raise InputError(f"--only {args.only!r} must be comma-separated scenario numbers") from None
    outside = sorted(i for i in only if not 0 <= i < args.scenarios)
    if outside:
        raise InputError(
            f"--only {args.only}: no scenario {', '.join(map(str, outside))} in a plan of "
            f"{args.scenarios} (numbered 0..{args.scenarios - 1}; --scenarios sets the plan)"
        )
    return only


def run(args) -> int:
    import warnings

    from firmware_model.config import load_config
    from firmware_model.effects import parse_effect
    from firmware_model.parameters import load_parameters
    from tools.diagnosis import bench as B
    from tools.diagnosis.options import Options

    warnings.filterwarnings("ignore", category=RuntimeWarning)
    cfg = resolve_gearbox(args, load_config(args.config))
    require_vehicle_drive(cfg.load_params(), "bench-diagnosis", scada=False)
    s = SimpleNamespace(**{k.split(".")[1]: setting(args, cfg, k) for k in BENCH_KEYS})
    _check(args, s)
    only = _only(args)
    custom = None
    if args.effect:
        if args.effect.strip().lower() == "none":
            custom = (s.setup, None, None, s.cooler)
        else:
            eid, val = parse_effect(args.effect)
            custom = (s.setup, eid, val, s.cooler)
    from tqdm import tqdm

    if args.family == "model-form":
        return _model_form(args, s, only, load_parameters(gearbox_of(cfg)))
    # one result line per scenario on stderr, above the progress bar (shown on a terminal)
    rows, summary = B.run_bench(
        args.scenarios,
        args.seed,
        args.out,
        model=s.model,
        train_s=s.train_s,
        test_s=s.test_s,
        only=only,
        custom=custom,
        write_scenarios=args.write_scenarios,
        progress=lambda line: tqdm.write(line, file=sys.stderr),
        family=args.family or "single",
        opts=Options(start=s.start),
        params=load_parameters(gearbox_of(cfg)),
    )
    print(B.format_table(rows, summary))
    if args.out:
        print(f"\n-> {Path(args.out) / 'bench.md'}", file=sys.stderr)
    return 0


def _model_form(args, s, only, params) -> int:
    """The model-form family: its own rows (diagnosis and calibration on the same files)."""
    from tools.diagnosis.bench_model_form import format_rows, run_model_form_bench

    rows = run_model_form_bench(
        args.scenarios,
        args.seed,
        params,
        model=s.model,
        train_s=s.train_s,
        only=only,
        progress=lambda line: print(line, file=sys.stderr),
    )
    table = format_rows(rows)
    print(table)
    if args.out:
        out = Path(args.out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "bench.md").write_text(table)
        print(f"\n-> {out / 'bench.md'}", file=sys.stderr)
    return 0

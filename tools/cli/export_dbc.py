"""`gearbox-vsensor export-dbc`: the DBC of a gearbox's CAN frames, generated from its description (can_dbc)."""

from __future__ import annotations

import argparse
import sys


def add_subparser(sub):
    p = sub.add_parser(
        "export-dbc",
        help="write the DBC of a gearbox's CAN frames, generated from its description's published components",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Write the DBC of the sensor's CAN frames for one gearbox: the J1939 inputs, then per published "
        "component (the [topology.published] order of its description, docs/description.md) a temperature, a "
        "warning level, a time to limit and a rig thermocouple signal, the status and DM1 frames. Four 16-bit "
        "values or 32 warning levels to a frame, Proprietary B PGNs from 0xFF40 up (docs/can.md, 'A DBC per "
        "gearbox'); for the GRS905 it is the shipped can_dbc/gearbox_vsensor.dbc. A description with more "
        "published components than the PGNs hold is one sentence (exit 2).",
        epilog="examples:\n  gearbox-vsensor export-dbc --out grs905.dbc\n"
        "  gearbox-vsensor export-dbc --gearbox my_gearbox.toml --out my_gearbox.dbc",
    )
    p.add_argument(
        "--gearbox",
        default="GRS905",
        metavar="NAME|FILE",
        help="a description shipped in firmware_model/params/ or the path of a .toml file (default: GRS905)",
    )
    p.add_argument("--out", metavar="FILE.dbc", help="file to write (default: standard output)")
    p.set_defaults(func=run)


def component_meanings(description) -> dict:
    """Published component id -> what it is in a few words, from the description's part names (``LI.teeth`` ->
    ``teeth of the <LI's name>``), else the GRS905 glossary's (firmware_model.components); None when neither knows."""
    from firmware_model.components import WHEEL_PARTS, meaning

    names = {i: n for i, n in description.names.items() if n and n != i}  # a part named by its id says nothing
    out = {}
    for p in description.published:
        wheel, _, part = p.id.partition(".")
        if p.id in names:
            out[p.id] = names[p.id]
        elif part in WHEEL_PARTS and wheel in names:
            out[p.id] = f"{WHEEL_PARTS[part]} of the {names[wheel]}"
        else:
            out[p.id] = meaning(p.id)
    return out


def run(args) -> int:
    from can_dbc.generate import GenerateError, generate_dbc
    from firmware_model.description import description_path, load_description
    from firmware_model.errors import InputError, ParameterError
    from tools.cli.paths import check_paths
    from tools.runtable import atomic_text_file

    if args.out is not None and not str(args.out).lower().endswith(".dbc"):
        raise InputError(f"--out {args.out}: a DBC file's name ends in .dbc")
    d = load_description(args.gearbox)
    if args.out is not None:
        try:
            source = str(description_path(args.gearbox))
        except ParameterError:
            source = None  # (a description made in code)
        check_paths([("the --gearbox description", source)], {"--out": args.out})
    # what the sensor publishes (firmware_model.onboard.reduce.published_ids): a derived temperature (a forced
    # system's oil inlet) is no node of the onboard network, the plant's only
    on_bus = tuple(p.id for p in d.published if p.id not in getattr(d, "derived", ()))
    try:
        text = generate_dbc(list(on_bus), component_meanings(d))
    except GenerateError as exc:
        print(f"gearbox-vsensor export-dbc: error: gearbox {d.name}: {exc}", file=sys.stderr)
        return 2
    if args.out is None:
        sys.stdout.write(text)
        return 0
    with atomic_text_file(args.out) as f:
        f.write(text)
    left = [p.id for p in d.published if p.id not in on_bus]
    note = f" ({', '.join(left)}: derived, the plant's only, not on the bus)" if left else ""
    print(f"wrote {args.out}: the DBC of {d.name}'s {len(on_bus)} published components{note}")
    _say_inputs_not_carried(d)
    return 0


def _say_inputs_not_carried(description) -> None:
    """A note where the J1939 inputs cannot carry the drive's torque (EEC1's percent of at most the largest reference
    torque: a wind turbine's rotor): the output frames still serve, the inputs must come another way."""
    from tools.can.logsynth import PCT_RANGE, REF_TORQUE_MAX_NM

    top_nm = PCT_RANGE[1] / 100.0 * REF_TORQUE_MAX_NM
    if description.drive.max_torque_nm > top_nm:
        print(
            f"note: {description.name}'s largest input torque, {description.drive.max_torque_nm:.4g} N m, is past "
            f"the most J1939's EEC1 carries ({top_nm:.0f} N m, {PCT_RANGE[1]:g} % of the largest reference torque): "
            "its inputs cannot come over this DBC's J1939 frames; its output frames (temperatures, warnings, time "
            "to limit, status) can, with the sensor fed from its run table or records (replay)",
            file=sys.stderr,
        )

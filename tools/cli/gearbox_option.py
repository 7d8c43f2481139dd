"""The ``--gearbox NAME|FILE`` option of the commands that build a gearbox, and its resolution.

NAME is a description shipped in firmware_model/params/ (GRS905, GRSO905, R1, HR225, MM82), FILE the path of a
user's parameter file (with its ``[topology]``, docs/description.md). The command line wins over the configuration's
``[gearbox]`` (``variant = NAME`` or ``params = FILE``), which wins over the default, GRS905. ``--variant`` is the
option's former name, still accepted and hidden; given with ``--gearbox`` it must name the same gearbox.

Everything is checked before any work: an unknown NAME and a FILE that is missing or does not load are one sentence
(exit 2 on the command line); what a builder cannot model yet is its own sentence when the command builds it.
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import sys
from pathlib import Path

from firmware_model.errors import InputError, ParameterError

GEARBOX_HELP = (
    "the gearbox: a description shipped in firmware_model/params/ (NAME: {names}) or the path of a parameter "
    "file with a [topology] (FILE) (default: the --config's [gearbox], else GRS905). Name the gearbox the data "
    "comes from: another one whose gears step alike (the GRS905 and GRSO905) is not told apart by the gear check, "
    "and its estimates are off by many kelvin"
)


class _GearboxAction(argparse.Action):
    """Stores the gearbox and remembers each option that gave one, so that --variant and --gearbox naming two
    different gearboxes is an error rather than the last one silently winning."""

    def __call__(self, parser, namespace, values, option_string=None):
        given = list(getattr(namespace, "gearbox_given", None) or [])
        given.append((option_string, values))
        namespace.gearbox_given = given
        setattr(namespace, self.dest, values)


@functools.lru_cache(maxsize=1)
def shipped() -> tuple:
    """The shipped descriptions' names (firmware_model.description.shipped_descriptions), read once per process:
    every command's parser names them."""
    from firmware_model.description import shipped_descriptions

    return shipped_descriptions()


def add_gearbox_option(parser, help_text: str | None = None) -> None:
    """``--gearbox NAME|FILE`` (default None: the configuration's, else GRS905) and its hidden alias ``--variant``
    (the same dest)."""
    text = (help_text or GEARBOX_HELP).format(names=", ".join(shipped()))
    parser.add_argument(
        "--gearbox", dest="gearbox", action=_GearboxAction, default=None, metavar="NAME|FILE", help=text
    )
    parser.add_argument("--variant", dest="gearbox", action=_GearboxAction, default=None, help=argparse.SUPPRESS)


def given_gearbox(args) -> str | None:
    """The gearbox the command line names (None: none); InputError when --variant and --gearbox name two."""
    given = getattr(args, "gearbox_given", None) or []
    values = {v for _, v in given}
    if len(values) > 1:
        said = " and ".join(f"{o} {v}" for o, v in given)
        raise InputError(f"{said} name different gearboxes: give one (--variant is the former name of --gearbox)")
    return getattr(args, "gearbox", None)


def _is_file(name: str) -> bool:
    """FILE (a path) rather than NAME: a .toml suffix, a path separator, or a file of that name here."""
    return Path(name).suffix.lower() == ".toml" or Path(name).name != name or Path(name).is_file()


def with_gearbox(cfg, gearbox: str | None):
    """The configuration ``cfg`` with ``gearbox`` (NAME or FILE; None: as it is) in place of its [gearbox]; an
    unknown NAME or a missing FILE is an InputError naming it and the shipped names."""
    if gearbox is None:
        return cfg
    names = shipped()
    if _is_file(gearbox):
        if not Path(gearbox).is_file():
            raise InputError(
                f"--gearbox {gearbox}: no such file; give the path of a parameter file with a [topology] or one "
                f"of the shipped gearboxes {', '.join(names)}"
            )
        return dataclasses.replace(cfg, params_path=str(Path(gearbox).resolve()))
    if gearbox not in names:
        raise InputError(
            f"--gearbox {gearbox} is not a shipped gearbox: use one of {', '.join(names)} or the path of a "
            f"parameter file (.toml) with a [topology]"
        )
    return dataclasses.replace(cfg, variant=gearbox, params_path=None)


def gearbox_of(cfg) -> str:
    """The gearbox a configuration names: its parameter file, else its variant."""
    return cfg.params_path or cfg.variant


def check_gearbox(cfg, said: str | None = None):
    """The description of the configuration's gearbox, checked before any work: its parameter file loads (its
    values, and its description with them); InputError naming it (``said``: as the user gave it, ``--gearbox
    NAME``) and why otherwise. What a builder cannot run yet is its own one sentence when the command builds it."""
    from firmware_model.description import description_of
    from firmware_model.parameters import load_parameters

    name = gearbox_of(cfg)
    said = said or f"gearbox {name}"
    try:
        return description_of(load_parameters(name))
    except ParameterError as exc:
        raise InputError(f"{said} does not load ({exc}); the shipped gearboxes are {', '.join(shipped())}") from None


def _config_key(cfg) -> str:
    """Where a configuration names its gearbox, for a sentence: ``config truck.toml: gearbox.params = "my.toml"``."""
    if cfg.origin == "defaults":
        return f"the default gearbox {cfg.variant}"
    key, value = ("params", cfg.params_path) if cfg.params_path else ("variant", cfg.variant)
    return f"config {Path(cfg.origin).name}: gearbox.{key} = {value!r}"


def resolve_gearbox(args, cfg=None):
    """The configuration a command runs with: ``--config`` (``cfg`` when the command loaded it already) with the
    command line's gearbox in place of its [gearbox], the gearbox checked (:func:`check_gearbox`); resolved once
    per command (kept on ``args``)."""
    from firmware_model.config import load_config

    if getattr(args, "resolved_config", None) is not None:
        return args.resolved_config
    gearbox = given_gearbox(args)
    if cfg is None:
        cfg = load_config(getattr(args, "config", None))
    before = cfg
    cfg = with_gearbox(cfg, gearbox)
    # a configuration that names another gearbox: the command line wins (documented), said (a rig's reference
    # configuration overridden in silence: a trial)
    if gearbox is not None and before.origin != "defaults" and (before.params_path or before.variant != "GRS905"):
        if gearbox_of(before) != gearbox_of(cfg):
            print(f"note: --gearbox {gearbox} overrides {_config_key(before)}", file=sys.stderr)
    check_gearbox(cfg, f"--gearbox {gearbox}" if gearbox is not None else _config_key(cfg))
    args.resolved_config = cfg
    return cfg


def require_vehicle_drive(params, command: str, scada: bool = True) -> None:
    """InputError for a fixed-ratio gearbox where ``command`` takes a vehicle's run tables (the diagnosis's effects,
    rig set-ups and synthetic drives are a truck's); ``scada``: the command reads a fixed-ratio gearbox's records
    through --columns."""
    from firmware_model.description import description_of

    d = description_of(params)
    if d.drive.kind == "vehicle":
        return
    where = "; its records go through --columns NAME|FILE (SCADA: a column map, docs/real-data.md)" if scada else ""
    raise InputError(
        f"gearbox {d.name} has a {d.drive.kind} drive: {command} on run tables takes a vehicle's gearbox (the "
        f"GRS905 family){where}"
    )

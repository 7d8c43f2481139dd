"""The settings a command reads from the configuration file rather than from its command line
(firmware_model.config.SETTINGS, docs/interfaces.md section 8), and the help formatter that shows every default.

Each setting's former option stays accepted, hidden from ``--help``, and wins over the file: scripts that used it
keep working (:func:`add_hidden`, :func:`setting`).
"""

from __future__ import annotations

import argparse

from firmware_model.config import SETTINGS
from firmware_model.errors import InputError


def dest_of(key: str) -> str:
    """The argparse dest of a setting's hidden option: ``simulate.rate_hz`` -> ``simulate_rate_hz``."""
    return key.replace(".", "_")


def add_hidden(parser, key: str) -> None:
    """The option that :data:`SETTINGS` ``[key]`` replaced, hidden from --help (still accepted; None when not
    given). A flag sets the value its name says (``--no-filters``: false, ``--rig``: true)."""
    s = SETTINGS[key]
    kw: dict = {"dest": dest_of(key), "default": None, "help": argparse.SUPPRESS}
    if s.kind == "bool":
        kw.update(action="store_const", const=not s.option.startswith("--no-"))
    elif isinstance(s.kind, tuple):
        kw.update(choices=s.kind, type=str.upper if all(k.isupper() for k in s.kind) else str)
    else:  # a whole number too is read as a number, so that 0.5 is refused in the setting's own sentence
        kw.update(type=float)
    parser.add_argument(s.option, **kw)


def setting(args, cfg, key: str):
    """The value of a setting: its hidden option when given (checked like the file's value), else the
    configuration's, else its default."""
    s = SETTINGS[key]
    v = getattr(args, dest_of(key), None)
    if v is None:
        return cfg.setting(key)
    if not s.accepts(v):
        shown = f"{v:g}" if s.kind == "int" else repr(float(v)) + (" degC" if key.endswith("_c") else "")
        raise InputError(f"{s.option} {shown} must be {s.describe()} (configuration key {key})")
    return int(v) if s.kind == "int" else v


def given(args, keys) -> list[str]:
    """The hidden options among ``keys`` that the command line set, as written."""
    return [SETTINGS[k].option for k in keys if getattr(args, dest_of(k), None) is not None]


class DefaultsHelpFormatter(argparse.RawDescriptionHelpFormatter):
    """Descriptions and epilogs as written, and every option's default at the end of its help: ``(default: X)``,
    ``(default: none)`` for an option without one, unless the help already says it; flags (off unless given) and
    required options are left as they are."""

    def _get_help_string(self, action):
        text = action.help or ""
        if (
            text == argparse.SUPPRESS
            or not action.option_strings
            or action.required
            or action.nargs == 0
            or "default" in text.lower()
            or text.rstrip().endswith("required")
        ):
            return text
        if action.default in (None, [], ()):
            return text + " (default: none)"
        return text + " (default: %(default)s)"

"""The ``--core auto|c|numpy`` option of the commands that step the onboard sensor, and the core line they print.

``auto`` (default): the compiled C kernel when it loads, else the numpy step (with the reason); ``c``: the kernel or
an error saying why not; ``numpy``: the readable reference step. The choice reaches every sensor the command builds,
worker processes included, through the ``GVS_CORE`` environment variable
(firmware_model.onboard.core_select).
"""

from __future__ import annotations

import os

from firmware_model.errors import InputError

CORE_HELP = (
    "which onboard step: auto (default: the compiled C kernel when it is built, else numpy), c (the "
    "kernel, or an error saying why it is unavailable), numpy (the readable reference; same outputs)"
)


def add_core_option(parser) -> None:
    """``--core`` (default None: auto, so that a command can tell whether it was given)."""
    parser.add_argument("--core", choices=("auto", "c", "numpy"), default=None, help=CORE_HELP)


def apply_core(args) -> str:
    """Make ``args.core`` the core of every sensor this process and its workers build; returns the core line
    (``core: c (the compiled C99 kernel, double)``)."""
    core = getattr(args, "core", "auto") or "auto"
    os.environ["GVS_CORE"] = core
    return "core: " + active_core(core)


def active_core(core: str = "auto") -> str:
    """The core a sensor built now would step on, and why not the kernel when it is not."""
    from firmware_model.onboard.ckernel import availability

    if core == "numpy" or (core == "auto" and os.environ.get("GVS_CORE", "auto") == "numpy"):
        return "numpy (the reference step)"
    ok, why = availability()
    if ok:
        return "c (the compiled C99 kernel, double)"
    if core == "c":
        raise InputError(f"--core c: {why}")
    return why

"""`gearbox-vsensor play`: play a CAN log onto a bus with its original timing, like canplayer (tools/replay/log.py,
``play_log_on``). It computes nothing: run `gearbox-vsensor run` on that bus for the sensor's outputs."""

from __future__ import annotations

import argparse
import math
import sys

from firmware_model.errors import InputError
from tools.can.bus import add_bus_options, can_subcommand
from tools.cli.paths import check_paths


def add_subparser(sub):
    p = can_subcommand(
        sub,
        "play",
        summary="play a CAN log onto a bus with its original timing (like canplayer)",
        description="Send the frames of a CAN log (.log candump -L, .asc, .blf, .mf4, .trc) onto a bus with their "
        "original timing, X times faster with --speed, like canplayer; error frames are not sent and "
        "gaps longer than 60 s are cut short. It computes nothing: run `gearbox-vsensor run` on that "
        "bus for the sensor's outputs, or `gearbox-vsensor replay LOG --out EST.csv` to compute them "
        "offline.",
        examples=[
            "gearbox-vsensor play drive.blf --interface socketcan --channel vcan0",
            "gearbox-vsensor play drive.log --interface udp_multicast --channel 239.74.163.2 --speed 10",
        ],
    )
    p.add_argument("input", metavar="LOG", help="CAN log (.log .asc .blf .mf4 .trc)")
    add_bus_options(p)
    p.add_argument(
        "--speed",
        type=float,
        default=1.0,
        metavar="X",
        help="play X times faster (default: 1; a sensor on a bus that stamps frames on arrival, all but "
        "virtual, then sees a wrong time base: a warning says so)",
    )
    p.add_argument("--quiet", action="store_true", help=argparse.SUPPRESS)  # its one line: redirect it
    p.set_defaults(func=run)
    return p


def run(args) -> int:
    from tools.can.bus import speed_warning, virtual_note
    from tools.replay.log import play_log_on

    check_paths([("the input", args.input)], {})
    if not (math.isfinite(args.speed) and args.speed > 0):  # (before the warning, which divides by it)
        raise InputError(f"--speed {args.speed:g} must be a positive number (1: the log's own timing)")
    warning = speed_warning(args.interface, args.speed)
    if warning:
        print(f"warning: {warning}", file=sys.stderr)
    note = virtual_note(args.interface)  # as run and plant say it: a virtual bus reaches this process only
    if note:
        print(f"note: {note}", file=sys.stderr)
    n = play_log_on(args.input, args.interface, args.channel, args.bitrate, speedup=args.speed)
    if not args.quiet:
        print(f"played {n} frames onto {args.interface} {args.channel}")
    return 0

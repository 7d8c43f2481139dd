"""`gearbox-vsensor demo`: the main job on an embedded default, end to end on python-can's virtual bus.

1. The reference plant runs the bundled synthetic uphill drive (the truth).
2. Its inputs become J1939 frames (EEC1, ETC2, TRF1, ET1, AMB, CCVS1, EC1 via TP.BAM) and its true component
   temperatures become rig thermocouple frames, as a real bus would carry them.
3. Those frames are played onto a python-can `virtual` bus; the onboard sensor's live CAN service (the same code
   as `gearbox-vsensor run`) decodes them, steps the sensor every 100 ms of frame time and publishes GBX_* frames.
4. A monitor on the same bus decodes the sensor's frames with the project's DBC and prints temperatures, warnings
   and time to limit; at the end the estimates are plotted against the plant's truth.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from tools.cli.gearbox_option import add_gearbox_option, gearbox_of, resolve_gearbox


def add_subparser(sub):
    p = sub.add_parser(
        "demo",
        help="run the main job on the bundled drive: plant -> J1939 frames -> sensor on a virtual bus",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--cycle", default="uphill", help="named cycle or CSV run table (default: uphill, synthetic)")
    p.add_argument(
        "--minutes", type=float, default=40.0, help="how much of the cycle to run, 1..600 minutes (default 40)"
    )
    p.add_argument(
        "--out-dir",
        default="demo_out",
        metavar="DIR",
        help="where to write the run tables (1 s rows), the CAN log and the plot (default: demo_out in "
        "the current directory; about 0.6 MB per minute of drive, 23 MB for the default 40)",
    )
    p.add_argument(
        "--print-every",
        type=float,
        default=300.0,
        metavar="S",
        help="print the sensor's outputs every this many seconds of drive time, (0, 36000] (default 300)",
    )
    add_gearbox_option(p)
    p.set_defaults(func=run)
    return p


def run(args) -> int:
    from firmware_model.errors import InputError
    from tools.demo import DemoOptions, run_demo

    if not 0 < args.print_every <= 36000:
        raise InputError(f"--print-every {args.print_every} must be within (0, 36000] s of drive time")
    gearbox = gearbox_of(resolve_gearbox(args))
    bus = run_demo(
        DemoOptions(
            cycle=args.cycle,
            minutes=args.minutes,
            out_dir=Path(args.out_dir),
            print_every_s=args.print_every,
            gearbox=gearbox,
        )
    )
    if bus.send_errors:
        print(f"note: {bus.send_errors} frames could not be sent", file=sys.stderr)
    return 0

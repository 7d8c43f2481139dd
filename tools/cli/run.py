"""`gearbox-vsensor run`: the onboard sensor live on a CAN bus (any python-can interface); tools/can/live.py."""

from __future__ import annotations

import logging
import sys

from firmware_model.errors import InputError
from tools.can.bus import add_bus_options, can_subcommand
from tools.cli.gearbox_option import add_gearbox_option, resolve_gearbox
from tools.cli.settings import add_hidden, given, setting


def add_subparser(sub):
    p = can_subcommand(
        sub,
        "run",
        summary="run the onboard sensor live on a CAN bus (J1939 in, GBX_* frames out)",
        description="Run the onboard virtual sensor on a CAN bus: decode the J1939 inputs (EEC1, EC1 by TP.BAM, "
        "ETC2, TRF1, ET1, AMB, CCVS1, ERC1; source addresses from --config [can]), step the sensor every "
        "100 ms of frame time (frame timestamps, never the wall clock) and send GBX_TEMP_1..7, GBX_WARN, "
        "GBX_TTL_1..7, GBX_STATUS every 100 ms and GBX_DM1 every second and on change. A signal that "
        "stops arriving for 3x its period is 'not available' to the sensor (degraded mode) until it "
        "returns. Counters of frames seen, used and rejected (by reason) are logged every "
        "[can] counter_log_period_s (60 s) of frame time. Stop with Ctrl-C or SIGTERM (exit 0).",
        examples=[
            "gearbox-vsensor run --interface socketcan --channel can0",
            "gearbox-vsensor run --interface socketcan --channel vcan0 --config truck.toml",
            "gearbox-vsensor run --interface pcan --channel PCAN_USBBUS1 --config truck.toml --duration 3600   "
            "# truck.toml: [bus] bitrate_bit_s = 250000",
        ],
        notes="\nconfig [can] keys: sensor_source_address, engine_source_address, transmission_source_address,\n"
        "retarder_source_address, ambient_source_address, vehicle_speed_source_address,\n"
        "coolant_source_address, the [can.source_address] table (one message's address alone:\n"
        "EEC1 EC1 ETC2 TRF1 ET1 AMB CCVS1 ERC1 RC, e.g. TRF1 = 0x21 where the oil comes from another node\n"
        "than the gear), engine_reference_torque_nm (used until EC1 "
        "arrives),\nretarder_reference_torque_nm (used until RC arrives), gear_map, output_period_s, "
        "stale_factor, "
        "counter_log_period_s.\nWatch the outputs: python -m cantools monitor -c vcan0 "
        "can_dbc/gearbox_vsensor.dbc",
    )
    add_bus_options(p, bitrate=False)
    p.add_argument(
        "--config",
        metavar="TOML",
        help="project configuration: gearbox variant, [can], [sensor], [bus] (bitrate_bit_s, receive_filters, "
        "receive_rig: the rig thermocouple frames) and [gateway] (log_level INFO, rt_priority: SCHED_FIFO 1..99, "
        "state_period_s 60): docs/interfaces.md section 8",
    )
    p.add_argument("--duration", type=float, metavar="S", help="stop after this many seconds of wall time")
    p.add_argument(
        "--state-file",
        metavar="PATH",
        help="keep the sensor state across restarts and ignition cycles: saved every [gateway] state_period_s "
        "(60 s) and on shutdown (atomically), restored at start cooled for the time off and "
        "reconciled with the first oil reading; missing, corrupt or another gearbox's: cold start, "
        "logged (docs/gateway.md)",
    )
    p.add_argument(
        "--health-file",
        metavar="PATH",
        help="rewrite a health file every second for `gearbox-vsensor status` (uptime, last step, "
        "degraded state, counters, age of the last state save)",
    )
    for key in RUN_KEYS:  # moved to the configuration, still accepted (hidden) and overriding it
        add_hidden(p, key)
    add_gearbox_option(p)
    p.set_defaults(func=run)
    return p


#: the settings of `run` in the configuration (firmware_model.config.SETTINGS)
RUN_KEYS = (
    "bus.bitrate_bit_s",
    "bus.receive_filters",
    "bus.receive_rig",
    "gateway.log_level",
    "gateway.rt_priority",
    "gateway.state_period_s",
)


def run(args) -> int:
    from firmware_model.config import load_config
    from tools.can.live import LiveSettings, run_live

    if given(args, ("gateway.state_period_s",)) and not args.state_file:
        raise InputError("--state-period sets how often --state-file is saved; give --state-file too")
    cfg = resolve_gearbox(args, load_config(args.config))
    s = {key: setting(args, cfg, key) for key in RUN_KEYS}
    settings = LiveSettings(
        interface=args.interface,
        channel=args.channel,
        bitrate_bit_s=s["bus.bitrate_bit_s"],
        config_path=cfg,
        duration_s=args.duration,
        filters=s["bus.receive_filters"],
        rig=s["bus.receive_rig"],
        rt_priority=s["gateway.rt_priority"],
        state_file=args.state_file,
        state_period_s=s["gateway.state_period_s"],
        health_file=args.health_file,
    )
    settings.check()
    from tools.can.bus import virtual_note

    note = virtual_note(args.interface, receiver=True)
    if note:
        print(f"gearbox-vsensor run: note: {note}", file=sys.stderr, flush=True)
    logging.basicConfig(
        level=getattr(logging, s["gateway.log_level"]),
        stream=sys.stderr,
        format="%(asctime)s %(levelname)s %(name)s: %(message)s",
    )
    run_live(settings)
    return 0

"""The CAN edge of the gearbox virtual sensor, in one import: J1939 inputs in, the sensor's own frames out.

``can_dbc`` is the one package that knows frame layouts. It reads them from ``gearbox_vsensor.dbc`` and stands on
its own (python-can, cantools and the standard library; nothing of the sensor). Its modules:

- ``can_dbc.j1939``: J1939 identifier arithmetic, value ranges, transport-protocol, EC1 and RC constants;
- ``can_dbc.dbc``: the DBC, loaded once, and the layouts, PGNs, source addresses and component ids read from it;
  :func:`load_dbc` another gearbox's;
- ``can_dbc.generate``: :func:`generate_dbc`, a gearbox's DBC from its published components (``export-dbc``);
- ``can_dbc.decoder``: :class:`J1939Decoder` (frames -> :class:`SignalUpdate`, every frame counted once);
- ``can_dbc.encoder``: :class:`OutputEncoder` (the GBX_* frames), :class:`RigEncoder` / :func:`encode_rig`;
- ``can_dbc.readback``: :func:`decode_outputs`, :func:`decode_rig`, the encoders' inverse through cantools;
- ``can_dbc.errors``: DecodeError, EncodeError, ConfigError (``ValueError``s).

See docs/can.md.
"""

from __future__ import annotations

from can_dbc.dbc import (
    DBC_NAME,
    CanDatabase,
    ComponentSignal,
    SignalLayout,
    default_source,
    fill_mask,
    load_database,
    load_dbc,
    message_id,
    message_pgn,
    numbered_messages,
    published_components,
)
from can_dbc.decoder import (
    DEFAULT_LIMITS,
    INPUT_SPNS,
    REJECT_REASONS,
    SIGNAL_NAMES,
    J1939Decoder,
    LatestValues,
    SignalUpdate,
    message_names,
    signal_messages,
)
from can_dbc.encoder import STATUS_KEYS, OutputEncoder, RigEncoder, encode_rig
from can_dbc.errors import CanDbcError, ConfigError, DecodeError, EncodeError
from can_dbc.generate import MAX_COMPONENTS, GenerateError, frame_layout, generate_dbc
from can_dbc.j1939 import (
    EC1_PGN,
    GLOBAL_ADDRESS,
    RC_PGN,
    can_id_of,
    destination_address,
    pgn_of,
    priority,
    receive_filter,
    source_address,
    with_source,
)
from can_dbc.readback import decode_outputs, decode_rig

__all__ = [
    "DBC_NAME",
    "CanDatabase",
    "ComponentSignal",
    "SignalLayout",
    "default_source",
    "fill_mask",
    "load_database",
    "load_dbc",
    "message_id",
    "message_pgn",
    "numbered_messages",
    "published_components",
    "DEFAULT_LIMITS",
    "INPUT_SPNS",
    "REJECT_REASONS",
    "SIGNAL_NAMES",
    "J1939Decoder",
    "LatestValues",
    "SignalUpdate",
    "message_names",
    "signal_messages",
    "STATUS_KEYS",
    "OutputEncoder",
    "RigEncoder",
    "encode_rig",
    "MAX_COMPONENTS",
    "GenerateError",
    "frame_layout",
    "generate_dbc",
    "CanDbcError",
    "ConfigError",
    "DecodeError",
    "EncodeError",
    "EC1_PGN",
    "GLOBAL_ADDRESS",
    "RC_PGN",
    "can_id_of",
    "destination_address",
    "pgn_of",
    "priority",
    "receive_filter",
    "source_address",
    "with_source",
    "decode_outputs",
    "decode_rig",
]

"""J1939 network management of the sensor node (SAE J1939-81 address claim, J1939-21 requests), done in the service.

Why not python-can-j1939 or the kernel's CAN_J1939 sockets: the service owns time and is pure of I/O (frames in,
frames out, frame time; the replay and the live run share it), and either would take the socket and the timing
from it; what the sensor needs is small and written here against the standard:

* at start-up it sends Address Claimed (PGN 60928, its 64-bit NAME, little-endian) from its address and keeps its
  periodic frames back for 250 ms of frame time (the contention window);
* a Request (PGN 59904) for Address Claimed, DM1 (65226) or the software identification (65242), to its address or
  global, is answered; a request to its address for another PGN gets a NACK (Acknowledgement, PGN 59392);
* another node claiming the same address: the lower NAME wins. Losing, an arbitrary-address-capable node claims the
  next free address in 128..247; otherwise it sends Cannot Claim Address (Address Claimed from the null address
  254) and stops transmitting (counted, logged); winning, it claims again.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import can

from can_dbc.j1939 import GLOBAL_ADDRESS, NULL_ADDRESS, can_id_of, destination_address, pgn_of, source_address

PGN_REQUEST = 0xEA00
PGN_ADDRESS_CLAIMED = 0xEE00
PGN_ACKNOWLEDGEMENT = 0xE800
PGN_DM1 = 0xFECA
PGN_SOFTWARE_ID = 0xFEDA
#: J1939-81: after claiming, a node waits this long before its other messages [s]
CONTENTION_S = 0.25
#: the self-configurable address range an arbitrary-address-capable node picks from
ARBITRARY_RANGE = range(128, 248)
#: the software identification this node reports (fields end with '*')
SOFTWARE_ID = b"gvs 0.1*"


@dataclass(frozen=True)
class J1939Name:
    """The 64-bit NAME (J1939-81): the defaults are placeholders that an integrator sets per vehicle (config [can]
    name_identity_number, name_manufacturer_code, ...; assumed values, not registered codes)."""

    identity_number: int = 0x0E5  # 21 bits
    manufacturer_code: int = 0x7FF  # 11 bits
    ecu_instance: int = 0  # 3 bits
    function_instance: int = 0  # 5 bits
    function: int = 0x81  # 8 bits
    vehicle_system: int = 0  # 7 bits
    vehicle_system_instance: int = 0  # 4 bits
    industry_group: int = 1  # 3 bits: on-highway
    arbitrary_address_capable: bool = False

    def value(self) -> int:
        return (
            self.identity_number & 0x1FFFFF
            | (self.manufacturer_code & 0x7FF) << 21
            | (self.ecu_instance & 0x7) << 32
            | (self.function_instance & 0x1F) << 35
            | (self.function & 0xFF) << 40
            | (self.vehicle_system & 0x7F) << 49
            | (self.vehicle_system_instance & 0xF) << 56
            | (self.industry_group & 0x7) << 60
            | int(bool(self.arbitrary_address_capable)) << 63
        )


def _frame(pgn: int, sa: int, data: bytes, t: float, prio: int = 6, dest: int = GLOBAL_ADDRESS) -> can.Message:
    return can.Message(timestamp=t, arbitration_id=can_id_of(pgn, sa, prio, dest), is_extended_id=True, data=data)


class AddressClaim:
    """The node's address state: ``address`` (None when it could not claim one), ``can_transmit(t)``."""

    def __init__(self, name: J1939Name, address: int, log: logging.Logger | None = None):
        self.name = name
        self.name_value = name.value()
        self.address: int | None = address
        self.log = log or logging.getLogger("gearbox_vsensor.j1939")
        self.claimed_at_s: float | None = None
        self.seen: dict[int, int] = {}  # address -> NAME of other claimants
        self.counters = {
            "claims_sent": 0,
            "requests_answered": 0,
            "nacks_sent": 0,
            "contentions_won": 0,
            "contentions_lost": 0,
        }

    def _claim(self, t: float) -> list:
        self.claimed_at_s = t
        self.counters["claims_sent"] += 1
        sa = NULL_ADDRESS if self.address is None else self.address
        return [_frame(PGN_ADDRESS_CLAIMED, sa, self.name_value.to_bytes(8, "little"), t)]

    def start(self, t: float) -> list:
        """The claim at start-up (frame time ``t``)."""
        return self._claim(t)

    def can_transmit(self, t: float) -> bool:
        return (
            self.address is not None and self.claimed_at_s is not None and t >= self.claimed_at_s + CONTENTION_S - 1e-9
        )

    def on_frame(self, msg, dm1_frame=None) -> list:
        """Replies to a received frame (network management only; other frames: nothing). ``dm1_frame``: a callable
        returning the current DM1 frame (or None)."""
        if not msg.is_extended_id or msg.is_remote_frame or len(msg.data) < 3:
            return []
        pgn = pgn_of(msg.arbitration_id)
        if pgn == PGN_ADDRESS_CLAIMED and len(msg.data) >= 8:
            return self._contention(
                source_address(msg.arbitration_id), int.from_bytes(bytes(msg.data[:8]), "little"), msg.timestamp
            )
        if pgn == PGN_REQUEST:
            dest = destination_address(msg.arbitration_id)
            if dest == GLOBAL_ADDRESS or (self.address is not None and dest == self.address):
                return self._request(
                    int.from_bytes(bytes(msg.data[:3]), "little"),
                    dest,
                    source_address(msg.arbitration_id),
                    msg.timestamp,
                    dm1_frame,
                )
        return []

    def _request(self, requested: int, dest: int, requester: int, t: float, dm1_frame) -> list:
        if requested == PGN_ADDRESS_CLAIMED:
            self.counters["requests_answered"] += 1
            return (
                self._claim(t)
                if self.address is not None
                else [_frame(PGN_ADDRESS_CLAIMED, NULL_ADDRESS, self.name_value.to_bytes(8, "little"), t)]
            )
        if self.address is None:
            return []
        if requested == PGN_SOFTWARE_ID:
            self.counters["requests_answered"] += 1
            return [_frame(PGN_SOFTWARE_ID, self.address, SOFTWARE_ID, t)]
        if requested == PGN_DM1 and dm1_frame is not None:
            frame = dm1_frame()
            if frame is not None:
                self.counters["requests_answered"] += 1
                return [
                    can.Message(timestamp=t, arbitration_id=frame.arbitration_id, is_extended_id=True, data=frame.data)
                ]
        if dest == self.address:  # to us, for a PGN we do not send: NACK (control byte 1)
            self.counters["nacks_sent"] += 1
            data = bytes([1, 0xFF, 0xFF, 0xFF, requester]) + requested.to_bytes(3, "little")
            return [_frame(PGN_ACKNOWLEDGEMENT, self.address, data, t, dest=GLOBAL_ADDRESS)]
        return []

    def _contention(self, sa: int, other: int, t: float) -> list:
        if other == self.name_value:
            return []  # our own claim echoed back
        self.seen[sa] = other
        if self.address is None or sa != self.address:
            return []
        if self.name_value < other:  # we win: defend the address
            self.counters["contentions_won"] += 1
            return self._claim(t)
        self.counters["contentions_lost"] += 1
        lost = self.address
        if self.name.arbitrary_address_capable:
            free = [a for a in ARBITRARY_RANGE if a not in self.seen and a != lost]
            if free:
                self.address = free[0]
                self.log.warning(
                    "J1939 address 0x%02X lost to a higher-priority NAME; claiming 0x%02X", lost, self.address
                )
                return self._claim(t)
        self.address = None
        self.log.error(
            "J1939 address 0x%02X lost to a higher-priority NAME and no other address can be claimed: "
            "the sensor stops transmitting (Cannot Claim Address sent)",
            lost,
        )
        return self._claim(t)

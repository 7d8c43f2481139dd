"""The errors of the CAN edge. One sentence each, naming the field and the rule that was broken.

``can_dbc`` stands on its own (python-can, cantools and the standard library): it does not import the sensor's
packages, so it has its own error types. They are ``ValueError``s; the CAN service (``firmware_model.service``)
turns a :class:`ConfigError` from its configuration into the project's ``ParameterError``.
"""

from __future__ import annotations


class CanDbcError(ValueError):
    """Base class of every error ``can_dbc`` raises on purpose."""


class DecodeError(CanDbcError):
    """A J1939 identifier, a DBC signal or a frame cannot be decoded."""


class EncodeError(CanDbcError):
    """A value handed to an encoder cannot be put into a frame (wrong type, unknown key, out of its set)."""


class ConfigError(CanDbcError):
    """A decoder or encoder setting (source address, limits, reference torque) is outside its allowed range."""

"""Typed errors. Messages are one sentence naming the field and the rule that was broken."""


class VSensorError(Exception):
    """Base class of every error this project raises on purpose."""


class ParameterError(VSensorError, ValueError):
    """A parameter file or value is missing, has the wrong unit or is out of its allowed range."""


class InputError(VSensorError, ValueError):
    """An input (run table, drive cycle, CLI option, log) is malformed or physically impossible."""


class DecodeError(VSensorError, ValueError):
    """A CAN frame or DBC signal cannot be decoded."""


class StabilityError(ParameterError):
    """A parameter set would make the fixed-step explicit network unstable."""

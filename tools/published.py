"""The published components the offline tools show, from the gearbox in hand, never from the GRS905's constants.

A gearbox's published components (their ids in CAN and column order, each one's limit group) are the ``published``
of its description (docs/description.md, firmware_model.description). The tools take them from what they are
given: a parameter set (its description), a description, a sensor or its parameters (the ids the sensor publishes
when it says, else its parameter set's description), or the published entries themselves; None stands for the
default gearbox (the CLI's ``--gearbox`` default), for a caller that was given no gearbox.

    >>> from firmware_model.description import load_description
    >>> d = load_description("GRS905")
    >>> ids(d)[:3], groups(d)["PS"], label_of("PS", d)
    (('LI.teeth', '3M.teeth', '2M.teeth'), 'sun', 'PS (sun wheel)')
"""

from __future__ import annotations

from functools import lru_cache

from firmware_model.components import WHEEL_PARTS, meaning
from firmware_model.description import Description, description_of, load_description
from firmware_model.parameters import Parameters


def description(source=None) -> Description | None:
    """The description of ``source``: a Description, a parameter set's, a sensor's (its ``params``), the default
    gearbox's for None; None for a list of published entries."""
    if source is None:
        return _default()
    if isinstance(source, Description):
        return source
    if isinstance(source, Parameters):
        return description_of(source)
    params = getattr(source, "params", None)
    if isinstance(params, Parameters):
        return description_of(params)
    return None


@lru_cache(maxsize=1)
def _default() -> Description:
    return load_description()


def published(source=None) -> tuple:
    """The published entries (``id``, ``group``, limits; firmware_model.description.Published) of ``source``, in
    their CAN and column order."""
    d = description(source)
    if d is None:
        out = tuple(source) if isinstance(source, (tuple, list)) else ()
        if not out or not all(hasattr(c, "id") and hasattr(c, "group") for c in out):
            raise TypeError(f"{source!r} is no parameter set, description, sensor or list of published components")
        return out
    pub = getattr(source, "published", None)  # a sensor that says what it publishes
    if pub is not None and not isinstance(source, Description) and all(isinstance(c, str) for c in pub):
        by_id = {c.id: c for c in d.published}
        return tuple(by_id[c] for c in pub)
    return d.published


def ids(source=None) -> tuple:
    """The published component ids of ``source`` (:func:`published`), in order."""
    return tuple(c.id for c in published(source))


def groups(source=None) -> dict:
    """Each published component's limit group (``gear``, ``sun``, ``planetary``, ``bearing``, ``oil``)."""
    return {c.id: c.group for c in published(source)}


def limits(source=None):
    """The warning limits (firmware_model.onboard.warning_levels.Limits) of ``source``: a sensor's own (its
    configuration may name another file), else the limits file its description's published.limits names, for the
    components the sensor holds; the default gearbox's for None. Plots draw these, never the GRS905's file for
    another gearbox (whose components that file does not list)."""
    from firmware_model.onboard.reduce import published_components
    from firmware_model.onboard.warning_levels import Limits, load_limits

    own = getattr(source, "limits", None)
    if isinstance(own, Limits):
        return own
    d = description(source)
    if d is None:
        raise TypeError(f"{source!r} is no parameter set, description or sensor: it names no limits file")
    return load_limits(d.limits_path, published=published_components(d))


def housings(source=None) -> tuple:
    """The housing ids of ``source``'s description, in its order (the nodes a housing start offset moves)."""
    d = description(source)
    return tuple(h.id for h in d.housings) if d is not None else ()


def words(component_id: str, desc: Description | None = None) -> str | None:
    """What a component is, in a few words: the description's name of the part (an idle wheel's teeth or hub named
    after its wheel), or, without a description, the GRS905 code's meaning (firmware_model.components); None when
    neither says."""
    if desc is None:
        return meaning(component_id)
    names = desc.names
    if names.get(component_id):
        return names[component_id]
    part, _, piece = component_id.partition(".")
    if piece in WHEEL_PARTS and names.get(part):
        return f"{WHEEL_PARTS[piece]} of the {names[part]}"
    return None


def label_of(component_id: str, desc: Description | None = None) -> str:
    """A code with its words, for legends and printed output: ``"PS (sun wheel)"``; a code without words as it is."""
    w = words(component_id, desc)
    return f"{component_id} ({w})" if w else component_id

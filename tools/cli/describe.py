"""`gearbox-vsensor describe`: check a gearbox description and print its summary (firmware_model.description)."""

from __future__ import annotations

import argparse
import math
import sys


def add_subparser(sub):
    p = sub.add_parser(
        "describe",
        help="check a gearbox description and print its shafts, wheels, meshes, gears, bearings, housings, oil "
        "system and published components",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Check a gearbox description (the [topology] of a parameter file, docs/description.md) and "
        "print its summary: shafts and segments, wheels, meshes, gears with their power paths and ratios "
        "(from the teeth and as stated), bearings, housings, the oil system, the boundaries and the "
        "published components with their warning limits. A description that does not hold together is "
        "one sentence naming the file, the key and why (exit 2).",
        epilog="examples:\n  gearbox-vsensor describe\n  gearbox-vsensor describe --gearbox my_gearbox.toml",
    )
    p.add_argument(
        "--gearbox",
        default="GRS905",
        metavar="NAME|FILE",
        help="a description shipped in firmware_model/params/ (GRS905, GRSO905, HR225, MM82, R1) or the path of a "
        ".toml file (default: GRS905)",
    )
    p.set_defaults(func=run)


def _mm(x_m) -> str:
    return "-" if x_m is None else f"{x_m * 1e3:g} mm"


def _c(t_c) -> str:
    return "-" if t_c is None else f"{t_c:g}"


def summary(d) -> list[str]:
    """The description as text lines, section by section."""
    out = [f"gearbox {d.name} ({d.origin}): {d.drive.kind} drive, {d.drive.input_shaft} -> {d.drive.output_shaft}"]
    out.append(f"shafts ({len(d.shafts)}):")
    for s in d.shafts:
        segs = ", ".join(f"{g.id} {g.x_m * 1e3:g}" for g in s.segments)
        out.append(f"  {s.id} {s.name}: d {_mm(s.d_out_m)}, bore {_mm(s.d_bore_m)}; segments at x [mm]: {segs}")
    out.append(f"wheels ({len(d.wheels)}):")
    for w in d.wheels:
        on = "on a pin" if w.shaft is None else f"{w.mount} on {w.shaft} ({w.segment})"
        out.append(
            f"  {w.id}{f' ({w.name})' if w.name else ''}: {on}, z {w.teeth}, module {_mm(w.module_m)}, helix "
            f"{math.degrees(w.helix_rad):g} deg, width {_mm(w.width_m)}"
        )
    for ps in d.planetary:
        out.append(
            f"planetary set {ps.id}: sun {ps.sun} (z {ps.z_sun}, on {ps.sun_shaft}), {ps.n_planets} planets "
            f"{ps.planet} (z {ps.z_planet}), ring {ps.ring} (z {ps.z_ring}), carrier on {ps.carrier_shaft}"
        )
    out.append(f"meshes ({len(d.meshes)}):")
    for m in d.meshes:
        kind = "internal" if m.internal else "external"
        out.append(
            f"  {m.id}: {m.wheels[0]}-{m.wheels[1]} {kind}, centre distance {m.centre_distance_m * 1e3:.4g} mm "
            f"(standard {m.standard_m * 1e3:.4g} mm)"
        )
    out.append("couplings: " + (", ".join(f"{c.id} ({c.kind})" for c in d.couplings) or "none (a fixed ratio)"))
    neutral = " and neutral" if any(g.number == 0 for g in d.gears) else ""
    out.append(f"gears ({sum(g.number != 0 for g in d.gears)}{neutral}):" if d.gears else "gears: none")
    for g in d.gears:
        ratio = "neutral" if g.number == 0 else f"ratio {g.ratio:.6g} (stated {g.stated_ratio:g})"
        out.append(f"  {g.number:>3} {g.name}: {ratio}; path {' '.join(g.path)}")
    return out + _summary_rest(d)


def _summary_rest(d) -> list[str]:
    out = [f"bearings ({len(d.bearings)}):"]
    for b in d.bearings:
        seat = f"under {b.wheel}" if b.wheel else (f"in {b.housing}" if b.housing else f"inside {b.inside}")
        size = f"{_mm(b.bore_m)} x {_mm(b.outer_m)} x {_mm(b.width_m)}" if b.bore_m else f"width {_mm(b.width_m)}"
        named = f"{b.id} ({b.name})" if b.name else b.id
        out.append(f"  {named}: {b.kind} on {b.shaft} ({b.segment}), {seat}; {size}")
    out.append(f"housings ({len(d.housings)}):")
    for h in d.housings:
        out.append(
            f"  {h.id} {h.name}: {h.material}, {h.mass_kg:g} kg, {h.area_m2:g} m2, {h.internal_split:.0%} of the "
            f"inside{f', bolted to {h.joined_to}' if h.joined_to else ''}; faces {', '.join(h.faces)}"
        )
    o = d.oil
    pump = f"pump on {o.pump_shaft}" if o.pump_shaft else ("pump" if o.pump_flow else "no pump")
    thermo = (
        f", thermostatic bypass opens at {o.thermostat_open_c:g} degC (full {o.thermostat_full_c:g} degC)"
        if o.thermostat_open_c is not None
        else ""
    )
    heater = ", no heater"
    if o.heater_w:
        full_c = o.heater_set_c - o.heater_band_k
        heater = f", heater {o.heater_w:g} W below {o.heater_set_c:g} degC (all of it below {full_c:g})"
    out.append(
        f"oil system: {o.lubrication} lubrication, {o.volume_m3 * 1e3:g} L, {pump} reaching {len(o.jets)} parts, "
        f"filter {o.filter}; cooler {o.cooler}{thermo}{heater}"
    )
    out.append(f"  dipping into the sump: {', '.join(o.dipping) or 'nothing'}")
    out.append(f"  splashed: {', '.join(o.splashed) or 'nothing'}")
    out.append(f"boundaries ({len(d.boundaries)}, default temperature; what touches each):")
    for b in d.boundaries:
        g = f" through {b.conductance_w_per_k:g} W/K each" if b.conductance_w_per_k else ""
        out.append(f"  {b.id} {b.temperature_c:g} degC; touches {', '.join(b.touches) or 'nothing directly'}{g}")
    out.append(f"published ({len(d.published)}, warning/critical degC):")
    for i in range(0, len(d.published), 7):
        out.append("  " + ", ".join(f"{c.id} {_c(c.warning_c)}/{_c(c.critical_c)}" for c in d.published[i : i + 7]))
    derived = [c.id for c in d.published if c.id in d.derived]
    if derived:  # (firmware_model.onboard.reduce.published_components: no node of the onboard network)
        out.append(
            f"  {', '.join(derived)}: derived (the reference plant's); the onboard sensor and its CAN frames publish "
            f"the other {len(d.published) - len(derived)}"
        )
    return out


#: how many missing parameters describe looks for before it stops (each one found costs a model build)
MISSING_MAX = 40


#: the shipped descriptions whose physics keys stand in for a user's missing ones while describe looks for more
KEY_DONORS = ("GRS905", "MM82")


def missing_physics(params) -> tuple[list[str], str | None]:
    """(the physics parameters the reference plant and the onboard sensor read that ``params`` lacks, all of them
    (simulate and replay name one per run), another problem building or running them (a mesh whose teeth
    interfere) or None): the plant and the sensor are built, and a short drive run in each gear, with each missing
    key borrowed from the GRS905, else the MM82 (the cylindrical and spherical bearings' keys), until none is
    missing (a key neither has ends the search: it is named)."""
    import dataclasses
    import re

    from firmware_model.errors import InputError, ParameterError
    from firmware_model.parameters import load_parameters

    donors = [load_parameters(name) for name in KEY_DONORS]
    missing: list[str] = []
    p = params
    while len(missing) < MISSING_MAX:
        try:
            _exercise(p)
            return missing, None
        except (ParameterError, InputError) as exc:
            m = re.match(r"parameter '([^']+)' is missing from parameter set", str(exc))
            if m is None:
                return missing, str(exc)  # what simulate and replay would refuse the file for
            key = m.group(1)
            ref = next((d for d in donors if key in d.values), None)
            if ref is None or key in missing:
                return missing + [key] * (key not in missing), None
            missing.append(key)
            p = dataclasses.replace(
                p,
                values={**p.values, key: ref.values[key]},
                units={**p.units, key: ref.units[key]},
                sources={**p.sources, key: "assumed"},
            )
    return missing, None


def _exercise(p) -> None:
    """Build the reference plant and the onboard sensor of ``p`` and run the plant two seconds in each gear."""
    import numpy as np

    from firmware_model.description import description_of
    from firmware_model.onboard.sensor import VirtualSensor
    from tools.plant.reference import ReferencePlant
    from tools.runtable import RunTable

    d = description_of(p)
    gears = [g.number for g in d.gears if g.number != 0] or [0]
    t = np.arange(0.0, 2.0 * len(gears) + 1.0)
    gear = np.repeat(np.asarray(gears + [gears[-1]], dtype=float), 2)[: t.size]
    rpm = min(1000.0, 0.5 * d.drive.max_speed_rad_s * 30.0 / np.pi)
    nm = 0.3 * d.drive.max_torque_nm
    table = RunTable(
        {
            "time_s": t,
            "engine_speed_rpm": np.full(t.size, rpm),
            "engine_torque_nm": np.full(t.size, nm),
            "gear": gear,
            "ambient_temp_c": np.full(t.size, 20.0),
        }
    )
    ReferencePlant(p).run(table, out_dt_s=1.0, progress=False)
    VirtualSensor(p)


def oil_line(params) -> str:
    """The oil the plant and the sensor take: its [oil] grade or the seed's, with its viscosity and density."""
    from firmware_model.physics.oil import COLDEST_USE_MU_PA_S, T_MIN_C, oil_of

    oil = oil_of(params)
    nu = [float(oil.kinematic_viscosity_m2_s(t)) * 1e6 for t in (40.0, 60.0, 100.0)]
    line = (
        f"  oil: {oil.name}: {nu[0]:.4g} / {nu[1]:.3g} / {nu[2]:.3g} mm2/s at 40 / 60 / 100 degC, "
        f"{float(oil.density_kg_m3(40.0)):.0f} kg/m3 at 40 degC"
    )
    cold_c = oil.temperature_at_mu_c(COLDEST_USE_MU_PA_S)
    if cold_c > T_MIN_C:  # an oil that reaches it within the model's range: say where the model stops being one
        line += (
            f"; below {cold_c:.0f} degC thicker than {COLDEST_USE_MU_PA_S:g} Pa s (SAE J306's coldest use of a gear "
            'oil): a start there is outside the loss model (docs/physics.md, "Oil properties")'
        )
    return line


def run(args) -> int:
    from pathlib import Path

    from firmware_model.description import default_limits_note, description_of, limit_notes, load_description
    from firmware_model.errors import ParameterError
    from firmware_model.parameters import load_parameters

    load_description(args.gearbox)  # the description's own sentences first (a missing [topology], a bad key)
    # then its parameter values, as every other command loads them (a cp of 0, a value outside its bounds, a unit
    # typo: one sentence here too)
    params = load_parameters(args.gearbox)
    d = description_of(params)
    missing, problem = missing_physics(params)
    name = Path(params.path).name if params.path else params.variant
    if missing:
        ref = load_parameters("GRS905")
        own = [k for k in missing if k not in ref.values]
        raise ParameterError(
            f"{name}: simulate and replay need physics parameters the file lacks: {', '.join(missing)} (the "
            "GRS905's, with their notes and provenance, are in firmware_model/params/GRS905.toml: copy them with "
            "values for this gearbox"
            + (
                f"; {', '.join(own)}: the GRS905 has none, the MM82 has a cylindrical and a spherical bearing's in "
                "firmware_model/params/MM82.toml, and docs/description.md says where such values come from"
                if own
                else ""
            )
            + ")"
        )
    if problem:
        raise ParameterError(f"{name}: simulate and replay cannot build this gearbox: {problem}")
    lines = summary(d)
    at = next((i + 1 for i, x in enumerate(lines) if x.startswith("  splashed:")), len(lines))
    print("\n".join(lines[:at] + [oil_line(params)] + lines[at:]))
    default = default_limits_note(d)  # the truck's limits taken in silence: a note, the run may still be meant
    for note in ((default,) if default else ()) + limit_notes(d):  # plausible but suspect: on stderr, as the others
        print(f"note: {note}", file=sys.stderr)
    return 0

"""The onboard model: the full thermal network and loss model, rebuilt as cheap, fixed-size tables for a 10 Hz
explicit step, with a stability guarantee checked when the parameters load.

Everything here is derived by code from the same description the reference plant integrates
(:func:`firmware_model.network.build_network`, :class:`~firmware_model.network.ConductanceEvaluator`,
:class:`~firmware_model.physics.gearbox_losses.GearboxLosses`): no number is copied by hand. The cooler
(:func:`firmware_model.onboard.evaluate.cooler_heat` over :func:`firmware_model.physics.cooler.oil_cooler_heat`),
the heat lag (:mod:`firmware_model.physics.heat_lag`, coefficients in ``rp.helpers.heat_lag``) and the conductance
matrix (:func:`firmware_model.physics.conductance_matrix.conductance_matrix` of ``rp.helpers.topology``) are the
plant's.

Reduction (docs/sensor.md, "Reduction")
---------------------------------------
* **Nodes by aggregation.** A *partition* maps every full node to a reduced node. A reduced node's heat capacity is
  the sum of its members'; a reduced link's conductance is the sum of the full links between two groups (links
  inside a group vanish); heat sources follow their node. ``PARTITIONS["fine"]`` (the default) keeps every node of
  the full network: an error-driven search (docs/sensor.md) showed that every merge of two nodes costs a published
  bearing more than the 0.3 K RMS budget on at least one cycle, because each bearing reads the temperature of the
  shaft segment and housing it sits in. ``PARTITIONS["compact"]`` (40 nodes: one node per shaft, one housing, the
  reverse idler in the sump) is the cheaper alternative for ECUs that can accept larger errors on bearings.
* **Conductance laws.** Every speed- or oil-temperature-dependent link is tabulated from the full evaluator on a
  grid of its own shaft speed x oil temperature and classified: *power law* ``a(gear) w^e phi(T_oil)`` when the
  table is separable to 1e-9 (splash Eq 59, Harris Eq 63, immersed bearings Eq 52: exact), else a bilinear table
  over ``(sqrt(w / w_max), T_oil)`` (immersed wheels with their laminar/turbulent bridge and fling-off, oil-system
  streams with their flow-limited effectiveness). Gear contacts (Eq 45) are a per-gear mask, the ring gear is a
  splash law at high range and a constant at low range, radiation (Eq 81) is evaluated from the housing
  temperature every step.
* **Loss maps.** Gear-contact slip (Eq 7-10) of a mesh is exactly ``T1 w2 phi(log10 T1 - log10 mu - 3 log10 w2)``
  (the Benedict-Kelley argument is load / (mu V_g V_r^2) and both speeds are proportional to w2), so each mesh needs
  one 1-D table; rolling (Eq 14-22) is exactly ``K mu^0.7 a_p^0.54 w2^1.7 T1^-0.13``; bearings (Eq 35-40),
  needle bearings, synchronizers (Eq 41) and the pump (Eq 42) are closed forms with per-gear coefficients; churning
  (Eq 23-34) is a table over layshaft speed x oil temperature. Oil properties are one row of a table over the oil
  temperature (5 K steps).

The run-time side of these tables (the record :class:`~firmware_model.onboard.evaluate.ReducedParams` and the
functions the step and the C kernel evaluate it with) is firmware_model.onboard.evaluate; the stability proof checked
here when the tables are built is firmware_model.onboard.stability.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from firmware_model.components import SHAFT_BEARINGS, STEP_S
from firmware_model.description import OIL_INLET, Description
from firmware_model.effects import CATALOG, FIELD_OF_EFFECT, EffectScales, effect_value, with_oil_volume
from firmware_model.errors import ParameterError
from firmware_model.network import (
    K_BRG_SPLASH,
    K_CONST,
    K_CONTACT,
    K_EXT_CONV,
    K_EXT_RAD,
    K_IMM_BRG,
    K_IMM_GEAR,
    K_RING,
    K_SPLASH,
    K_STREAM,
    MIN_SPEED_RAD_S,
    S_CHANNEL,
    S_IMPOSED,
    ConductanceEvaluator,
    Network,
    build_network,
)
from firmware_model.onboard.evaluate import (
    COOLER_CODES,
    N_U,
    N_U_CHURN,
    PUMP_CODES,
    T2_STRIDE,
    T_GRID_C,
    X_STEP,
    ReducedParams,
    speed_bin_min_rad_s,
)
from firmware_model.onboard.kernel_interface import (
    EFFECT_HOUSING_AIR_H,
    EFFECT_NONE,
    EFFECT_PLANET_OIL_H,
    EFFECT_TEETH_OIL_H,
    N_PROP,
    P_CP,
    P_K,
    P_LN_MU,
    P_LN_NU_CST,
    P_LN_PR,
    P_LN_ROLL,
    P_LOG10_MU,
    P_RHO,
)
from firmware_model.onboard.stability import HELD_STEP_CAP_S, STABILITY_MARGIN, check_stability
from firmware_model.parameters import Parameters
from firmware_model.physics import heat_transfer as ht
from firmware_model.physics import losses as L
from firmware_model.physics import oil as oilprops
from firmware_model.physics.cooler import (
    AIR_RECIRC_V_KMH,
    COOLER_KEYS,
    DEFAULT_VEHICLE_SPEED_KMH,
    cooler_values,
    heater_values,
)
from firmware_model.physics.drivetrain import kinematics_of, speed_names
from firmware_model.physics.gearbox_losses import ROLL_POINTS, GearboxLosses
from firmware_model.physics.kinematics import GEAR_MIN, MESHES, N_GEARS
from firmware_model.units import RAD_S_PER_RPM

#: fixed step of the onboard model [s] (firmware_model.components.STEP_S)
DT_S = STEP_S
#: engine-off relaxation of the boundary temperatures to ambient [s] when the parameter file has no
#: boundary.engine_off_tau (assumed: a heavy diesel's block and coolant, ~0.65 MJ/K, losing ~180 W/K at rest)
ENGINE_OFF_TAU_S = 3600.0
#: separability tolerance for power-law conductances (relative)
SEPARABLE_RTOL = 1e-7

#: effect ids the onboard model represents, each per vehicle (arrays) as well as scalar; oil_level_low changes the
#: geometry and is applied when the model is built (scalar only)
EFFECT_HOOKS = (
    "retarder_heat",
    "churning_scale",
    "gear_friction_scale",
    "planetary_loss_scale",
    "bearing_loss_scale",
    "teeth_oil_h_scale",
    "planet_oil_h_scale",
    "housing_air_h_scale",
    "cooler_effectiveness_scale",
    "thermostat_offset",
    "hot_surroundings_offset",
)
BUILD_EFFECTS = ("oil_level_low",)
#: the boundaries the step writes from its inputs (ambient, coolant) or an effect shifts (hot_surroundings)
STEP_BOUNDARIES = ("ambient", "coolant", "hot_surroundings")


def aux_inputs_expected(d: Description) -> tuple:
    """Whether the description's drive has each auxiliary input (ambient, coolant, vehicle speed, retarder torque:
    records.INPUT_FIELDS from I_AMB on). Every drive has an ambient; a coolant only with a coolant boundary or a
    liquid cooler (the MM82's air cooler, the HR225's none: no coolant); a vehicle speed and a retarder only a
    vehicle. An input the drive has not is not applicable: missing, it takes its default and is not counted
    (aux_missing would say an input fails at every step of a wind turbine)."""
    coolant = any(b.id == "coolant" for b in d.boundaries) or d.oil.cooler == "liquid"
    vehicle = d.drive.kind == "vehicle"
    return (True, coolant, vehicle, vehicle)


# ---------------------------------------------------------------------------------------------------------------
# partitions


def _compact_partition(d: Description) -> dict:
    """One node per shaft, one for the housings, the wheels on a pin (an idler) in the sump."""
    part = {g.id: sh.id for sh in d.shafts for g in sh.segments}
    part.update({h.id: "H" for h in d.housings})
    part.update({w.id: "oil" for w in d.wheels if w.mount == "pin"})
    return part


def _fine_partition(d: Description) -> dict:
    return {}


#: name -> the partition of a description ({full node: reduced node}; nodes not named keep their own name)
PARTITIONS = {"fine": _fine_partition, "compact": _compact_partition}

# loss sources of the onboard model (columns of the source matrix): every mesh, every shaft bearing, the oil-lumped
# sources and the retarder; the GRS905's (a model built from a description carries its own: ReducedParams.src_names)
SRC_NAMES = (
    tuple(f"mesh:{m}" for m in MESHES) + tuple(f"bearing:{b}" for b in SHAFT_BEARINGS) + ("oil_lumped", "retarder")
)
N_SRC = len(SRC_NAMES)
#: the GRS905's first bearing, its oil-lumped and its retarder source (a description's: ReducedParams.src_names)
I_SRC_BEARING = SRC_NAMES.index(f"bearing:{SHAFT_BEARINGS[0]}")
I_SRC_OIL = SRC_NAMES.index("oil_lumped")
I_SRC_RET = SRC_NAMES.index("retarder")


def planetary_meshes(d: Description) -> tuple:
    """The ids of the meshes inside a planetary set (their heat is the set's, their loss split over the planets)."""
    members = {m for ps in d.planetary for m in (ps.sun, ps.planet, ps.ring)}
    return tuple(m.id for m in d.meshes if set(m.wheels) & members)


def source_names(d: Description) -> tuple:
    """The loss sources of a description's onboard model, in the order of SRC_NAMES: its meshes, its shaft bearings
    (those under no idle wheel), the oil-lumped sources, the retarder."""
    return (
        tuple(f"mesh:{m.id}" for m in d.meshes)
        + tuple(f"bearing:{b.id}" for b in d.bearings if b.wheel is None)
        + ("oil_lumped", "retarder")
    )


def _ro(a, dtype=float) -> np.ndarray:
    a = np.array(a, dtype=dtype)
    a.setflags(write=False)
    return a


#: the effect values the onboard model applies at run time (the one effect record, firmware_model.effects); its
#: ``src_scale`` (..., N_SRC) multiplies each loss source's heat
Effects = EffectScales


def make_effects(effects: dict | None = None, rp=None) -> Effects:
    """Effects record from {effect id: value or array of per-vehicle values}; unknown or unsupported ids raise.
    Each value is a float or an array over vehicles (V,). ``rp``: the onboard model whose loss sources the scales
    follow (ReducedParams.src_names, .src_planetary); None: the GRS905's (SRC_NAMES)."""
    effects = dict(effects or {})
    for eid, v in effects.items():
        if eid not in CATALOG:
            raise ParameterError(f"unknown effect id {eid!r}")
        if eid not in EFFECT_HOOKS and eid not in BUILD_EFFECTS:
            raise ParameterError(
                f"effect {eid} is not represented by the onboard model (it represents "
                f"{', '.join(EFFECT_HOOKS + BUILD_EFFECTS)})"
            )
        a = np.asarray(v, dtype=float)
        e = CATALOG[eid]
        if np.any(~np.isfinite(a)) or np.any(a < e.low) or np.any(a > e.high):
            raise ParameterError(
                f"effect {eid}: {e.param} = {v} is outside its plausible range "
                f"{e.low:g}..{e.high:g}{'' if e.unit in ('', '-') else ' ' + e.unit}"
            )

    def val(eid):
        v = effects.get(eid, CATALOG[eid].neutral)
        a = np.asarray(v, dtype=float)
        return float(a) if a.ndim == 0 else a

    gf, pl, ch, br = (
        np.asarray(val(k), dtype=float)
        for k in ("gear_friction_scale", "planetary_loss_scale", "churning_scale", "bearing_loss_scale")
    )
    names = SRC_NAMES if rp is None else rp.src_names
    planetary = {f"mesh:{m}" for m in ("PSP", "PPR")} if rp is None else set(rp.src_planetary)
    shape = np.broadcast(gf, pl, ch, br).shape
    s = np.ones(shape + (len(names),))
    for j, nm in enumerate(names):
        if nm.startswith("mesh:"):
            s[..., j] = pl if nm in planetary else gf
        elif nm.startswith("bearing:"):
            s[..., j] = br
    # the lumped oil source carries its own scales (churning, needle bearings); the retarder its heat
    s.setflags(write=False)
    return Effects(src_scale=s, **{FIELD_OF_EFFECT[eid]: val(eid) for eid in EFFECT_HOOKS})


# ---------------------------------------------------------------------------------------------------------------
# aggregation


@dataclass(frozen=True)
class Aggregation:
    nodes: tuple
    members: tuple
    C: np.ndarray
    node_of_full: np.ndarray  # (n_full,) reduced node index
    link_of_full: np.ndarray  # (nl_full,) reduced link index or -1 (inside a group)
    link_a: np.ndarray
    link_b: np.ndarray
    link_name: tuple


def published_components(d: Description) -> tuple:
    """The published components the onboard model holds as nodes, in the description's published.order: a derived
    temperature (a forced oil system's inlet, Description.derived) is no node of the network and is left out."""
    return tuple(c for c in d.published if c.id not in d.derived)


def published_ids(d: Description) -> tuple:
    """The ids of published_components (CAN signal and column order)."""
    return tuple(c.id for c in published_components(d))


def speed_columns(d: Description) -> dict:
    """The speed_coef columns (drivetrain.speed_names) the step reads, from the description: the shaft that drives
    the oil pump (oil.pump_shaft), the one most of the dipping wheels turn with (churn_column: the GRS905's layshaft),
    the output shaft (drive.output_shaft, the retarder's). The tables allow -1 (no pump or a motor-driven one, no
    dipping wheel: it turns at 0)."""
    names = speed_names(d)

    def col(key: str, shaft: str | None) -> int:
        if shaft is None:
            return -1
        if shaft not in names:
            raise ParameterError(f"{d.origin}: {key} = {shaft!r} is no shaft of the kinematics ({', '.join(names)})")
        return names.index(shaft)

    return dict(
        pump_speed_col=col("topology.oil.pump_shaft", d.oil.pump_shaft),
        churn_speed_col=churn_column(d),
        output_speed_col=col("topology.drive.output_shaft", d.drive.output_shaft),
    )


def _wheel_column(d: Description, wheel: str) -> int:
    """The speed column a wheel turns with: its own (an idle wheel, an idler on a pin), else its shaft's."""
    names = speed_names(d)
    w = next(w for w in d.wheels if w.id == wheel)
    return names.index(w.id) if w.id in names else names.index(w.shaft)


def churn_column(d: Description) -> int:
    """The speed column the onboard churning table is tabulated on: the one most of the dipping wheels turn with
    (the GRS905's layshaft; the others scale from it, _churn_table); -1 when no wheel dips."""
    cols = [_wheel_column(d, w.id) for w in d.wheels if w.id in d.oil.dipping]
    return max(cols, key=cols.count) if cols else -1


def aggregate(net: Network, partition: dict) -> Aggregation:
    """Merge full nodes into groups: C summed, links between groups summed, links inside a group dropped."""
    for k in partition:
        if k not in net.nodes:
            raise ParameterError(f"partition names node {k!r}, which is not in the thermal network")
    names = []
    for nm in net.nodes:
        g = partition.get(nm, nm)
        if g not in names:
            names.append(g)
    for c in published_ids(net.geometry.description):
        if c not in names:
            raise ParameterError(f"the partition has no node named {c!r} (every published component must be one)")
    gi = {g: i for i, g in enumerate(names)}
    n_full, m = net.n, len(names)
    node_of = np.array([gi[partition.get(nm, nm)] for nm in net.nodes])
    C = np.bincount(node_of, net.C_j_per_k, minlength=m)
    members = tuple(tuple(nm for nm in net.nodes if partition.get(nm, nm) == g) for g in names)
    keys: dict = {}
    link_of = np.full(len(net.link_a), -1)
    for k, (a, b) in enumerate(zip(net.link_a, net.link_b)):
        ga = node_of[a]
        gb = node_of[b] if b < n_full else m + (b - n_full)
        if ga == gb:
            continue
        if gb < m and gb < ga:
            ga, gb = gb, ga
        kind_class = "rad" if net.link_kind[k] == K_EXT_RAD else "lin"
        key = (ga, gb, kind_class)
        if key not in keys:
            keys[key] = len(keys)
        link_of[k] = keys[key]
    la = np.array([k[0] for k in keys], dtype=np.int64)
    lb = np.array([k[1] for k in keys], dtype=np.int64)
    allnames = list(names) + list(onboard_boundaries(net))
    lname = tuple(f"{allnames[a]}-{allnames[b]}{':rad' if c == 'rad' else ''}" for a, b, c in keys)
    return Aggregation(tuple(names), members, C, node_of, link_of, la, lb, lname)


# ---------------------------------------------------------------------------------------------------------------
# build


def oil_property_table(T_c: np.ndarray, oil: oilprops.Oil = oilprops.SEED_OIL) -> np.ndarray:
    """The kernel's oil row at each temperature of ``T_c`` (evaluate.oil_row interpolates it): the properties of
    ``oil`` (the description's) its laws read."""
    op = oil.properties(T_c)
    prop = np.empty((T_c.size, N_PROP))
    prop[:, P_LOG10_MU] = np.log10(op.mu_pa_s)
    prop[:, P_LN_NU_CST] = np.log(op.nu_m2_s * 1e6)
    prop[:, P_LN_MU] = np.log(op.mu_pa_s)
    prop[:, P_LN_ROLL] = 0.7 * np.log(op.mu_pa_s) + 0.54 * np.log(op.piezo_per_pa)
    prop[:, P_RHO] = op.rho_kg_m3
    prop[:, P_CP] = op.cp_j_per_kgk
    prop[:, P_K] = op.k_w_per_mk
    prop[:, P_LN_PR] = np.log(op.pr)
    return prop


def _speed_of_link(net: Network, k: int) -> int:
    kind = int(net.link_kind[k])
    if kind == K_STREAM:  # the oil streams follow the pump's shaft; a motor pump's flow none (column 0, a flat table)
        shaft = net.geometry.description.oil.pump_shaft
        return 0 if shaft is None else net.speed_names.index(shaft)
    j = int(np.sum(net.link_kind[:k] == kind))
    return int(net.kind_params[kind]["speed"][j])


def _link_param(net: Network, k: int, key: str):
    kind = int(net.link_kind[k])
    j = int(np.sum(net.link_kind[:k] == kind))
    return net.kind_params[kind][key][j]


class PowerTerm(NamedTuple):
    """G = gear_coef[gear] w_in^exp (phi[T_oil, col] or 1) x effect scale."""

    link: int
    exp: float
    gear_coef: np.ndarray  # (17,)
    col: int  # column of the phi table, -1 for none
    effect: int  # EFFECT_* (kernel_interface)


class TableTerm(NamedTuple):
    """G = table(sqrt(omega / omega_max), T_oil), omega = speed_coef[gear] omega_in."""

    link: int
    speed_coef: np.ndarray  # (17,)
    omega_max_rad_s: float
    table: np.ndarray  # (N_U, nT2) W/K
    stream: bool  # an oil-system stream (the cooler's inlet drop applies)
    frac: float  # its share of the oil flow
    effect: int


class StreamTerm(NamedTuple):
    """Closed-form stream G = m (1 - exp(-hA / m)), m = flow_m3_per_rad rho cp |w_LS|, hA = alpha k_oil + beta."""

    link: int
    flow_m3_per_rad: float
    alpha_m: float
    beta_w_per_k: float
    effect: int


class CylinderTerm(NamedTuple):
    """Immersed wheel, Nusselt part: G = c k_oil Nu(Re, Pr), Re = R_p^2 w / nu, w = speed_coef[gear] w_in."""

    link: int
    speed_coef: np.ndarray  # (17,)
    c_m: float  # area / R_p
    ln_rp2: float  # ln(R_p^2 [m2])


class LawGrid(NamedTuple):
    """Every link tabulated from the full evaluator at its own shaft speed w x oil temperature (T_GRID_C)."""

    tables: dict  # speed source -> (N_U, nT, n_links) W/K at w = u^2 w_max
    src_of_link: np.ndarray  # speed source of every variable link (-1: constant)
    w_src_max: np.ndarray  # max speed of every speed source over all gears [rad/s]
    u: np.ndarray  # (N_U,) sqrt(w / w_max)
    G_ring_low: np.ndarray  # every link at low range, standstill, 60 degC (the ring gear's low-range value)


def law_grid(net: Network, p: Parameters, batched: bool = True) -> LawGrid:
    """Tabulate every speed- or oil-dependent link with all shafts at the same speed (each link reads its own).

    The full evaluator is called once per oil temperature with every grid speed as a batch; ``batched=False``
    calls it once per grid point instead (the same numbers bit for bit, ~50x slower; kept as the reference the
    tests and benchmarks/bench_build.py compare with)."""
    ev = ConductanceEvaluator(net, p, EffectScales())
    speed_abs = np.abs(kinematics_of(p).speed)  # (17, speed columns)
    w_src_max = speed_abs.max(axis=0) * net.geometry.description.drive.max_speed_rad_s
    u = np.linspace(0.0, 1.0, N_U)
    n_links = len(net.link_a)
    variable = (K_SPLASH, K_IMM_GEAR, K_IMM_BRG, K_BRG_SPLASH, K_STREAM, K_RING)
    src_of_link = np.full(n_links, -1)
    for k in range(n_links):
        if int(net.link_kind[k]) in variable:
            src_of_link[k] = _speed_of_link(net, k)
    zero_mt = np.zeros(len(net.geometry.description.meshes))
    T_dummy = np.full(net.n, 60.0)
    bc_dummy = np.full(len(net.boundaries), 40.0)

    def eval_all(w, T, low_range=False):
        """Every link with all shafts at the speed w (an array of speeds: a batch, see evaluate) [W/K]."""
        sp = np.repeat(np.asarray(w, dtype=float)[..., None], len(net.speed_names), axis=-1)
        return ev.evaluate(float(T), sp, 0, zero_mt, low_range, T_dummy, bc_dummy).copy()

    sources = sorted(set(src_of_link[src_of_link >= 0].tolist()))
    # one batch per oil temperature: every source's speeds u^2 w_max (the oil properties are scalars per call)
    w = np.array([[ui * ui * max(w_src_max[s], 1e-6) for ui in u] for s in sources]).reshape(-1)
    tab = np.empty((len(sources), N_U, T_GRID_C.size, n_links))
    for j, Tj in enumerate(T_GRID_C):
        if batched:
            tab[:, :, j] = eval_all(w, Tj).reshape(len(sources), N_U, n_links)
        else:
            for k, wk in enumerate(w):
                tab[k // N_U, k % N_U, j] = eval_all(wk, Tj)
    tables = {s: tab[k] for k, s in enumerate(sources)}
    return LawGrid(tables, src_of_link, w_src_max, u, eval_all(0.0, 60.0, low_range=True))


class _Laws:
    """The conductance law of every reduced link, collected link by link of the full network (module doc)."""

    def __init__(self, net: Network, agg: Aggregation, p: Parameters, grid: LawGrid):
        self.net, self.agg, self.p, self.grid = net, agg, p, grid
        self.kin = kinematics_of(p)
        self.speed_abs = np.abs(self.kin.speed)
        self.G_const = np.zeros(len(agg.link_a))
        self.pw: list = []
        self.t2: list = []
        self.ef: list = []
        self.cyl: list = []
        self.rad: dict = {}  # reduced link -> area x emissivity
        self.phi_cols: list = []

    def phi_col(self, values) -> int:
        for c, v in enumerate(self.phi_cols):
            if np.allclose(v, values, rtol=1e-12, atol=0):
                return c
        self.phi_cols.append(values)
        return len(self.phi_cols) - 1

    def phi_table(self) -> np.ndarray:
        pw_phi = np.ones((T_GRID_C.size, max(len(self.phi_cols), 1)))
        for c, v in enumerate(self.phi_cols):
            pw_phi[:, c] = v
        return pw_phi

    def add_link(self, k: int) -> None:
        r = int(self.agg.link_of_full[k])
        if r < 0:
            return  # inside a group
        net, p = self.net, self.p
        kind = int(net.link_kind[k])
        if kind == K_CONST:
            self.G_const[r] += net.link_G0[k]
        elif kind == K_CONTACT:
            mask = (self.kin.mesh_torque[:, int(_link_param(net, k, "mesh"))] != 0).astype(float)
            self.pw.append(PowerTerm(r, 0.0, net.link_G0[k] * mask, -1, EFFECT_NONE))
        elif kind == K_EXT_CONV:
            self.pw.append(
                PowerTerm(r, 0.0, np.full(N_GEARS, net.link_G0[k] * p["housing.h_air"]), -1, EFFECT_HOUSING_AIR_H)
            )
        elif kind == K_EXT_RAD:
            # housings merged into one node: their radiation areas add (same boundary, same law)
            area_eps = net.link_G0[k] * p["housing.emissivity"]
            self.rad[r] = self.rad[r] + area_eps if r in self.rad else area_eps
        elif kind == K_IMM_GEAR:
            self._immersed_wheel(k, r)
        elif kind == K_STREAM and int(_link_param(net, k, "sub")) in (S_CHANNEL, S_IMPOSED):
            self._closed_form_stream(k, r)
        else:
            self._tabulated(k, r, kind)

    def _immersed_wheel(self, k: int, r: int) -> None:
        """Nusselt (Eq 46-48, closed form) plus fling-off (Eq 54-58, an exact sqrt(w) power law)."""
        net, s = self.net, self.grid.src_of_link[k]
        w = self.grid.u * self.grid.u * self.grid.w_src_max[s]
        R_p = float(_link_param(net, k, "R_p"))
        fo = _fling_off_table(net, k, w, T_GRID_C)
        law = _separable_power_law(fo, w)
        nus = _cyl_table(net.link_G0[k] / R_p, R_p, w, T_GRID_C, net.oil)
        tab = self.grid.tables[s][:, :, k]
        if law is None or np.max(np.abs(nus + fo - tab)) > 1e-9 * np.abs(tab).max():
            raise ParameterError(
                f"link {net.link_name[k]}: the immersed-wheel conductance is not Nusselt (Eq 46-48) "
                f"plus fling-off (Eq 54-58) as the onboard model assumes"
            )
        e, a, phi = law
        self.pw.append(PowerTerm(r, e, a * self.speed_abs[:, s] ** e, self.phi_col(phi), EFFECT_NONE))
        self.cyl.append(CylinderTerm(r, self.speed_abs[:, s], net.link_G0[k] / R_p, math.log(R_p * R_p)))

    def _closed_form_stream(self, k: int, r: int) -> None:
        """Channel flows (Eq 77-80: 7.54 k / D_h x area) and the planetary's imposed h, through the NTU law."""
        net = self.net
        sub = int(_link_param(net, k, "sub"))
        frac = float(_link_param(net, k, "frac"))
        if sub == S_CHANNEL:
            alpha, beta = net.link_G0[k] * ht.NU_CHANNEL / float(_link_param(net, k, "D")), 0.0  # Eq 77-80
        else:
            alpha, beta = 0.0, net.link_G0[k] * float(_link_param(net, k, "h"))
        self.ef.append(
            StreamTerm(
                r,
                frac * _flow_per_drive_m3(net.geometry.description),
                alpha,
                beta,
                EFFECT_PLANET_OIL_H if sub == S_IMPOSED else EFFECT_NONE,
            )
        )

    def _tabulated(self, k: int, r: int, kind: int) -> None:
        """A power law where the table is separable (splash Eq 59, Harris Eq 63, immersed bearings Eq 52), else a
        bilinear table; the ring gear is a splash law at high range and a constant at low range."""
        net, s = self.net, self.grid.src_of_link[k]
        tab = self.grid.tables[s][:, :, k]  # (N_U, nT)
        wmax = self.grid.w_src_max[s]
        name = net.link_name[k]
        # an oil-system stream stays a stream (the cooler's inlet drop applies to it): a motor pump's is flat in
        # speed, which would pass for a power law
        law = None if kind == K_STREAM else _separable_power_law(tab, self.grid.u * self.grid.u * wmax)
        if kind == K_RING:
            # low range: housing-like constant h (seed 3.3); high range: the ring turns with the sun (splash)
            G_low = float(self.grid.G_ring_low[k])
            if law is not None:
                self.pw.append(PowerTerm(r, 0.0, G_low * self.kin.low_range.astype(float), -1, EFFECT_NONE))
            elif not np.allclose(tab[0, :], G_low, rtol=1e-9):
                raise ParameterError(
                    "ring-gear conductance: the high-range law at standstill differs from the "
                    "low-range value; the onboard tables cannot represent it"
                )
            # else: the table at zero ring speed (the ring does not turn at low range) is the low-range value
        if law is not None:
            e, a, phi = law
            col = -1 if np.allclose(phi, 1.0, rtol=1e-12) else self.phi_col(phi)
            coef = a * self.speed_abs[:, s] ** e
            if kind == K_RING:
                coef = coef * (~self.kin.low_range)
            eff = EFFECT_TEETH_OIL_H if (name.startswith("splash:") and name.endswith(".teeth")) else EFFECT_NONE
            self.pw.append(PowerTerm(r, e, coef, col, eff))
        else:
            frac = float(_link_param(net, k, "frac")) if kind == K_STREAM else 0.0
            speed = self._speed(kind, s)
            self.t2.append(TableTerm(r, speed, wmax, tab[:, ::T2_STRIDE], kind == K_STREAM, frac, EFFECT_NONE))

    def _speed(self, kind: int, s: int) -> np.ndarray:
        """|speed| per unit input speed a link's table is read at: its source's; a motor pump's stream reads its
        table at standstill (the flow follows no shaft: the table is flat in speed)."""
        motor = kind == K_STREAM and self.net.geometry.description.oil.pump_shaft is None
        return np.zeros(N_GEARS) if motor else self.speed_abs[:, s]


class LossMaps(NamedTuple):
    """The loss model as the onboard step evaluates it (module doc, "Loss maps")."""

    mesh_x0: np.ndarray
    mesh_phi: np.ndarray
    mesh_roll_k: np.ndarray
    mesh_heat_sf: np.ndarray
    bear_speed: np.ndarray
    bear_c: np.ndarray
    bear_load: np.ndarray
    bear_rr: np.ndarray
    bear_ish: np.ndarray
    needle_c: np.ndarray
    sync_coef: np.ndarray
    pump_coef: np.ndarray
    churn_omega_max_rad_s: float
    churn_table: np.ndarray
    mesh_roll_lt_min: np.ndarray


def _pump_code(d: Description) -> int:
    """PUMP_CODES of the description's oil pump: on a shaft (oil.pump_shaft), motor-driven (a pump_flow, no shaft),
    none."""
    if d.oil.pump_shaft is not None:
        return PUMP_CODES["shaft"]
    return PUMP_CODES["motor"] if d.oil.pump_flow else PUMP_CODES["none"]


def _pump_flow_m3_per_rad(d: Description) -> float:
    """The oil volume a shaft-driven pump moves per radian of its shaft (0: no pump, or a motor-driven one)."""
    return float(d.oil.pump_flow or 0.0) if d.oil.pump_shaft is not None else 0.0


def _motor_pump_flow_m3_s(d: Description) -> float:
    """A motor-driven pump's volume flow [m3/s] (0: none, or a pump on a shaft): the plant holds it fixed
    (network.ConductanceEvaluator.oil_mass_flow_kg_s, mass flow rho(T_oil) x it), and so does the onboard model."""
    return float(d.oil.pump_flow or 0.0) if d.oil.pump_shaft is None else 0.0


def _flow_per_drive_m3(d: Description) -> float:
    """The oil flow per unit of evaluate.pump_drive (evaluate.flow_per_drive): m3/rad of a shaft pump, m3/s of a
    motor pump."""
    return _motor_pump_flow_m3_s(d) if _pump_code(d) == PUMP_CODES["motor"] else _pump_flow_m3_per_rad(d)


def _loss_maps(p: Parameters, net: Network, w_ls_max_rad_s: float) -> LossMaps:
    """Mesh slip tables and rolling constants (Eq 7-22), Palmgren coefficients of the shaft and needle bearings
    (Eq 35-40), synchronizer (Eq 41) and pump (Eq 42) coefficients per gear, churning table (Eq 23-34)."""
    kin = kinematics_of(p)
    gl = GearboxLosses(p, net.geometry)
    mesh_x0, mesh_phi_rows, roll_k, roll_lt_min = _mesh_tables(gl)
    speed_abs = np.abs(kin.speed)
    d = net.geometry.description
    bear_speed = np.zeros((N_GEARS, len(gl.bearing_ids)))
    for j in range(len(gl.bearing_ids)):
        if gl.bearing_outer_idx[j] is not None:  # a pilot bearing: between its shaft and the one around it
            bear_speed[:, j] = np.abs(kin.speed[:, gl.bearing_outer_idx[j]] - kin.speed[:, gl.bearing_speed_idx[j]])
        else:
            bear_speed[:, j] = speed_abs[:, gl.bearing_speed_idx[j]]
    sync_c = np.array(
        [
            n_r * 2.0 * math.pi * R**3 * p["sync.w_ring"] / (J * math.sin(p["sync.theta_ring"]))
            for n_r, R, J in gl.sync_geo
        ]
    )
    u_ch = np.linspace(0.0, 1.0, N_U_CHURN)
    planetary = planetary_meshes(d)
    heat_sf = np.array(
        [p["scale.planet_to_heat"] if m.id in planetary else p["scale.gear_contact_to_heat"] for m in d.meshes]
    )
    pump = np.zeros(N_GEARS) if gl.pump_col is None else gl.pump_k * kin.speed[:, gl.pump_col] ** 2
    return LossMaps(
        mesh_x0,
        mesh_phi_rows,
        roll_k,
        heat_sf,
        bear_speed,
        L.PALMGREN_SEED_C * gl.f0 * gl.Dm**3,
        gl.load_torque_coef,
        gl.rr_coef,
        L.skf_inlet_shear_coef(gl.Dm),
        L.PALMGREN_SEED_C * gl.needle_f0 * gl.needle_Dm**3,
        (kin.sync_rel**2) @ sync_c,
        pump,
        w_ls_max_rad_s,
        _churn_table(gl, u_ch * u_ch * w_ls_max_rad_s, T_GRID_C, kin, churn_column(d)),
        roll_lt_min,
    )


def _source_matrix(net: Network, agg: Aggregation) -> np.ndarray:
    """(sources, n): where each source's heat goes, in reduced nodes (source_names)."""
    d = net.geometry.description
    planetary = planetary_meshes(d)
    names = source_names(d)
    S = np.zeros((len(names), len(agg.nodes)))
    for j, nm in enumerate(names):
        if nm.startswith("mesh:") and nm[5:] in planetary:
            dist = net.sources["planetary"]
        elif nm == "oil_lumped":
            dist = net.sources["churning"]
        else:
            dist = net.sources[nm]
        for node, frac in dist:
            S[j, agg.node_of_full[node]] += frac
    return S


def _resolve_partition(partition: str | dict, d: Description) -> tuple[str, dict]:
    if not isinstance(partition, str):
        return "custom", partition
    if partition not in PARTITIONS:
        raise ParameterError(f"unknown partition {partition!r}; known: {', '.join(PARTITIONS)}")
    return partition, PARTITIONS[partition](d)


def _law_fields(laws: _Laws) -> dict:
    """The ReducedParams fields of the conductance laws (read-only arrays)."""
    pw, t2, ef, cyl = laws.pw, laws.t2, laws.ef, laws.cyl
    nT2 = T_GRID_C[::T2_STRIDE].size

    def col(rows, name, dtype=float):
        return _ro(np.array([getattr(r, name) for r in rows], dtype=dtype), dtype)

    def per_gear(rows, name):
        return _ro(np.array([getattr(r, name) for r in rows]).T.reshape(N_GEARS, len(rows)))

    return dict(
        G_const_w_per_k=_ro(laws.G_const),
        pw_link=col(pw, "link", np.int64),
        pw_exp=col(pw, "exp"),
        pw_gear_coef=per_gear(pw, "gear_coef"),
        pw_col=col(pw, "col", np.int64),
        pw_phi=_ro(laws.phi_table()),
        pw_effect=col(pw, "effect", np.int64),
        t2_link=col(t2, "link", np.int64),
        t2_speed_coef=per_gear(t2, "speed_coef"),
        t2_omega_max_rad_s=col(t2, "omega_max_rad_s"),
        t2_table=_ro(np.array([r.table for r in t2]).reshape(len(t2), N_U, nT2)),
        t2_stream=col(t2, "stream", bool),
        t2_frac=col(t2, "frac"),
        t2_effect=col(t2, "effect", np.int64),
        cyl_link=col(cyl, "link", np.int64),
        cyl_speed_coef=per_gear(cyl, "speed_coef"),
        cyl_c=col(cyl, "c_m"),
        cyl_ln_rp2=col(cyl, "ln_rp2"),
        ef_link=col(ef, "link", np.int64),
        ef_mcp=col(ef, "flow_m3_per_rad"),
        ef_alpha=col(ef, "alpha_m"),
        ef_beta=col(ef, "beta_w_per_k"),
        ef_effect=col(ef, "effect", np.int64),
        rad_link=_ro(np.array(list(laws.rad), dtype=np.int64), np.int64),
        rad_area_eps=_ro(np.array(list(laws.rad.values()), dtype=float)),
    )


def onboard_boundaries(net: Network) -> tuple:
    """The onboard model's boundaries: the network's (its description's, in order: link_b indexes them), then those
    of STEP_BOUNDARIES the description has not, as slots no link touches (the step writes the ambient and coolant
    inputs and shifts the hot surroundings there; the GRS905 has all three)."""
    return tuple(net.boundaries) + tuple(b for b in STEP_BOUNDARIES if b not in net.boundaries)


def _boundary_defaults_c(p: Parameters, net: Network) -> np.ndarray:
    """The boundaries' default temperatures (onboard_boundaries order): the file's boundary.<name>, else the
    description's (topology.boundary.<name>.temperature); a slot no link touches takes the ambient's."""
    stated = {b.id: b.temperature_c for b in net.geometry.description.boundaries}
    ambient = p.get("boundary.ambient", stated.get("ambient", p["boundary.initial"]))
    return np.array([p.get(f"boundary.{b}", stated.get(b, ambient)) for b in onboard_boundaries(net)], dtype=float)


def _surroundings_fields(p: Parameters, net: Network) -> dict:
    """The ReducedParams fields of the cooler, the oil flow, the boundaries, the drive's operating range and the
    loss sources, from the parameter set and its description."""
    kind = p.strings.get("cooler.kind", "liquid")
    d, bcs = net.geometry.description, onboard_boundaries(net)
    return dict(
        cooler_code=COOLER_CODES.get(kind, 0),
        cooler=cooler_values(p) if COOLER_CODES.get(kind, 0) else {**{k: 0.0 for k in COOLER_KEYS}, **heater_values(p)},
        flow_m3_per_rad=_pump_flow_m3_per_rad(d),
        pump_code=_pump_code(d),
        pump_flow_m3_s=_motor_pump_flow_m3_s(d),
        pump_stop_rad_s=float(d.oil.pump_stops_below_rad_s or 0.0),
        # the plant's (tools.plant.reference: v_default_kmh): a vehicle's default speed, else no recirculation
        default_v_kmh=DEFAULT_VEHICLE_SPEED_KMH if d.drive.kind == "vehicle" else float(AIR_RECIRC_V_KMH[-1]),
        bc_default_c=_ro(_boundary_defaults_c(p, net)),
        engine_off_tau_s=float(p.get("boundary.engine_off_tau", ENGINE_OFF_TAU_S)),
        i_ambient=bcs.index("ambient"),
        i_coolant=bcs.index("coolant"),
        i_hot=bcs.index("hot_surroundings"),
        aux_expected=aux_inputs_expected(d),
        max_speed_rpm=float(d.drive.max_speed_rad_s / RAD_S_PER_RPM),
        min_torque_nm=float(d.drive.min_torque_nm),
        max_torque_nm=float(d.drive.max_torque_nm),
        speed_bin_min_rad_s=speed_bin_min_rad_s(float(d.drive.max_speed_rad_s)),
        src_names=source_names(d),
        src_planetary=tuple(f"mesh:{m}" for m in planetary_meshes(d)),
        oil_inlet=OIL_INLET in d.derived,
    )


def build_reduced(
    p: Parameters,
    partition: str | dict = "fine",
    effects: dict | None = None,
    dt_s: float = DT_S,
    margin: float = STABILITY_MARGIN,
    check: bool = True,
) -> ReducedParams:
    """Build the onboard model from a validated parameter set; raises StabilityError if dt is unsafe.

    ``effects``: only the build-time effect oil_level_low is used here (the others are applied at run time through
    :func:`make_effects`)."""
    p = with_oil_volume(p, effect_value(effects, "oil_level_low"))
    if not 0.0 < dt_s <= 1.0:
        raise ParameterError(f"dt_s = {dt_s} s must be in (0, 1] s")
    if not 0.0 < margin <= 1.0:
        raise ParameterError(f"stability margin = {margin} must be in (0, 1]")
    net = build_network(p)
    d = net.geometry.description
    cols = speed_columns(d)
    part_name, partition = _resolve_partition(partition, d)
    agg = aggregate(net, partition)
    kin = kinematics_of(p)
    grid = law_grid(net, p)
    laws = _Laws(net, agg, p, grid)
    for k in range(len(net.link_a)):
        laws.add_link(k)
    # the churning table's speed axis: the churning column's top speed (no wheel dips: a nominal 1 rad/s, the table 0)
    churn_col = cols["churn_speed_col"]
    lm = _loss_maps(p, net, float(grid.w_src_max[churn_col]) if churn_col >= 0 else 1.0)
    published = published_ids(d)
    rp = ReducedParams(
        variant=p.variant,
        partition=part_name,
        nodes=agg.nodes,
        dt_s=float(dt_s),
        margin=float(margin),
        C_j_per_k=_ro(agg.C),
        i_oil=agg.nodes.index("oil"),
        published_index=_ro(np.array([agg.nodes.index(c) for c in published]), np.int64),
        published=published,
        members=agg.members,
        link_a=_ro(agg.link_a, np.int64),
        link_b=_ro(agg.link_b, np.int64),
        link_name=agg.link_name,
        **_law_fields(laws),
        prop=_ro(oil_property_table(T_GRID_C, net.oil)),
        speed_coef=_ro(kin.speed),
        **cols,
        mesh_torque=_ro(kin.mesh_torque),
        mesh_omega2=_ro(kin.mesh_omega2),
        mesh_x0=_ro(lm.mesh_x0),
        mesh_phi=_ro(lm.mesh_phi),
        mesh_roll_k=_ro(lm.mesh_roll_k),
        mesh_heat_sf=_ro(lm.mesh_heat_sf),
        mesh_roll_lt_min=_ro(lm.mesh_roll_lt_min),
        bear_speed=_ro(lm.bear_speed),
        bear_c=_ro(lm.bear_c),
        bear_load=_ro(lm.bear_load),
        bear_rr=_ro(lm.bear_rr),
        bear_ish=_ro(lm.bear_ish),
        needle_rel=_ro(kin.wheel_bearing_rel),
        needle_c=_ro(lm.needle_c),
        sync_coef=_ro(lm.sync_coef),
        pump_coef=_ro(lm.pump_coef),
        gear_defined=_ro(np.isin(np.arange(N_GEARS) + GEAR_MIN, [g.number for g in d.gears]), bool),
        churn_omega_max_rad_s=float(lm.churn_omega_max_rad_s),
        churn_table=_ro(lm.churn_table),
        churn_heat_sf=float(p["scale.churn_to_heat"]),
        src_matrix=_ro(_source_matrix(net, agg)),
        heat_lag_tau_s=float(p["scale.heat_lag_tau"]),
        **_surroundings_fields(p, net),
    )
    if check:
        object.__setattr__(rp, "stability", check_stability(rp))
    return rp


def with_step(rp: ReducedParams, dt_s: float) -> ReducedParams:
    """The same onboard model at another explicit step ``dt_s`` (a held replay's coarser step; nothing else in the
    tables depends on it), its stability proof checked again (StabilityError when ``dt_s`` exceeds it). At most
    HELD_STEP_CAP_S."""
    if not 0.0 < dt_s <= HELD_STEP_CAP_S:
        raise ParameterError(f"dt_s = {dt_s} s must be in (0, {HELD_STEP_CAP_S:g}] s")
    if dt_s == rp.dt_s:
        return rp
    new = dataclasses.replace(rp, dt_s=float(dt_s))  # a fresh record: its helpers (the heat lag at dt) rebuilt
    object.__setattr__(new, "stability", check_stability(new))
    return new


def _separable_power_law(tab: np.ndarray, w: np.ndarray):
    """(exponent e, a, phi(T)) with tab[i, j] = a w_i^e phi_j to SEPARABLE_RTOL for every w_i > 0, else None.

    phi is normalised to 1 at 60 degC. At w = 0 the law gives 0 (the full evaluator floors some speeds at
    MIN_SPEED_RAD_S, a conductance below 0.3 % of its value at 100 rpm)."""
    if not np.all(np.isfinite(tab)) or np.any(tab < 0):
        return None
    pos = np.flatnonzero(w > 0)
    j_ref = int(np.argmin(np.abs(T_GRID_C - 60.0)))
    i1, i2 = pos[0], pos[-1]
    if tab[i1, j_ref] <= 0 or tab[i2, j_ref] <= 0:
        return None
    e = math.log(tab[i2, j_ref] / tab[i1, j_ref]) / math.log(w[i2] / w[i1])
    if abs(e) < 1e-9:
        e = 0.0
    a = tab[i2, j_ref] / w[i2] ** e
    phi = tab[i2, :] / tab[i2, j_ref]
    model = a * w[pos, None] ** e * phi[None, :]
    if np.max(np.abs(model - tab[pos])) <= SEPARABLE_RTOL * np.abs(tab).max():
        return e, a, phi
    return None


def _cyl_table(c, R_p, w, T, oil: oilprops.Oil):
    op = oil.properties(T)
    wf = np.maximum(w, MIN_SPEED_RAD_S)[:, None]
    re = R_p * R_p * wf / op.nu_m2_s[None, :]
    return c * op.k_w_per_mk[None, :] * ht.nusselt_rotating_cylinder(re, op.pr[None, :])


def _fling_off_table(net: Network, k: int, w, T):
    kp = {key: float(_link_param(net, k, key)) for key in ("z", "width", "h_t", "R_p", "h_i")}
    op = net.oil.properties(T)
    wf = np.maximum(w, MIN_SPEED_RAD_S)[:, None]
    return ht.fling_off_hA(
        kp["z"],
        kp["width"],
        kp["h_t"],
        kp["R_p"],
        kp["h_i"],
        wf,
        op.k_w_per_mk[None, :],
        op.alpha_m2_s[None, :],
        op.nu_m2_s[None, :],
    ).hA_w_per_k


def _mesh_tables(gl: GearboxLosses):
    """Per mesh: x0 and phi on x = x0 + X_STEP i (slip loss / (T1 w2)), the rolling-loss constant and log10 of the
    torque T1 below which the rolling loss ramps to 0 (the plant's L.ROLL_TORQUE_MIN_NM per contact)."""
    rows, x0s, roll, lt_min = [], [], [], []
    # x range: beyond it f_g is clipped at both ends for every point of the line of action
    xs = np.arange(-16.0, 24.0 + 1e-9, X_STEP)
    for n_planets, mesh in zip(gl.mesh_planets, gl.meshes):
        planetary = n_planets > 0
        n_pl = n_planets if planetary else gl.n_planets
        # total torque T on wheel 1; the loss model splits it over the planets
        T_tot = 10.0**xs
        T1 = T_tot / n_pl if planetary else T_tot
        P = L.gear_slip_loss_w(mesh, T1, 1.0, 1.0, 1.0)
        if planetary:
            P = P * n_pl
        phi = P / T_tot
        # trim constant ends (keep one point of each plateau)
        d = np.abs(np.diff(phi)) > 1e-14 * np.abs(phi).max()
        lo = max(int(np.argmax(d)) - 1, 0)
        hi = min(len(phi) - int(np.argmax(d[::-1])) + 1, len(phi))
        rows.append(phi[lo:hi])
        x0s.append(xs[lo])
        Tr = 1000.0 / (n_pl if planetary else 1.0)
        Pr = L.gear_rolling_loss_w(mesh, Tr, 100.0, 1.0, 1.0, gl.E, gl.E, gl.poisson, gl.poisson, n_points=ROLL_POINTS)
        if planetary:
            Pr = Pr * n_pl
        roll.append(float(Pr) / (100.0**1.7 * 1000.0**-0.13))
        # the plant's ramp starts at ROLL_TORQUE_MIN_NM per contact: n_pl times that on the sun's total torque
        lt_min.append(math.log10((n_pl if planetary else 1.0) * L.ROLL_TORQUE_MIN_NM))
    nx = max(len(r) for r in rows)
    tab = np.empty((len(rows), nx))
    for i, r in enumerate(rows):
        tab[i, : len(r)] = r
        tab[i, len(r) :] = r[-1]
    return np.array(x0s), tab, np.array(roll), np.array(lt_min)


def churn_ratios(gl: GearboxLosses, kin, col: int) -> np.ndarray:
    """Each dipping wheel's speed over the churning column's, taken in neutral (or, without one, the first gear that
    turns that column): 1 for the wheels that turn with it (the GRS905's layshaft wheels, its idler: RI/LS). The
    table has one speed axis: a wheel whose ratio changes with the gear is refused (one sentence naming it)."""
    if col < 0:
        return np.ones(len(gl.ch_col))
    turning = [r for r in range(N_GEARS) if kin.speed[r, col] != 0.0]
    r = next(r for r in [0 - GEAR_MIN] + turning if kin.speed[r, col] != 0.0)
    out = np.array([1.0 if c == col else abs(kin.speed[r, c] / kin.speed[r, col]) for c in gl.ch_col])
    dipping = [w.id for w in gl.d.wheels if w.id in gl.d.oil.dipping]  # gl.ch_col's order
    for w, c, ratio in zip(dipping, gl.ch_col, out):
        every = np.abs(kin.speed[turning, c] / kin.speed[turning, col])
        if not np.allclose(every, ratio, rtol=1e-12, atol=0.0):
            raise ParameterError(
                f"{gl.d.origin}: topology.oil.dipping names {w}, whose speed over {kin.speed_names[col]}'s changes "
                "with the gear: the onboard churning table follows one shaft (the wheels dipping into the sump must "
                "turn with it or at a fixed ratio to it)"
            )
    return out


def _churn_table(gl: GearboxLosses, w_ls: np.ndarray, T2: np.ndarray, kin, col: int) -> np.ndarray:
    """Churning loss [W] of every immersed wheel at the churning column's speed w_ls (the GRS905's layshaft; each
    wheel at its own ratio to it) x oil temperature T2 (Eq 23-34)."""
    ratio = churn_ratios(gl, kin, col)
    out = np.zeros((w_ls.size, T2.size))
    for j, T in enumerate(T2):
        op = gl.oil.properties(T)
        wc = np.where(ratio[None, :] != 1.0, w_ls[:, None] * ratio[None, :], w_ls[:, None])
        ch = L.churning_loss(
            wc, gl.ch_Ra, gl.ch_Rp, gl.ch_ht, gl.ch_w, gl.ch_hi, gl.ch_Vp, gl.V0, op.rho_kg_m3, op.nu_m2_s, gl.h_t0
        )
        out[:, j] = np.sum(np.where(gl.ch_mask, ch.power_w, 0.0), axis=1)
    return out

"""The gearbox thermal network as data (seed section 3.1 thermal masses, 3.3 heat paths).

`build_network(params)` derives every geometric quantity the equations need from the parameter set (through
:func:`firmware_model.physics.geometry.build_geometry`) and returns a `Network`: node names and heat capacities, and
links. A link joins two nodes, or a node and a boundary temperature, with a conductance that is either constant or
evaluated by its *kind* from the oil temperature, the shaft speeds, the gear and the oil flow. The full reference
plant integrates this network as it is; the onboard model is a reduction of the same description (nodes merged,
links summed), so the two cannot drift apart. The network is built from the physics (``firmware_model.physics``);
the physics never imports it.

All in SI; temperatures in degC.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from firmware_model.description import Description
from firmware_model.effects import RETARDER_HEAT_SPLIT, EffectScales
from firmware_model.errors import ParameterError
from firmware_model.parameters import Parameters
from firmware_model.physics import heat_transfer as ht
from firmware_model.physics import oil as oilprops
from firmware_model.physics.geometry import Geometry, build_geometry
from firmware_model.physics.losses import ADDENDUM_COEF, DEDENDUM_COEF, PLANETARY_HEAT_SPLIT

#: the GRS905's boundary temperatures in its description's order (seed section 3, boundary conditions); a network
#: takes its own from its description (`Network.boundaries`); the onboard step and the C kernel index these
BOUNDARIES = (
    "engine_shaft",
    "flywheel_cover",
    "support_beam",
    "end_yoke",
    "hot_surroundings",
    "cold_surroundings",
    "coolant",
    "ambient",
)

# link kinds
K_CONST, K_CONTACT, K_SPLASH, K_IMM_GEAR, K_IMM_BRG, K_BRG_SPLASH, K_STREAM, K_RING, K_EXT_CONV, K_EXT_RAD = range(10)
KIND_NAMES = (
    "conduction",
    "gear_contact",
    "splash",
    "immersed_gear",
    "immersed_bearing",
    "bearing_splash",
    "oil_system",
    "ring_oil",
    "external_convection",
    "external_radiation",
)
N_KINDS = len(KIND_NAMES)
# oil-system stream sub-kinds
S_PIPE, S_CHANNEL, S_IMPOSED = range(3)

#: shortest shaft segment [m] (a numerical floor: two neighbouring parts at one position)
MIN_SEGMENT_M = 1e-3
#: speed floor of the rotating-part correlations (immersed wheels and bearings, bearing splash) [rad/s]: they are
#: evaluated at this speed at standstill (a conductance below 0.3 % of its value at 100 rpm)
MIN_SPEED_RAD_S = 1e-3


class NamedNodes:
    """Node names and their indices (the full network and the onboard model's reduced one)."""

    nodes: tuple

    @property
    def n(self) -> int:
        return len(self.nodes)

    def index(self, name: str) -> int:
        return self.nodes.index(name)


class Share(NamedTuple):
    """A share of a heat source deposited into one node."""

    node: int
    frac: float


@dataclass
class Network(NamedNodes):
    nodes: tuple
    C_j_per_k: np.ndarray
    # links: endpoint a is always a node; b is a node index, or n_nodes + boundary index
    link_a: np.ndarray
    link_b: np.ndarray
    link_kind: np.ndarray
    link_G0: np.ndarray  # constant part / area-like factor, meaning depends on kind
    link_name: tuple
    # per-kind parameters (arrays aligned with the links of that kind, in link order)
    kind_params: dict
    #: heat-source name -> list of Share(node index, fraction)
    sources: dict
    geometry: Geometry | None = None
    #: shaft segment -> its length [m]
    segment_length_m: dict = field(default_factory=dict)
    #: the boundary temperatures a link's b indexes past the nodes, in the description's order
    boundaries: tuple = BOUNDARIES
    #: the speeds a link's ``speed`` parameter indexes (`speed_names`)
    speed_names: tuple = ()
    #: the description's oil (its [oil] grade; the seed's where it gives none): every oil property of its laws
    oil: oilprops.Oil = oilprops.SEED_OIL

    def links_of_kind(self, kind: int) -> np.ndarray:
        return np.flatnonzero(self.link_kind == kind)


# ---------------------------------------------------------------------------------------------------------------
# building


def speed_names(d: Description) -> tuple:
    """The speeds the network's rotating parts turn at, in the order of the kinematics' speed table: the shafts,
    the wheels that turn on their own (idle wheels, idlers on a pin), each planetary set's sun, planets relative to
    the carrier (``<planet>_rel``) and ring (for the GRS905, kinematics.SPEED_NAMES)."""
    out = [s.id for s in d.shafts] + [w.id for w in d.wheels if w.mount in ("idle", "pin")]
    for ps in d.planetary:
        out += [ps.sun, f"{ps.planet}_rel", ps.ring]
    return tuple(out)


def _needed(d: Description, value, key: str, why: str):
    """A description value the network needs: missing, one sentence naming the file and the key."""
    if value is None:
        raise ParameterError(f"{d.origin}: topology.{key} is missing: the network needs it ({why})")
    return value


class _Builder:
    """Collects nodes, then links (with their per-kind parameters)."""

    def __init__(self, p: Parameters, geo: Geometry):
        self.p, self.geo, self.W = p, geo, geo.wheels
        self.desc = geo.description
        self.boundaries = tuple(bd.id for bd in self.desc.boundaries)
        self.speeds = speed_names(self.desc)
        self.mesh_ix = {m.id: i for i, m in enumerate(self.desc.meshes)}
        self.bearing = {brg.id: brg for brg in self.desc.bearings}
        self.housing = {h.id: h for h in self.desc.housings}
        #: idle wheels (teeth and bulk nodes), the other wheels (one node each), shaft bearings, (wheel, its bearing)
        self.idle = tuple(w.id for w in self.desc.wheels if w.mount == "idle")
        self.whole = tuple(w.id for w in self.desc.wheels if w.mount != "idle")
        self.shaft_brgs = tuple(x.id for x in self.desc.bearings if x.wheel is None)
        self.wheel_brgs = tuple((x.wheel, x.id) for x in self.desc.bearings if x.wheel is not None)
        self.st_rho, self.st_k, self.st_cp = p["material.steel.rho"], p["material.steel.k"], p["material.steel.cp"]
        self.oil = oilprops.oil_of(p)
        self.nodes: list = []
        self.C: list = []
        self.ix: dict = {}
        self.la, self.lb, self.lk, self.lg, self.lname = [], [], [], [], []
        self.kp = {k: [] for k in range(N_KINDS)}
        self.seg_len: dict = {}

    def add(self, name: str, C_j_per_k: float) -> None:
        if C_j_per_k <= 0 or not math.isfinite(C_j_per_k):
            raise ParameterError(f"thermal mass of node {name} is {C_j_per_k:g} J/K; it must be positive")
        self.ix[name] = len(self.nodes)
        self.nodes.append(name)
        self.C.append(C_j_per_k)

    def link(self, a: str, b: str, kind: int, G0: float, name: str, **params) -> None:
        self.la.append(self.ix[a])
        self.lb.append(self.ix[b] if b in self.ix else len(self.nodes) + self.boundaries.index(b))
        self.lk.append(kind)
        self.lg.append(float(G0))
        self.lname.append(name)
        self.kp[kind].append(params)

    def radial(self, k_w_per_mk, width_m, D_ext_m, D_int_m, sf=1.0) -> float:
        return ht.radial_conductance_w_per_k(k_w_per_mk, width_m, D_ext_m, D_int_m, sf)

    def network(self, sources: dict) -> Network:
        kind_params = {}
        for k, lst in self.kp.items():
            if lst:
                keys = sorted({kk for d in lst for kk in d})
                kind_params[k] = {kk: np.array([d.get(kk, 0.0) for d in lst], dtype=float) for kk in keys}
        return Network(
            tuple(self.nodes),
            np.array(self.C),
            np.array(self.la),
            np.array(self.lb),
            np.array(self.lk),
            np.array(self.lg),
            tuple(self.lname),
            kind_params,
            sources,
            self.geo,
            self.seg_len,
            self.boundaries,
            self.speeds,
            self.oil,
        )

    def spd(self, name: str) -> int:
        return self.speeds.index(name)


def _segment_lengths(xs: list, x_front: float, x_rear: float) -> list:
    """Each segment spans from the midpoint with its front neighbour to the midpoint with its rear neighbour."""
    bounds = [x_front] + [(xs[i] + xs[i + 1]) / 2 for i in range(len(xs) - 1)] + [x_rear]
    return [max(bounds[i + 1] - bounds[i], MIN_SEGMENT_M) for i in range(len(xs))]


def _segment_positions(d: Description) -> tuple[dict, dict]:
    """Axial position of every shaft segment node, and each shaft's front and rear end (seed 3.1, Fig 3), as the
    description states them."""
    pos = {s.id: [g.x_m for g in s.segments] for s in d.shafts}
    ends = {s.id: (s.front_m, s.rear_m) for s in d.shafts}
    return pos, ends


def _shaft_nodes(b: _Builder, pos: dict, ends: dict) -> None:
    """Shaft segments (seed 3.1): a hollow cylinder each; a planet carrier's segment has its own mass."""
    carriers = {ps.carrier_segment: ps.carrier_mass_kg for ps in b.desc.planetary if ps.carrier_mass_kg is not None}
    for sh in b.desc.shafts:
        s, names = sh.id, [g.id for g in sh.segments]
        ro, ri = sh.d_out_m / 2, sh.d_bore_m / 2
        for nm, L in zip(names, _segment_lengths(pos[s], *ends[s])):
            b.seg_len[nm] = L
            m = carriers.get(nm, b.st_rho * math.pi * (ro**2 - ri**2) * L)
            b.add(nm, m * b.st_cp)


def _wheel_nodes(b: _Builder) -> None:
    """Idle wheels split into teeth (with a rim a few modules deep) and bulk (seed 3.1); layshaft wheels and the
    reverse idler whole (teeth counted as half-filled between root and tip)."""
    p, W = b.p, b.W
    shell = p["gear.teeth_shell_modules"]
    hub = p["wheel.hub_mass_factor"]
    for w in b.idle:
        g = W[w]
        R_sh = g.R_f - shell * g.m_n
        m_teeth = b.st_rho * g.width * (math.pi * (g.R_f**2 - R_sh**2) + 0.5 * math.pi * (g.R_a**2 - g.R_f**2))
        m_bulk = b.st_rho * g.width * math.pi * (R_sh**2 - g.R_in**2) * hub
        b.add(f"{w}.teeth", m_teeth * b.st_cp)
        b.add(f"{w}.bulk", m_bulk * b.st_cp)
    for w in b.whole:
        g = W[w]
        shaft = b.desc.wheel(w).shaft
        R_inner = g.R_in if shaft is None else b.geo.R_shaft_m[shaft]  # an idler on a pin: its bore
        m = b.st_rho * g.width * (math.pi * (g.R_f**2 - R_inner**2) + 0.5 * math.pi * (g.R_a**2 - g.R_f**2))
        b.add(w, m * b.st_cp)


def _other_nodes(b: _Builder) -> None:
    """Planetary members, bearings, housings and the sump, with the masses the description gives."""
    p, cp, d = b.p, b.st_cp, b.desc
    for ps in d.planetary:
        for member, m, k in (
            (ps.sun, ps.mass_sun_kg, "mass_sun"),
            (ps.planet, ps.mass_planets_kg, "mass_planets"),
            (ps.ring, ps.mass_ring_kg, "mass_ring"),
        ):
            b.add(member, _needed(d, m, f"planetary.{ps.id}.{k}", f"the heat capacity of {member}") * cp)
    for brg in b.shaft_brgs + tuple(x for _, x in b.wheel_brgs):
        b.add(brg, _needed(d, b.bearing[brg].mass_kg, f"bearing.{brg}.mass", "its heat capacity") * cp)
    for h in b.housing:
        b.add(h, b.housing[h].mass_kg * p[f"material.{b.housing[h].material}.cp"])
    T_cap = p["oil.capacity_temp"]
    op = b.oil.properties(float(T_cap))
    rho_oil, cp_oil = float(op.rho_kg_m3), float(op.cp_j_per_kgk)
    b.add("oil", d.oil.volume_m3 * rho_oil * cp_oil)


def _conduction_links(b: _Builder, pos: dict) -> None:
    """Linear conduction along the shafts, to the boundary structures and across the housing joints (Eq 43)."""
    p = b.p
    for sh in b.desc.shafts:
        s, names = sh.id, [g.id for g in sh.segments]
        ro, ri = sh.d_out_m / 2, sh.d_bore_m / 2
        A = math.pi * (ro**2 - ri**2)
        for i in range(len(names) - 1):
            G = ht.linear_conductance_w_per_k(b.st_k, A, pos[s][i], pos[s][i + 1])
            b.link(names[i], names[i + 1], K_CONST, G, f"cond:{names[i]}-{names[i + 1]}")
    # the boundaries touched by conduction (a flange, a spline), in the order of the nodes that touch them
    conducting = [bd for bd in b.desc.boundaries if bd.conductance_w_per_k is not None]
    for node in b.nodes:
        for bd in conducting:
            if node in bd.touches:
                b.link(node, bd.id, K_CONST, bd.conductance_w_per_k, f"bc:{node}-{bd.id}")
    kj = p["housing.k_joint"]
    for h in b.desc.housings:
        if h.joined_to is not None:  # the bolted flange conducts between the two housings' nodes
            G = ht.linear_conductance_w_per_k(kj, h.joint_area_m2, h.x_m, b.housing[h.joined_to].x_m)
            b.link(h.id, h.joined_to, K_CONST, G, f"cond:{h.id}-{h.joined_to}")


def _wheel_radial_links(b: _Builder) -> None:
    """Radial conduction (Eq 44): idle-wheel teeth to bulk to needle bearing to shaft; layshaft wheels to the
    layshaft."""
    p, W, k = b.p, b.W, b.st_k
    sf_tb, sf_lw = p["heat.sf_teeth_bulk"], p["heat.sf_layshaft_wheel"]
    f_in = p["heat.shaft_inner_diameter_frac"]
    for w, wb in b.wheel_brgs:
        g, brg = W[w], b.bearing[wb]
        d_roll = _needed(b.desc, brg.roller_m, f"bearing.{wb}.roller", "the conduction through the bearing")
        D_teeth = g.R_a + g.R_f  # mean of tip and root diameters
        D_bulk = g.R_b + g.R_in  # mean of base and inner diameters
        b.link(f"{w}.teeth", f"{w}.bulk", K_CONST, b.radial(k, g.width, D_teeth, D_bulk, sf_tb), f"rad:{w}.teeth-bulk")
        sf_b = p[f"wheel_bearing.sf_radial_{brg.kind}"]
        D_shaft = 2 * b.geo.R_shaft_m[b.desc.wheel(w).shaft]
        Dm = D_shaft + d_roll
        # bulk -> bearing: solid from the bulk's representative diameter to the bore, then the bearing's outer half
        G_solid = b.radial(k, g.width, D_bulk, 2 * g.R_in, 1.0)
        G_outer = b.radial(k, g.width, 2 * g.R_in, Dm, sf_b)
        b.link(f"{w}.bulk", wb, K_CONST, 1.0 / (1.0 / G_solid + 1.0 / G_outer), f"rad:{w}.bulk-{wb}")
        seg = b.desc.wheel(w).segment
        b.link(wb, seg, K_CONST, b.radial(k, g.width, Dm, f_in * D_shaft, sf_b), f"rad:{wb}-{seg}")
    for w in (x for x in b.whole if b.desc.wheel(x).shaft is not None):
        g, seat = W[w], b.desc.wheel(w)
        D_w = g.R_b + g.R_in
        D_s = f_in * 2 * b.geo.R_shaft_m[seat.shaft]
        b.link(w, seat.segment, K_CONST, b.radial(k, g.width, D_w, D_s, sf_lw), f"rad:{w}-{seat.segment}")


def _bearing_radial_links(b: _Builder) -> None:
    """Radial conduction (Eq 44): shaft bearings to their shaft segment and housing; planets to the carrier through
    their bearings, the sun to the main shaft through its spline."""
    p, k = b.p, b.st_k
    f_in, f_seat = p["heat.shaft_inner_diameter_frac"], p["heat.seat_outer_diameter_factor"]
    for brg in b.shaft_brgs:
        seat = b.bearing[brg]
        sf = p[f"bearing.sf_radial_{seat.kind}"]
        d_in, d_out, wdt = seat.bore_m, seat.outer_m, seat.width_m
        Dm = 0.5 * (d_in + d_out)
        seg = seat.segment
        b.link(brg, seg, K_CONST, b.radial(k, wdt, Dm, f_in * d_in, sf), f"rad:{brg}-{seg}")
        if seat.inside is not None:
            # a pilot bearing sits inside another shaft's segment
            b.link(brg, seat.inside, K_CONST, b.radial(k, wdt, f_seat * d_out, Dm, sf), f"rad:{brg}-{seat.inside}")
        else:
            h = seat.housing
            k_h = p[f"material.{b.housing[h].material}.k"]
            b.link(brg, h, K_CONST, b.radial(min(k_h, k), wdt, f_seat * d_out, Dm, sf), f"rad:{brg}-{h}")
    for ps in b.desc.planetary:
        gp, gs = b.W[ps.planet], b.W[ps.sun]
        carrier = _needed(b.desc, ps.carrier_segment, f"planetary.{ps.id}.carrier_segment", "the planets' node")
        sun_seg = _needed(b.desc, ps.sun_segment, f"planetary.{ps.id}.sun_segment", "the sun's seat")
        G_pc = ps.n_planets * b.radial(k, gp.width, gp.R_b + gp.R_f, 2 * gp.R_in, p["planetary.sf_planet_carrier"])
        b.link(ps.planet, carrier, K_CONST, G_pc, f"rad:{ps.planet}-{carrier}")
        G_ss = b.radial(k, gs.width, gs.R_b + gs.R_in, f_in * 2 * gs.R_in, p["planetary.sf_sun_spline"])
        b.link(ps.sun, sun_seg, K_CONST, G_ss, f"rad:{ps.sun}-{sun_seg}")
    # a ring gear held by a coupling to the housing: no conduction path modelled (seed lists none)


def _contact_links(b: _Builder) -> None:
    """Gear contact conductance between the wheels of each mesh, over its face width (Eq 45); a planetary set's
    meshes once per planet."""
    p = b.p
    tcc, whz, cfrac = p["heat.TCC"], p["heat.w_Hz"], p["heat.contact_length_frac"]
    n_planets = {m: ps.n_planets for ps in b.desc.planetary for m in (ps.sun, ps.planet, ps.ring)}
    for m in b.desc.meshes:
        w1, w2 = m.wheels
        G = ht.gear_contact_conductance_w_per_k(tcc, b.geo.meshes[m.id].face_width_m, whz, cfrac)
        if w1 in n_planets:
            G = n_planets[w1] * G
        a, c = (f"{w}.teeth" if w in b.idle else w for w in m.wheels)
        b.link(a, c, K_CONTACT, G, f"contact:{w1}-{w2}", mesh=b.mesh_ix[m.id])


def _bearing_dims(b: _Builder, brg: str, why: str):
    """(width, roller diameter, mean diameter [m], number of rollers) of a shaft bearing the oil reaches."""
    x = b.bearing[brg]
    dr = _needed(b.desc, x.roller_m, f"bearing.{brg}.roller", why)
    n_r = _needed(b.desc, x.rollers, f"bearing.{brg}.rollers", why)
    return x.width_m, dr, 0.5 * (x.bore_m + x.outer_m), n_r


def _immersed_links(b: _Builder) -> None:
    """Dipping layshaft wheels and reverse idler: rotating cylinder (Eq 46-53) + fling-off (Eq 54-58); the layshaft
    bearings partly immersed (Eq 52-53)."""
    p, W = b.p, b.W
    spd = b.spd
    dipping = b.desc.oil.dipping
    for w in (x for x in dipping if x in W):
        g = W[w]
        shaft = b.desc.wheel(w).shaft
        if w not in b.geo.immersion_m:
            raise ParameterError(
                f"{b.desc.origin}: topology.oil.dipping names {w}, whose immersion the plant cannot compute yet "
                f"(it knows only the GRS905's layshaft wheels and reverse idler); lubricate it by jets instead"
            )
        h_i = b.geo.immersion_m[w]
        if h_i <= 0:
            continue
        w_in = 0.0 if b.desc.wheel(w).mount == "cut" else p["wheel.side_width_in_frac"] * g.width
        h_i_p = min(h_i, 2 * g.R_p)
        A = float(ht.immersed_gear_area_m2(g.R_p, g.width, g.R_in, w_in, h_i_p, g.z, g.h_t, g.beta))
        b.link(
            w,
            "oil",
            K_IMM_GEAR,
            A,
            f"imm:{w}",
            speed=spd(w if shaft is None else shaft),  # a wheel on a pin turns at its own speed
            R_p=g.R_p,
            z=g.z,
            width=g.width,
            h_t=g.h_t,
            h_i=h_i_p,
        )
    for brg in (x for x in dipping if x in b.bearing and b.bearing[x].wheel is None):
        wdt, dr, Dm, n_r = _bearing_dims(b, brg, "it dips into the sump")
        h_f = _needed(b.desc, b.bearing[brg].immersion, f"bearing.{brg}.immersion", "it dips into the sump")
        A = float(ht.immersed_bearing_area_m2(Dm - dr, Dm + dr, n_r, dr, wdt, h_f))
        b.link(brg, "oil", K_IMM_BRG, A, f"imm:{brg}", speed=spd(b.bearing[brg].shaft), Dm=Dm)


def _splash_links(b: _Builder) -> None:
    """Splashed parts (Eq 59-64): idle-wheel teeth, other wheels the thrown or jetted oil wets, the output shaft,
    the ring gear, the shaft bearings (Harris), and the housings' inside (200 W/(m2 K) on 90 % of 1.9 m2, split
    50/35/15)."""
    p, W, d = b.p, b.W, b.desc
    spd = b.spd
    covered = bool(p.get("wheel.covered_sides", 1))
    splashed = d.oil.splashed
    for w in (x.id for x in b.desc.wheels if f"{x.id}.teeth" in splashed):
        g = W[w]
        if b.desc.wheel(w).sides == "free" or not covered:
            A = float(ht.wheel_area_free_sides_m2(g.R_p, g.width, g.z, g.h_t, g.beta, g.R_in))  # Eq 61
        else:
            A = float(ht.wheel_area_covered_sides_m2(g.R_p, g.width, g.z, g.h_t, g.beta))  # Eq 60
        b.link(f"{w}.teeth", "oil", K_SPLASH, A, f"splash:{w}.teeth", speed=spd(w), group=0)
    # a wheel on its shaft (no planetary member) the thrown or the jetted oil wets: its teeth, Eq 59 over Eq 60/61
    wetted = set(splashed) | (set(d.oil.jets) if d.oil.lubrication == "forced" else set())
    for w in (x for x in b.whole if x in wetted):
        g, wh = W[w], b.desc.wheel(w)
        if wh.sides == "free":
            A = float(ht.wheel_area_free_sides_m2(g.R_p, g.width, g.z, g.h_t, g.beta, g.R_in))  # Eq 61
        else:
            A = float(ht.wheel_area_covered_sides_m2(g.R_p, g.width, g.z, g.h_t, g.beta))  # Eq 60
        b.link(w, "oil", K_SPLASH, A, f"splash:{w}", speed=spd(wh.shaft or w), group=0)
    for sh in d.shafts:  # splashed shaft segments: the wetted length of the shaft's outside (Eq 62)
        for seg in (g.id for g in sh.segments if g.id in splashed):
            L = sh.wetted_length_m if sh.wetted_length_m is not None else b.seg_len[seg]
            A = float(ht.cylinder_area_m2(sh.d_out_m, L))
            b.link(seg, "oil", K_SPLASH, A, f"splash:{sh.id}", speed=spd(sh.id), group=1)
    # a ring gear: splash when it turns (high range), 200 W/(m2 K) like the housing when held (seed 3.3)
    for ps in (x for x in d.planetary if x.ring in splashed):
        A = _needed(d, ps.ring_area_m2, f"planetary.{ps.id}.ring_area", "the ring gear is splashed")
        b.link(ps.ring, "oil", K_RING, A, f"ring:{ps.ring}", speed=spd(ps.ring))
    for brg in (x for x in splashed if x in b.bearing and b.bearing[x].wheel is None):
        wdt, dr, Dm, n_r = _bearing_dims(b, brg, "it is splashed")
        A = float(ht.bearing_internal_area_m2(Dm - dr, Dm + dr, n_r, dr, wdt))  # Eq 64
        b.link(brg, "oil", K_BRG_SPLASH, A, f"bsplash:{brg}", speed=spd(b.bearing[brg].shaft), Dm=Dm, d_roller=dr)
    A_in = d.oil.inside_area_m2
    if A_in is None:  # the inside of the housings: what their outside (housing.external_frac) leaves
        A_in = sum(h.area_m2 for h in d.housings) * (1.0 - p["housing.external_frac"])
    A_int = A_in * p["housing.oil_covered_frac"]
    for h in b.housing.values():
        b.link(h.id, "oil", K_CONST, p["housing.h_oil"] * A_int * h.internal_split, f"hoil:{h.id}")


def _bore_and_bearing_streams(b: _Builder) -> None:
    """Oil-system streams through the shaft bores (Eq 65-68), the needle bearings (Eq 69-74, 77-80) and the shaft
    bearings (Eq 75-80) the pumped oil reaches (oil.jets); heat goes to the sump with the returning oil."""
    p, d, jets = b.p, b.desc, b.desc.oil.jets
    for sh in d.shafts:
        fed = [g.id for g in sh.segments if g.id in jets]  # (the input shaft's oil enters behind its front bearing)
        D = sh.d_bore_m
        if not fed or D <= 0:
            continue
        frac = _flow_share(b, sh.id, f"the oil through the bore of shaft {sh.id}")
        for nm in fed:
            L = b.seg_len[nm]
            b.link(nm, "oil", K_STREAM, math.pi * D * L, f"oilsys:{nm}", sub=S_PIPE, frac=frac, D=D, L=L, h=0.0)
    for w, wb in (x for x in b.wheel_brgs if x[1] in jets):
        brg = b.bearing[wb]
        r_r = _needed(d, brg.roller_m, f"bearing.{wb}.roller", "the pumped oil reaches it") / 2
        n_r = _needed(d, brg.rollers, f"bearing.{wb}.rollers", "the pumped oil reaches it")
        cd = p["wheel_bearing.cage_depth_frac"] * r_r
        L_r = brg.width_m
        R_s = b.geo.R_shaft_m[d.wheel(w).shaft]
        A_i, P_i = ht.needle_channel_inner(R_s, R_s + cd, r_r, n_r)
        A_o, P_o = ht.needle_channel_outer(R_s + 2 * r_r - cd, R_s + 2 * r_r, r_r, n_r)
        A_heat = float(ht.channel_heat_area_m2(P_i, L_r, n_r) + ht.channel_heat_area_m2(P_o, L_r, n_r))
        Dh = float(0.5 * (ht.hydraulic_diameter_m(A_i, P_i) + ht.hydraulic_diameter_m(A_o, P_o)))
        b.link(
            wb,
            "oil",
            K_STREAM,
            A_heat,
            f"oilsys:{wb}",
            sub=S_CHANNEL,
            frac=_flow_share(b, wb, "the pumped oil reaches it"),
            D=Dh,
            L=0.0,
            h=0.0,
        )
    for brg in (x for x in b.shaft_brgs if x in jets):
        wdt, dr, Dm, n_r = _bearing_dims(b, brg, "the pumped oil reaches it")
        A_f, P_f = ht.shaft_bearing_channel(Dm / 2 - dr / 2, Dm / 2 + dr / 2, dr / 2, n_r)
        A_heat = float(ht.channel_heat_area_m2(P_f, wdt, n_r))
        b.link(
            brg,
            "oil",
            K_STREAM,
            A_heat,
            f"oilsys:{brg}",
            sub=S_CHANNEL,
            frac=_flow_share(b, brg, "the pumped oil reaches it"),
            D=float(ht.hydraulic_diameter_m(A_f, P_f)),
            L=0.0,
            h=0.0,
        )


def _flow_share(b: _Builder, part: str, why: str) -> float:
    """The share of the pumped flow a jet takes (``oil.flow_share``)."""
    return _needed(b.desc, b.desc.oil.flow_share.get(part), f"oil.flow_share.{part}", why)


def _check_flow_shares(b: _Builder) -> None:
    """Every share of the pumped flow names a shaft (its bore), a bearing or a planetary set (one the pumped oil no
    longer reaches, oil.jets, takes none)."""
    d = b.desc
    parts = {x.id for x in d.shafts} | {x.id for x in d.bearings} | {x.id for x in d.planetary}
    for part in d.oil.flow_share:
        if part not in parts:
            raise ParameterError(
                f"{d.origin}: topology.oil.flow_share.{part} names no shaft, bearing or planetary set of the "
                f"description"
            )


def _planetary_streams(b: _Builder) -> None:
    """The oil system in a planetary set the pumped oil reaches: an imposed h (750 W/(m2 K), seed 3.3) on every
    outer tooth surface of its members in oil.jets, the set's share of the flow split by area."""
    d = b.desc
    for ps in d.planetary:
        _set_streams(b, ps, [m for m in (ps.sun, ps.planet, ps.ring) if m in d.oil.jets])


def _set_streams(b: _Builder, ps, fed: list) -> None:
    if not fed:
        return
    p, W = b.p, b.W
    m_n = ps.module_m
    h_t = (ADDENDUM_COEF + DEDENDUM_COEF) * m_n
    size = {
        ps.sun: (ps.z_sun, W[ps.sun].R_p, 1),
        ps.planet: (ps.z_planet, W[ps.planet].R_p, ps.n_planets),
        ps.ring: (ps.z_ring, m_n * ps.z_ring / 2, 1),
    }
    pl_area = {}
    for nm in fed:
        z, R_p, mult = size[nm]
        pl_area[nm] = mult * ps.width_m * (2 * math.pi * R_p + 2 * z * h_t)
    tot = sum(pl_area.values())
    share = _flow_share(b, ps.id, f"the pumped oil reaches planetary set {ps.id}")
    for nm, A in pl_area.items():
        b.link(
            nm,
            "oil",
            K_STREAM,
            A,
            f"oilsys:{nm}",
            sub=S_IMPOSED,
            frac=share * A / tot,
            D=0.0,
            L=0.0,
            h=p["planetary.h_oil"],
        )


def face_shares(d: Description, h) -> dict:
    """Each boundary a housing's outside exchanges heat with by convection and radiation (its faces but those it
    touches by conduction) -> its share of the outside: as stated (``share``), the rest split evenly between the
    faces without one (for the GRS905: the hot surroundings housing.hot_frac, the cold ones the rest)."""
    conducting = {bd.id for bd in d.boundaries if bd.conductance_w_per_k is not None and h.id in bd.touches}
    faces = [f for f in h.faces if f not in conducting]
    rest = [f for f in faces if f not in h.shares]
    left = (1 - sum(h.shares.values())) / len(rest) if rest else 0.0
    return {f: h.shares.get(f, left) for f in faces}


def _external_links(b: _Builder) -> None:
    """Outside of the housings: convection and radiation to the boundaries each faces (for the GRS905, the hot and
    the cold surroundings), over its share of the external area."""
    p = b.p
    for h in b.desc.housings:
        A_ext = h.area_m2 * p["housing.external_frac"]
        for side, frac in face_shares(b.desc, h).items():
            short = side.removesuffix("_surroundings")  # the GRS905's: extconv:H1-hot
            b.link(h.id, side, K_EXT_CONV, A_ext * frac, f"extconv:{h.id}-{short}")
            b.link(h.id, side, K_EXT_RAD, A_ext * frac, f"extrad:{h.id}-{short}")


def _heat_sources(b: _Builder) -> dict:
    """Where each loss is deposited: mesh heat split evenly between the two wheels (seed 3.2), a planetary set's
    heat (``planetary:<set>``; the first set's also ``planetary``) over its sun, planets and ring by
    losses.PLANETARY_HEAT_SPLIT, bearings into themselves, the lumped losses into the sump (seed 3.2), the retarder
    by effects.RETARDER_HEAT_SPLIT (its housing share into the housing of the output shaft's last bearing),
    synchronizer shift heat into the engaged wheel or ring."""
    ix, sources, d = b.ix, {}, b.desc
    planetary = {m for ps in d.planetary for m in (ps.sun, ps.planet, ps.ring)}
    for m in d.meshes:
        if planetary.isdisjoint(m.wheels):  # a planetary set's meshes: the planetary source
            sources[f"mesh:{m.id}"] = [Share(ix[f"{w}.teeth" if w in b.idle else w], 0.5) for w in m.wheels]
    roles = dict(zip(PLANETARY_HEAT_SPLIT, ("sun", "planet", "ring")))  # PS, PP, PR: the GRS905's members
    for i, ps in enumerate(d.planetary):
        split = [Share(ix[getattr(ps, roles[w])], f) for w, f in PLANETARY_HEAT_SPLIT.items()]
        sources[f"planetary:{ps.id}"] = split
        if i == 0:
            sources["planetary"] = split
    for brg in b.shaft_brgs:
        sources[f"bearing:{brg}"] = [Share(ix[brg], 1.0)]
    for key in ("churning", "wheel_bearings", "synchronizers", "pump"):
        sources[key] = [Share(ix["oil"], 1.0)]
    sources["retarder"] = [Share(ix[_retarder_node(d, nm)], f) for nm, f in RETARDER_HEAT_SPLIT.items()]
    for w in b.idle:
        sources[f"shift:{w}"] = [Share(ix[f"{w}.bulk"], 1.0)]
    for ps in d.planetary:
        sources[f"shift:{ps.ring}"] = [Share(ix[ps.ring], 1.0)]
    return sources


def _retarder_node(d: Description, name: str) -> str:
    """A node of effects.RETARDER_HEAT_SPLIT: the sump, or the housing at the output (that of the output shaft's
    last bearing seated in a housing; the last housing when none is)."""
    if name == "oil":
        return name
    seats = [x.housing for x in d.bearings if x.shaft == d.drive.output_shaft and x.housing is not None]
    return seats[-1] if seats else d.housings[-1].id


def build_network(p: Parameters) -> Network:
    """The full thermal network of the parameter set: nodes (seed 3.1), then links family by family (seed 3.3)."""
    geo = build_geometry(p)
    b = _Builder(p, geo)
    pos, ends = _segment_positions(geo.description)
    _shaft_nodes(b, pos, ends)
    _wheel_nodes(b)
    _other_nodes(b)
    _conduction_links(b, pos)
    _wheel_radial_links(b)
    _bearing_radial_links(b)
    _contact_links(b)
    _immersed_links(b)
    _splash_links(b)
    _bore_and_bearing_streams(b)
    _planetary_streams(b)
    _check_flow_shares(b)
    _external_links(b)
    return b.network(_heat_sources(b))


# ---------------------------------------------------------------------------------------------------------------
# conductances


class ConductanceEvaluator:
    """Evaluates the conductance of every link for given operating conditions (vectorised per kind)."""

    def __init__(self, net: Network, p: Parameters, scales: EffectScales | None = None):
        self.net = net
        self.p = p
        self.oil = net.oil
        self.scales = scales or EffectScales()
        self.G = net.link_G0.copy()
        self.idx = {k: net.links_of_kind(k) for k in range(N_KINDS)}
        self.kp = net.kind_params
        self.h_nom = p["heat.h_nom"]
        self.omega_nom_rad_s = p["heat.omega_nom_rad_s"]
        self.exp_splash = p["heat.splash_exponent"]
        self.h_house = p["housing.h_oil"]
        self.h_air = p["housing.h_air"]
        self.eps = p["housing.emissivity"]
        oil = net.geometry.description.oil
        # a pump on a shaft: oil volume per radian of the shaft (the GRS905's layshaft); a motor-driven pump: its flow
        self.pump_speed = None if oil.pump_shaft is None else net.speed_names.index(oil.pump_shaft)
        self.flow_m3_per_rad = (oil.pump_flow or 0.0) if oil.pump_shaft is not None else 0.0
        self.flow_m3_s = (oil.pump_flow or 0.0) if oil.pump_shaft is None else 0.0
        # a motor pump that stops with the machine (oil.pump_stops_below): it reads the input shaft's speed
        self.pump_stop_rad_s = oil.pump_stops_below_rad_s or 0.0
        d = net.geometry.description
        self.pump_col = self.pump_speed if self.pump_speed is not None else net.speed_names.index(d.drive.input_shaft)
        self.n_nodes = net.n
        self.ext_rad_idx = self.idx[K_EXT_RAD]
        self.ext_rad_a = net.link_a[self.ext_rad_idx]
        self.ext_rad_b = net.link_b[self.ext_rad_idx] - net.n
        self.generation = 0  # counts full evaluations: while it stands, only boundary links' G have moved

    def oil_mass_flow_kg_s(self, omega_ls_rad_s, rho_kg_m3):
        """Oil-system mass flow: linear in the pump shaft's (the layshaft's) speed (seed 3.3, Fig 12); a
        motor-driven pump's is its flow, none while the input shaft (``omega_ls_rad_s`` then: the speed at
        ``pump_col``) turns at or below ``oil.pump_stops_below`` when the description gives it."""
        if self.pump_speed is None:
            if self.pump_stop_rad_s > 0.0:
                return rho_kg_m3 * self.flow_m3_s * (np.abs(omega_ls_rad_s) > self.pump_stop_rad_s)
            return rho_kg_m3 * self.flow_m3_s
        return rho_kg_m3 * self.flow_m3_per_rad * abs(omega_ls_rad_s)

    def _splash_h(self, omega_rad_s):
        """Splash coefficient h_nom (|w| / w_nom)^0.6 (Eq 59)."""
        return self.h_nom * (omega_rad_s / self.omega_nom_rad_s) ** self.exp_splash

    def _speeds(self, kind: int, speeds: np.ndarray, floor: float | None = None) -> np.ndarray:
        omega_rad_s = speeds[..., self.kp[kind]["speed"].astype(int)]
        return omega_rad_s if floor is None else np.maximum(omega_rad_s, floor)

    def _oil_side(self, G, op, speeds, low_range):
        """Splash (Eq 59), immersed wheels (Eq 46-51, fling-off Eq 54-58), immersed bearings (Eq 52-53), bearing
        splash (Eq 63-64) and the ring gear."""
        G0, kp, sc = self.net.link_G0, self.kp, self.scales
        i = self.idx[K_SPLASH]  # idle-wheel teeth (group 0) and the output shaft (group 1)
        if i.size:
            h = self._splash_h(self._speeds(K_SPLASH, speeds))
            G[..., i] = G0[i] * (h * np.where(kp[K_SPLASH]["group"] == 0, sc.teeth_oil_h, 1.0))
        i = self.idx[K_IMM_GEAR]
        if i.size:
            k = kp[K_IMM_GEAR]
            omega_rad_s = self._speeds(K_IMM_GEAR, speeds, MIN_SPEED_RAD_S)
            h = (
                ht.nusselt_rotating_cylinder(ht.reynolds_gear(k["R_p"], omega_rad_s, op.nu_m2_s), op.pr)
                * op.k_w_per_mk
                / k["R_p"]
            )
            fo = ht.fling_off_hA(
                k["z"], k["width"], k["h_t"], k["R_p"], k["h_i"], omega_rad_s, op.k_w_per_mk, op.alpha_m2_s, op.nu_m2_s
            )
            G[..., i] = G0[i] * h + fo.hA_w_per_k
        i = self.idx[K_IMM_BRG]
        if i.size:
            Dm = kp[K_IMM_BRG]["Dm"]
            re = ht.reynolds_bearing(Dm, self._speeds(K_IMM_BRG, speeds, MIN_SPEED_RAD_S), op.nu_m2_s)
            G[..., i] = G0[i] * (ht.nusselt_rotating_cylinder(re, op.pr) * op.k_w_per_mk / (Dm / 2))
        i = self.idx[K_BRG_SPLASH]
        if i.size:
            k = kp[K_BRG_SPLASH]
            G[..., i] = G0[i] * ht.harris_bearing_h_w_per_m2k(
                self._speeds(K_BRG_SPLASH, speeds, MIN_SPEED_RAD_S),
                op.nu_m2_s,
                k["d_roller"],
                k["Dm"],
                op.k_w_per_mk,
                op.pr,
            )
        i = self.idx[K_RING]
        if i.size:
            if low_range:
                G[..., i] = G0[i] * self.h_house
            else:
                # rotating with the sun at high range: splash (Eq 59), never below the stationary housing value
                # (the ring always sits in oil; at standstill it must not be thermally isolated)
                G[..., i] = G0[i] * np.maximum(self._splash_h(self._speeds(K_RING, speeds)), self.h_house)

    def _streams(self, G, op, speeds):
        """Oil-system streams (Eq 65-80): flow linear in layshaft speed, effectiveness-limited."""
        i = self.idx[K_STREAM]
        if not i.size:
            return
        kp = self.kp[K_STREAM]
        omega_ls_rad_s = speeds[..., self.pump_col]
        if np.ndim(omega_ls_rad_s):
            omega_ls_rad_s = omega_ls_rad_s[..., None]  # a batch of operating points (evaluate)
        mdot_tot = self.oil_mass_flow_kg_s(omega_ls_rad_s, op.rho_kg_m3)
        mdot = np.maximum(mdot_tot * kp["frac"], 1e-9)
        sub = kp["sub"]
        h = np.empty(np.shape(mdot))
        pipe = sub == S_PIPE
        if pipe.any():
            D = kp["D"][pipe]
            re = ht.pipe_reynolds(mdot[..., pipe], op.mu_pa_s, D)
            h[..., pipe] = ht.h_from_nusselt_w_per_m2k(ht.pipe_nusselt(re, op.pr, kp["L"][pipe], D), op.k_w_per_mk, D)
        ch = sub == S_CHANNEL
        if ch.any():
            h[..., ch] = ht.channel_h_w_per_m2k(op.k_w_per_mk, kp["D"][ch])
        imp = sub == S_IMPOSED
        if imp.any():
            h[..., imp] = kp["h"][imp] * self.scales.planet_oil_h
        hA = self.net.link_G0[i] * h
        G[..., i] = np.where(mdot_tot > 0, ht.oil_system_conductance_w_per_k(hA, mdot, op.cp_j_per_kgk), 0.0)

    def evaluate(
        self,
        T_oil_c: float,
        speeds: np.ndarray,
        gear_row: int,
        mesh_torque_row: np.ndarray,
        low_range: bool,
        T_nodes_c: np.ndarray | None = None,
        T_bc_c: np.ndarray | None = None,
    ) -> np.ndarray:
        """Conductance of every link [W/K]. speeds: |rad/s| per the network's speed_names; T_nodes/T_bc for
        radiation.

        ``speeds`` may be a batch (..., len(speed_names)) of operating points at the one oil temperature, gear and
        range: then a new array (..., n_links) is returned, equal element by element to one call per point (the
        oil properties stay scalars as in a single call; the onboard build tabulates its laws this way)."""
        speeds = np.asarray(speeds)
        self.generation += 1  # every full evaluation (radiation alone keeps it: it moves only boundary links)
        G = self.G if speeds.ndim < 2 else np.broadcast_to(self.net.link_G0, speeds.shape[:-1] + self.G.shape).copy()
        op = self.oil.properties(T_oil_c)
        i = self.idx[K_CONTACT]  # contacts: active when the mesh carries torque (Eq 45)
        if i.size:
            G[..., i] = self.net.link_G0[i] * (mesh_torque_row[self.kp[K_CONTACT]["mesh"].astype(int)] != 0)
        self._oil_side(G, op, speeds, low_range)
        self._streams(G, op, speeds)
        i = self.idx[K_EXT_CONV]
        if i.size:
            G[..., i] = self.net.link_G0[i] * self.h_air * self.scales.housing_air_h
        self._update_radiation(G, T_nodes_c, T_bc_c)
        return G

    def _update_radiation(self, G, T_nodes_c, T_bc_c):
        # radiation, linearised around the current temperatures (Eq 6, 81)
        i = self.ext_rad_idx
        if i.size:
            if T_nodes_c is None or T_bc_c is None:
                h = ht.radiation_h_w_per_m2k(self.eps, 60.0, 40.0)
            else:
                h = ht.radiation_h_w_per_m2k(self.eps, T_nodes_c[..., self.ext_rad_a], T_bc_c[..., self.ext_rad_b])
            G[..., i] = self.net.link_G0[i] * h

    def evaluate_cached(
        self, T_oil_c, speeds, gear_row, mesh_torque_row, low_range, T_nodes_c, T_bc_c, speed_rtol=0.01, oil_atol_c=0.25
    ):
        """Like `evaluate`, but reuses the speed- and oil-dependent conductances while the gear is the same, the
        speeds are within `speed_rtol` and the oil within `oil_atol_c` of the last full evaluation (radiation is
        always updated). The error this allows is below 1 % on any conductance."""
        c = getattr(self, "_cache", None)
        if (
            c is not None
            and c[0] == gear_row
            and abs(T_oil_c - c[1]) < oil_atol_c
            and np.all(np.abs(speeds - c[2]) <= speed_rtol * np.maximum(c[2], 1.0))
        ):
            G = c[3]
            self._update_radiation(G, T_nodes_c, T_bc_c)
            return G
        G = self.evaluate(T_oil_c, speeds, gear_row, mesh_torque_row, low_range, T_nodes_c, T_bc_c)
        self._cache = (gear_row, float(T_oil_c), np.array(speeds, dtype=float), G)
        return G

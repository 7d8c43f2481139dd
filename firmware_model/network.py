"""The gearbox thermal network as data (seed section 3.1 thermal masses, 3.3 heat paths).

`build_network(params)` derives every geometric quantity the equations need from the parameter set and returns a
`Network`: node names and heat capacities, and links. A link joins two nodes, or a node and a boundary
temperature, with a conductance that is either constant or evaluated by its *kind* from the oil temperature, the
shaft speeds, the gear and the oil flow. The full reference plant integrates this network as it is; the onboard
model is a reduction of the same description (nodes merged, links summed), so the two cannot drift apart.

All in SI; temperatures in degC.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from firmware_model.physics import heat_transfer as ht
from firmware_model.physics import oil as oilprops
from firmware_model.components import IDLE_WHEELS, LAYSHAFT_WHEELS, PAIRS, SHAFT_BEARINGS, WHEEL_BEARINGS
from firmware_model.errors import ParameterError
from firmware_model.physics.kinematics import MESHES, SPEED_NAMES
from firmware_model.physics.losses import mesh_geometry
from firmware_model.parameters import Parameters

#: boundary temperatures (seed section 3, boundary conditions)
BOUNDARIES = ("engine_shaft", "flywheel_cover", "support_beam", "end_yoke", "hot_surroundings",
              "cold_surroundings", "coolant", "ambient")

# link kinds
K_CONST, K_CONTACT, K_SPLASH, K_IMM_GEAR, K_IMM_BRG, K_BRG_SPLASH, K_STREAM, K_RING, K_EXT_CONV, K_EXT_RAD = range(10)
KIND_NAMES = ("conduction", "gear_contact", "splash", "immersed_gear", "immersed_bearing", "bearing_splash",
              "oil_system", "ring_oil", "external_convection", "external_radiation")
# oil-system stream sub-kinds
S_PIPE, S_CHANNEL, S_IMPOSED = range(3)

SHAFT_SEGMENTS = {
    "IS": ("IS@bulk", "IS@BIF", "IS@LI"),
    "LS": ("LS@BLF", "LS@LL", "LS@3L", "LS@2L", "LS@1L", "LS@CL", "LS@RL", "LS@BLR"),
    "MS": ("MS@BIM", "MS@3M", "MS@2M", "MS@1M", "MS@CM", "MS@RM", "MS@BMR", "MS@PS"),
    "OS": ("OS@carrier", "OS@bulk", "OS@BO", "OS@EY"),
}
SHAFT_OF_BEARING = {"BIF": "IS", "BLF": "LS", "BLR": "LS", "BIM": "MS", "BMR": "MS", "BO": "OS"}
HOUSING_OF_BEARING = {"BIF": "H1", "BLF": "H1", "BLR": "H2", "BMR": "H2", "BO": "H3"}


@dataclass(frozen=True)
class Wheel:
    """Geometry of one gear wheel (radii in m)."""
    name: str
    z: int
    m_n: float
    beta: float
    width: float
    R_p: float
    R_a: float
    R_f: float
    R_b: float
    R_in: float       # inner radius (bore, or 70 % of base radius for wheels cut into the layshaft)
    h_t: float
    x: float          # axial position


@dataclass
class Network:
    nodes: tuple
    C_j_per_k: np.ndarray
    # links: endpoint a is always a node; b is a node index, or n_nodes + boundary index
    link_a: np.ndarray
    link_b: np.ndarray
    link_kind: np.ndarray
    link_G0: np.ndarray          # constant part / area-like factor, meaning depends on kind
    link_name: tuple
    # per-kind parameters (arrays aligned with the links of that kind, in link order)
    kind_params: dict
    #: heat-source name -> list of (node index, fraction)
    sources: dict
    geometry: dict = field(default_factory=dict)

    @property
    def n(self) -> int:
        return len(self.nodes)

    def index(self, name: str) -> int:
        return self.nodes.index(name)

    def links_of_kind(self, kind: int) -> np.ndarray:
        return np.flatnonzero(self.link_kind == kind)


def _wheel(name, z, m_n, beta, alpha_n, width, R_in, x, addendum=1.0) -> Wheel:
    R_p = m_n * z / (2.0 * math.cos(beta))
    alpha_t = math.atan(math.tan(alpha_n) / math.cos(beta))
    return Wheel(name, z, m_n, beta, width, R_p, R_p + addendum * m_n, R_p - 1.25 * m_n, R_p * math.cos(alpha_t),
                 R_in, 2.25 * m_n, x)


def build_geometry(p: Parameters) -> dict:
    """Every derived geometric quantity: wheels, meshes, segments, masses. Keys documented inline."""
    an = p["gear.alpha_n"]
    a = p["gear.center_distance"]
    R_is, R_ls, R_ms, R_os = (p[f"shaft.{s}.d_out"] / 2 for s in ("IS", "LS", "MS", "OS"))
    wheels = {}
    meshes = {}
    xs = {"LI": p["wheel.x_LI"], "3M": p["wheel.x_3M"], "2M": p["wheel.x_2M"], "1M": p["wheel.x_1M"],
          "CM": p["wheel.x_CM"], "RM": p["wheel.x_RM"]}
    x_blf = p["shaft.LS.x_BLF"]
    for pair, (iw, lw) in PAIRS.items():
        g = f"gear.{pair}"
        m_n, beta = p[f"{g}.m_n"], p[f"{g}.beta"]
        bore = (p["wheel.bore_LI"] if iw == "LI" else p["wheel.bore_main"]) / 2
        wheels[iw] = _wheel(iw, int(p[f"{g}.z1"]), m_n, beta, an, p[f"{g}.width1"], bore, xs[iw])
        lw_tmp = _wheel(lw, int(p[f"{g}.z2"]), m_n, beta, an, p[f"{g}.width2"], R_ls, xs[iw])
        if lw in ("1L", "CL", "RL"):
            # cut into the layshaft: inner diameter taken as 70 % of the base diameter (seed 3.3)
            R_in = p["heat.cut_wheel_inner_frac"] * lw_tmp.R_b
            lw_tmp = Wheel(**{**lw_tmp.__dict__, "R_in": max(R_in, R_ls)})
        wheels[lw] = lw_tmp
        if pair != "R":
            meshes[pair] = mesh_geometry(int(p[f"{g}.z1"]), int(p[f"{g}.z2"]), m_n, an, beta, a,
                                         min(p[f"{g}.width1"], p[f"{g}.width2"]))
    # reverse: RL (layshaft) drives RI, RI drives RM; standard centre distances (no profile shift)
    m_r, b_r = p["gear.R.m_n"], p["gear.R.beta"]
    zRL, zRI, zRM = int(p["gear.R.z2"]), int(p["gear.R.z_idler"]), int(p["gear.R.z1"])
    wr = min(p["gear.R.width1"], p["gear.R.width2"], p["gear.R.width_idler"])
    meshes["R"] = mesh_geometry(zRL, zRI, m_r, an, b_r, m_r * (zRL + zRI) / (2 * math.cos(b_r)), wr)
    meshes["RI"] = mesh_geometry(zRI, zRM, m_r, an, b_r, m_r * (zRI + zRM) / (2 * math.cos(b_r)), wr)
    wheels["RI"] = _wheel("RI", zRI, m_r, b_r, an, p["gear.R.width_idler"], 0.02, xs["RM"])
    # planetary: sun drives planets; planet drives (fixed) ring relative to the carrier
    zs, zp, zr = int(p["planetary.z_sun"]), int(p["planetary.z_planet"]), int(p["planetary.z_ring"])
    mp, bp, wp = p["planetary.m_n"], p["planetary.beta"], p["planetary.width"]
    a_p = mp * (zs + zp) / (2 * math.cos(bp))
    meshes["PSP"] = mesh_geometry(zs, zp, mp, an, bp, a_p, wp)
    meshes["PPR"] = mesh_geometry(zp, zr, mp, an, bp, a_p, wp, internal=True)
    wheels["PS"] = _wheel("PS", zs, mp, bp, an, wp, R_ms, p["shaft.MS.x_PS"])
    wheels["PP"] = _wheel("PP", zp, mp, bp, an, wp, 0.35 * mp * zp / 2, p["shaft.MS.x_PS"])

    # layshaft wheel immersion: oil surface below the layshaft axis at BLF, rising toward the rear (5 deg tilt)
    vol = p["oil.volume"]
    level_drop = max(0.0, (p.get("oil.nominal_volume", vol) - vol)) / p["oil.free_surface_area"]
    immersion = {}
    for w in LAYSHAFT_WHEELS:
        d_below = p["oil.level_below_ls_axis"] + level_drop - (wheels[w].x - x_blf) * math.tan(p["oil.inclination"])
        immersion[w] = float(np.clip(wheels[w].R_a - d_below, 0.0, 2 * wheels[w].R_a))
    immersion["RI"] = max(0.0, p["gear.R.idler_immersion"] - level_drop)
    return {"wheels": wheels, "meshes": meshes, "immersion_m": immersion, "level_drop_m": level_drop,
            "R_shaft": {"IS": R_is, "LS": R_ls, "MS": R_ms, "OS": R_os}}


def _segment_lengths(xs: list, x_front: float, x_rear: float) -> list:
    """Each segment spans from the midpoint with its front neighbour to the midpoint with its rear neighbour."""
    bounds = [x_front] + [(xs[i] + xs[i + 1]) / 2 for i in range(len(xs) - 1)] + [x_rear]
    return [max(bounds[i + 1] - bounds[i], 1e-3) for i in range(len(xs))]


def build_network(p: Parameters) -> Network:
    geo = build_geometry(p)
    W = geo["wheels"]
    st_rho, st_k, st_cp = p["material.steel.rho"], p["material.steel.k"], p["material.steel.cp"]
    nodes: list = []
    C: list = []

    def add(name, C_j_per_k):
        if C_j_per_k <= 0 or not math.isfinite(C_j_per_k):
            raise ParameterError(f"thermal mass of node {name} is {C_j_per_k:g} J/K; it must be positive")
        nodes.append(name)
        C.append(C_j_per_k)

    # ---- shaft segments (seed 3.1, Fig 3)
    pos = {
        "IS": [0.0, p["bearing.BIF.x"], W["LI"].x],
        "LS": [p["shaft.LS.x_BLF"]] + [W[w].x for w in LAYSHAFT_WHEELS] + [p["shaft.LS.x_BLR"]],
        "MS": [p["bearing.BIM.x"]] + [W[w].x for w in IDLE_WHEELS[1:]] + [p["bearing.BMR.x"], p["shaft.MS.x_PS"]],
        "OS": [p["shaft.OS.x_carrier"], p["shaft.OS.x_bulk"], p["shaft.OS.x_BO"], p["shaft.OS.x_EY"]],
    }
    ends = {"IS": (p["shaft.IS.x_front"], p["shaft.IS.x_rear"]),
            "LS": (pos["LS"][0] - 0.015, pos["LS"][-1] + 0.015),
            "MS": (pos["MS"][0] - 0.01, pos["MS"][-1] + 0.02),
            "OS": (pos["OS"][0] - 0.02, pos["OS"][-1] + 0.02)}
    seg_len = {}
    for s, names in SHAFT_SEGMENTS.items():
        ro, ri = p[f"shaft.{s}.d_out"] / 2, p[f"shaft.{s}.d_bore"] / 2
        lens = _segment_lengths(pos[s], *ends[s])
        for nm, L in zip(names, lens):
            seg_len[nm] = L
            m = st_rho * math.pi * (ro ** 2 - ri ** 2) * L
            if nm == "OS@carrier":
                m = p["shaft.OS.carrier_mass"]
            add(nm, m * st_cp)

    # ---- wheels: idle wheels split into teeth and bulk (seed 3.1)
    shell = p["gear.teeth_shell_modules"]
    hub = p["wheel.hub_mass_factor"]
    wheel_mass = {}
    for w in IDLE_WHEELS:
        g = W[w]
        R_sh = g.R_f - shell * g.m_n
        m_teeth = st_rho * g.width * (math.pi * (g.R_f ** 2 - R_sh ** 2) + 0.5 * math.pi * (g.R_a ** 2 - g.R_f ** 2))
        m_bulk = st_rho * g.width * math.pi * (R_sh ** 2 - g.R_in ** 2) * hub
        wheel_mass[w] = (m_teeth, m_bulk)
        add(f"{w}.teeth", m_teeth * st_cp)
        add(f"{w}.bulk", m_bulk * st_cp)
    for w in LAYSHAFT_WHEELS + ("RI",):
        g = W[w]
        R_inner = geo["R_shaft"]["LS"] if w != "RI" else g.R_in
        m = st_rho * g.width * (math.pi * (g.R_f ** 2 - R_inner ** 2) + 0.5 * math.pi * (g.R_a ** 2 - g.R_f ** 2))
        wheel_mass[w] = m
        add(w, m * st_cp)
    # ---- planetary
    add("PS", p["planetary.mass_sun"] * st_cp)
    add("PP", p["planetary.mass_planets"] * st_cp)
    add("PR", p["planetary.mass_ring"] * st_cp)
    # ---- bearings
    for b in SHAFT_BEARINGS:
        add(b, p[f"bearing.{b}.mass"] * st_cp)
    for b in WHEEL_BEARINGS:
        add(b, (p["wheel_bearing.mass_3B"] if b == "3B" else p["wheel_bearing.mass_needle"]) * st_cp)
    # ---- housings
    mats = {"H1": "aluminium", "H2": "cast_iron", "H3": "aluminium"}
    for h in ("H1", "H2", "H3"):
        add(h, p[f"housing.mass_{h}"] * p[f"material.{mats[h]}.cp"])
    # ---- sump
    rho_oil_40 = float(oilprops.density_kg_m3(60.0))
    cp_oil = float(oilprops.specific_heat_j_per_kgk(60.0))
    add("oil", p["oil.volume"] * rho_oil_40 * cp_oil)

    n = len(nodes)
    ix = {nm: i for i, nm in enumerate(nodes)}
    bx = {b: n + i for i, b in enumerate(BOUNDARIES)}
    la, lb, lk, lg, lname = [], [], [], [], []
    kp = {k: [] for k in range(10)}

    def link(a, b, kind, G0, name, **params):
        la.append(ix[a])
        lb.append(ix[b] if b in ix else bx[b])
        lk.append(kind)
        lg.append(float(G0))
        lname.append(name)
        kp[kind].append(params)

    # ---- linear conduction along shafts (Eq 43)
    for s, names in SHAFT_SEGMENTS.items():
        ro, ri = p[f"shaft.{s}.d_out"] / 2, p[f"shaft.{s}.d_bore"] / 2
        A = math.pi * (ro ** 2 - ri ** 2)
        for i in range(len(names) - 1):
            G = ht.linear_conductance_w_per_k(st_k, A, pos[s][i], pos[s][i + 1])
            link(names[i], names[i + 1], K_CONST, G, f"cond:{names[i]}-{names[i + 1]}")
    # to the boundary structures (Eq 43)
    link("IS@bulk", "engine_shaft", K_CONST, p["housing.G_IS_engine"], "bc:IS-engine_shaft")
    link("OS@EY", "end_yoke", K_CONST, p["housing.G_OS_endyoke"], "bc:OS-end_yoke")
    link("H1", "flywheel_cover", K_CONST, p["housing.G_H1_flywheel"], "bc:H1-flywheel_cover")
    link("H2", "support_beam", K_CONST, p["housing.G_H2_beam"], "bc:H2-support_beam")
    kj = p["housing.k_joint"]
    link("H1", "H2", K_CONST, ht.linear_conductance_w_per_k(kj, p["housing.A_H1H2"], p["housing.x_H1"], p["housing.x_H2"]),
         "cond:H1-H2")
    link("H2", "H3", K_CONST, ht.linear_conductance_w_per_k(kj, p["housing.A_H2H3"], p["housing.x_H2"], p["housing.x_H3"]),
         "cond:H2-H3")

    # ---- radial conduction (Eq 44)
    sf_tb, sf_lw = p["heat.sf_teeth_bulk"], p["heat.sf_layshaft_wheel"]
    shaft_of_idle = {"LI": "IS@LI", **{w: f"MS@{w}" for w in IDLE_WHEELS[1:]}}
    shaft_R_of_idle = {"LI": geo["R_shaft"]["IS"], **{w: geo["R_shaft"]["MS"] for w in IDLE_WHEELS[1:]}}
    d_roll_wb = p["wheel_bearing.d_roller"]
    for w, wb in zip(IDLE_WHEELS, WHEEL_BEARINGS):
        g = W[w]
        D_teeth = g.R_a + g.R_f                      # mean of tip and root diameters
        D_bulk = g.R_b + g.R_in                      # mean of base and inner diameters
        link(f"{w}.teeth", f"{w}.bulk", K_CONST,
             ht.radial_conductance_w_per_k(st_k, g.width, D_teeth, D_bulk, sf_tb), f"rad:{w}.teeth-bulk")
        sf_b = p["wheel_bearing.sf_radial_tapered"] if wb == "3B" else p["wheel_bearing.sf_radial_needle"]
        D_shaft = 2 * shaft_R_of_idle[w]
        Dm = D_shaft + d_roll_wb
        # bulk -> bearing: solid from the bulk's representative diameter to the bore, then the bearing's outer half
        G_solid = ht.radial_conductance_w_per_k(st_k, g.width, D_bulk, 2 * g.R_in, 1.0)
        G_outer = ht.radial_conductance_w_per_k(st_k, g.width, 2 * g.R_in, Dm, sf_b)
        link(f"{w}.bulk", wb, K_CONST, 1.0 / (1.0 / G_solid + 1.0 / G_outer), f"rad:{w}.bulk-{wb}")
        link(wb, shaft_of_idle[w], K_CONST, ht.radial_conductance_w_per_k(st_k, g.width, Dm, 0.7 * D_shaft, sf_b),
             f"rad:{wb}-{shaft_of_idle[w]}")
    for w in LAYSHAFT_WHEELS:
        g = W[w]
        D_w = g.R_b + g.R_in
        D_s = 0.7 * 2 * geo["R_shaft"]["LS"]
        link(w, f"LS@{w}", K_CONST, ht.radial_conductance_w_per_k(st_k, g.width, D_w, D_s, sf_lw), f"rad:{w}-LS@{w}")
    # shaft bearings to shafts and housing
    for b in SHAFT_BEARINGS:
        typ = "ball" if b == "BO" else "tapered"
        sf = p[f"bearing.sf_radial_{typ}"]
        d_in, d_out, wdt = p[f"bearing.{b}.d_bore"], p[f"bearing.{b}.d_out"], p[f"bearing.{b}.width"]
        Dm = 0.5 * (d_in + d_out)
        s = SHAFT_OF_BEARING[b]
        seg = {"BIF": "IS@BIF", "BLF": "LS@BLF", "BLR": "LS@BLR", "BIM": "MS@BIM", "BMR": "MS@BMR", "BO": "OS@BO"}[b]
        link(b, seg, K_CONST, ht.radial_conductance_w_per_k(st_k, wdt, Dm, 0.7 * d_in, sf), f"rad:{b}-{seg}")
        if b == "BIM":
            # the pilot bearing sits inside the rear end of the input shaft
            link(b, "IS@LI", K_CONST, ht.radial_conductance_w_per_k(st_k, wdt, 1.3 * d_out, Dm, sf), f"rad:{b}-IS@LI")
        else:
            h = HOUSING_OF_BEARING[b]
            k_h = p["material.cast_iron.k"] if h == "H2" else p["material.aluminium.k"]
            link(b, h, K_CONST, ht.radial_conductance_w_per_k(min(k_h, st_k), wdt, 1.3 * d_out, Dm, sf), f"rad:{b}-{h}")
    # planetary: planets to carrier via their bearings (sf 0.18), sun to main shaft (spline, sf 0.4)
    gp, gs = W["PP"], W["PS"]
    n_pl = int(p["planetary.n_planets"])
    link("PP", "OS@carrier", K_CONST,
         n_pl * ht.radial_conductance_w_per_k(st_k, gp.width, gp.R_b + gp.R_f, 2 * gp.R_in, p["planetary.sf_planet_carrier"]),
         "rad:PP-OS@carrier")
    link("PS", "MS@PS", K_CONST,
         ht.radial_conductance_w_per_k(st_k, gs.width, gs.R_b + gs.R_in, 0.7 * 2 * gs.R_in, p["planetary.sf_sun_spline"]),
         "rad:PS-MS@PS")
    # ring gear held by the range synchronizer to the housing: no conduction path modelled (seed lists none)

    # ---- gear contact conductance between active wheels (Eq 45)
    tcc, whz, cfrac = p["heat.TCC"], p["heat.w_Hz"], p["heat.contact_length_frac"]
    for pair, (iw, lw) in PAIRS.items():
        wmin = min(W[iw].width, W[lw].width)
        if pair == "R":
            G = ht.gear_contact_conductance_w_per_k(tcc, wmin, whz, cfrac)
            link("RL", "RI", K_CONTACT, G, "contact:RL-RI", mesh=MESHES.index("R"))
            link("RI", "RM.teeth", K_CONTACT, G, "contact:RI-RM", mesh=MESHES.index("RI"))
        else:
            link(f"{iw}.teeth", lw, K_CONTACT, ht.gear_contact_conductance_w_per_k(tcc, wmin, whz, cfrac),
                 f"contact:{iw}-{lw}", mesh=MESHES.index(pair))
    Gp = n_pl * ht.gear_contact_conductance_w_per_k(tcc, p["planetary.width"], whz, cfrac)
    link("PS", "PP", K_CONTACT, Gp, "contact:PS-PP", mesh=MESHES.index("PSP"))
    link("PP", "PR", K_CONTACT, Gp, "contact:PP-PR", mesh=MESHES.index("PPR"))

    # ---- convection to the sump
    spd = {nm: SPEED_NAMES.index(nm) for nm in SPEED_NAMES}
    # layshaft wheels and reverse idler: immersed rotating cylinder (Eq 46-53) + fling-off (Eq 54-58)
    for w in LAYSHAFT_WHEELS + ("RI",):
        g = W[w]
        h_i = geo["immersion_m"][w]
        if h_i <= 0:
            continue
        w_in = 0.0 if w in ("1L", "CL", "RL") else p["wheel.side_width_in_frac"] * g.width
        h_i_p = min(h_i, 2 * g.R_p)
        A = float(ht.immersed_gear_area_m2(g.R_p, g.width, g.R_in, w_in, h_i_p, g.z, g.h_t, g.beta))
        link(w, "oil", K_IMM_GEAR, A, f"imm:{w}", speed=spd["RI" if w == "RI" else "LS"], R_p=g.R_p, z=g.z,
             width=g.width, h_t=g.h_t, h_i=h_i_p)
    # layshaft bearings partly immersed (Eq 52-53)
    for b in ("BLF", "BLR"):
        d_in, d_out, wdt = p[f"bearing.{b}.d_bore"], p[f"bearing.{b}.d_out"], p[f"bearing.{b}.width"]
        dr = p[f"bearing.{b}.d_roller"]
        Dm = 0.5 * (d_in + d_out)
        A = float(ht.immersed_bearing_area_m2(Dm - dr, Dm + dr, p[f"bearing.{b}.n_rollers"], dr, wdt,
                                              p[f"bearing.{b}.immersion"]))
        link(b, "oil", K_IMM_BRG, A, f"imm:{b}", speed=spd["LS"], Dm=Dm)
    # idle-wheel teeth: splash with h_nom (Eq 59-61)
    covered = bool(p["wheel.covered_sides"])
    for w in IDLE_WHEELS:
        g = W[w]
        if w in ("CM", "RM") or not covered:
            A = float(ht.wheel_area_free_sides_m2(g.R_p, g.width, g.z, g.h_t, g.beta, g.R_in))
        else:
            A = float(ht.wheel_area_covered_sides_m2(g.R_p, g.width, g.z, g.h_t, g.beta))
        link(f"{w}.teeth", "oil", K_SPLASH, A, f"splash:{w}.teeth", speed=spd[w], group=0)
    # output shaft (Eq 62)
    A_os = float(ht.cylinder_area_m2(p["shaft.OS.d_out"], p["shaft.OS.oil_wetted_length"]))
    link("OS@bulk", "oil", K_SPLASH, A_os, "splash:OS", speed=spd["OS"], group=1)
    # ring gear: splash at high range, 200 W/(m2 K) like the housing at low range (seed 3.3)
    link("PR", "oil", K_RING, p["planetary.ring_outer_area"], "ring:PR", speed=spd["PR"])
    # shaft bearings except BIM: Harris oil splash (Eq 63-64)
    for b in SHAFT_BEARINGS:
        if b == "BIM":
            continue
        d_in, d_out, wdt = p[f"bearing.{b}.d_bore"], p[f"bearing.{b}.d_out"], p[f"bearing.{b}.width"]
        dr = p[f"bearing.{b}.d_roller"]
        Dm = 0.5 * (d_in + d_out)
        A = float(ht.bearing_internal_area_m2(Dm - dr, Dm + dr, p[f"bearing.{b}.n_rollers"], dr, wdt))
        link(b, "oil", K_BRG_SPLASH, A, f"bsplash:{b}", speed=spd[SHAFT_OF_BEARING[b]], Dm=Dm, d_roller=dr)
    # housings to oil (200 W/(m2 K) on 90 % of 1.9 m2, split 50/35/15)
    A_int = p["housing.internal_area"] * p["housing.oil_covered_frac"]
    for h in ("H1", "H2", "H3"):
        link(h, "oil", K_CONST, p["housing.h_oil"] * A_int * p[f"housing.internal_split_{h}"], f"hoil:{h}")

    # ---- oil-system streams (Eq 65-80, planetary 750 W/(m2 K)); heat goes to the sump via the returning oil
    # input and main shaft bores (Eq 65-68)
    for s, frac in (("IS", p["oil_system.frac_IS_bore"]), ("MS", p["oil_system.frac_MS_bore"])):
        D = p[f"shaft.{s}.d_bore"]
        if D <= 0:
            continue
        for nm in SHAFT_SEGMENTS[s]:
            if nm == "IS@bulk":
                continue      # oil enters the input shaft behind its front bearing
            L = seg_len[nm]
            link(nm, "oil", K_STREAM, math.pi * D * L, f"oilsys:{nm}", sub=S_PIPE, frac=frac, D=D, L=L, h=0.0)
    # needle bearings (Eq 69-74, 77-80)
    r_r = d_roll_wb / 2
    cd = p["wheel_bearing.cage_depth_frac"] * r_r
    for w, wb in zip(IDLE_WHEELS, WHEEL_BEARINGS):
        n_r = p["wheel_bearing.n_rollers_LB"] if wb == "LB" else p["wheel_bearing.n_rollers_main"]
        R_s = shaft_R_of_idle[w]
        A_i, P_i = ht.needle_channel_inner(R_s, R_s + cd, r_r, n_r)
        A_o, P_o = ht.needle_channel_outer(R_s + 2 * r_r - cd, R_s + 2 * r_r, r_r, n_r)
        A_heat = float(ht.channel_heat_area_m2(P_i, p["wheel_bearing.length_roller"], n_r)
                       + ht.channel_heat_area_m2(P_o, p["wheel_bearing.length_roller"], n_r))
        Dh = float(0.5 * (ht.hydraulic_diameter_m(A_i, P_i) + ht.hydraulic_diameter_m(A_o, P_o)))
        link(wb, "oil", K_STREAM, A_heat, f"oilsys:{wb}", sub=S_CHANNEL, frac=p["oil_system.frac_needle_each"], D=Dh,
             L=0.0, h=0.0)
    # shaft bearings BIM and BMR in the oil system (Eq 75-80)
    for b in ("BIM", "BMR"):
        d_in, d_out = p[f"bearing.{b}.d_bore"], p[f"bearing.{b}.d_out"]
        dr = p[f"bearing.{b}.d_roller"]
        Dm = 0.5 * (d_in + d_out)
        n_r = p[f"bearing.{b}.n_rollers"]
        A_f, P_f = ht.shaft_bearing_channel(Dm / 2 - dr / 2, Dm / 2 + dr / 2, dr / 2, n_r)
        A_heat = float(ht.channel_heat_area_m2(P_f, p[f"bearing.{b}.width"], n_r))
        link(b, "oil", K_STREAM, A_heat, f"oilsys:{b}", sub=S_CHANNEL, frac=p[f"oil_system.frac_{b}"],
             D=float(ht.hydraulic_diameter_m(A_f, P_f)), L=0.0, h=0.0)
    # planetary (imposed 750 W/(m2 K) on all outer tooth surfaces, flow split by area)
    pl_area = {}
    for nm, z, R_p, mult in (("PS", int(p["planetary.z_sun"]), gs.R_p, 1),
                             ("PP", int(p["planetary.z_planet"]), gp.R_p, n_pl),
                             ("PR", int(p["planetary.z_ring"]), p["planetary.m_n"] * p["planetary.z_ring"] / 2, 1)):
        h_t = 2.25 * p["planetary.m_n"]
        pl_area[nm] = mult * p["planetary.width"] * (2 * math.pi * R_p + 2 * z * h_t)
    tot = sum(pl_area.values())
    for nm, A in pl_area.items():
        link(nm, "oil", K_STREAM, A, f"oilsys:{nm}", sub=S_IMPOSED, frac=p["oil_system.frac_planetary"] * A / tot,
             D=0.0, L=0.0, h=p["planetary.h_oil"])

    # ---- outside of the housings: convection and radiation to hot and cold surroundings
    for h in ("H1", "H2", "H3"):
        A_ext = p[f"housing.area_{h}"] * p["housing.external_frac"]
        for side, frac in (("hot_surroundings", p["housing.hot_frac"]), ("cold_surroundings", 1 - p["housing.hot_frac"])):
            link(h, side, K_EXT_CONV, A_ext * frac, f"extconv:{h}-{side.split('_')[0]}")
            link(h, side, K_EXT_RAD, A_ext * frac, f"extrad:{h}-{side.split('_')[0]}")

    # ---- heat sources: where each loss is deposited
    sources = {}
    for pair, (iw, lw) in PAIRS.items():
        if pair == "R":
            sources["mesh:R"] = [(ix["RL"], 0.5), (ix["RI"], 0.5)]
            sources["mesh:RI"] = [(ix["RI"], 0.5), (ix["RM.teeth"], 0.5)]
        else:
            sources[f"mesh:{pair}"] = [(ix[f"{iw}.teeth"], 0.5), (ix[lw], 0.5)]   # seed 3.2: split evenly
    sources["planetary"] = [(ix["PS"], 1 / 3), (ix["PP"], 1 / 2), (ix["PR"], 1 / 6)]
    for b in SHAFT_BEARINGS:
        sources[f"bearing:{b}"] = [(ix[b], 1.0)]
    for key in ("churning", "wheel_bearings", "synchronizers", "pump"):
        sources[key] = [(ix["oil"], 1.0)]                                           # seed 3.2: to the sump
    sources["retarder"] = [(ix["oil"], 0.8), (ix["H3"], 0.2)]
    for w in IDLE_WHEELS:
        sources[f"shift:{w}"] = [(ix[f"{w}.bulk"], 1.0)]
    sources["shift:PR"] = [(ix["PR"], 1.0)]

    # pack per-kind params into arrays
    kind_params = {}
    for k, lst in kp.items():
        if not lst:
            continue
        keys = sorted({kk for d in lst for kk in d})
        kind_params[k] = {kk: np.array([d.get(kk, 0.0) for d in lst], dtype=float) for kk in keys}
    geo["segment_length_m"] = seg_len
    geo["wheel_mass_kg"] = wheel_mass
    return Network(tuple(nodes), np.array(C), np.array(la), np.array(lb), np.array(lk), np.array(lg), tuple(lname),
                   kind_params, sources, geo)


@dataclass
class HeatTransferScales:
    """Multipliers used by effects and parameter studies (1.0 = nominal)."""
    teeth_oil_h: float = 1.0
    planet_oil_h: float = 1.0
    housing_air_h: float = 1.0
    all_oil_h: float = 1.0


class ConductanceEvaluator:
    """Evaluates the conductance of every link for given operating conditions (vectorised per kind)."""

    def __init__(self, net: Network, p: Parameters, scales: HeatTransferScales | None = None):
        self.net = net
        self.p = p
        self.scales = scales or HeatTransferScales()
        self.G = net.link_G0.copy()
        self.idx = {k: net.links_of_kind(k) for k in range(10)}
        self.kp = net.kind_params
        self.h_nom = p["heat.h_nom"]
        self.w_nom = p["heat.N_nom"]          # rad/s (converted from rpm)
        self.exp_splash = p["heat.splash_exponent"]
        self.h_house = p["housing.h_oil"]
        self.h_air = p["housing.h_air"]
        self.eps = p["housing.emissivity"]
        self.flow_per_rad = p["oil_system.flow_per_ls_rpm"]   # m3 per rad of layshaft rotation
        self.n_nodes = net.n
        self.ext_rad_idx = self.idx[K_EXT_RAD]
        self.ext_rad_a = net.link_a[self.ext_rad_idx]
        self.ext_rad_b = net.link_b[self.ext_rad_idx] - net.n

    def oil_mass_flow_kg_s(self, omega_ls_rad_s, rho):
        return rho * self.flow_per_rad * abs(omega_ls_rad_s)

    def evaluate(self, T_oil_c: float, speeds: np.ndarray, gear_row: int, mesh_torque_row: np.ndarray,
                 low_range: bool, T_nodes_c: np.ndarray | None = None, T_bc_c: np.ndarray | None = None) -> np.ndarray:
        """Conductance of every link [W/K]. speeds: |rad/s| per SPEED_NAMES; T_nodes/T_bc for radiation."""
        G = self.G
        sc = self.scales
        op = oilprops.oil_properties(T_oil_c)
        k_oil, nu, pr, cp, rho = op.k_w_per_mk, op.nu_m2_s, op.pr, op.cp_j_per_kgk, op.rho_kg_m3
        # contacts: active when the mesh carries torque
        i = self.idx[K_CONTACT]
        if i.size:
            active = mesh_torque_row[self.kp[K_CONTACT]["mesh"].astype(int)] != 0
            G[i] = self.net.link_G0[i] * active
        # splash (Eq 59): idle-wheel teeth (group 0) and the output shaft (group 1)
        i = self.idx[K_SPLASH]
        if i.size:
            kp = self.kp[K_SPLASH]
            w = speeds[kp["speed"].astype(int)]
            h = self.h_nom * (w / self.w_nom) ** self.exp_splash
            h = h * np.where(kp["group"] == 0, sc.teeth_oil_h, 1.0) * sc.all_oil_h
            G[i] = self.net.link_G0[i] * h
        # immersed layshaft wheels (Eq 46-51) + fling-off (Eq 54-58)
        i = self.idx[K_IMM_GEAR]
        if i.size:
            kp = self.kp[K_IMM_GEAR]
            w = np.maximum(speeds[kp["speed"].astype(int)], 1e-3)
            re = ht.reynolds_gear(kp["R_p"], w, nu)
            nu_num = ht.nusselt_rotating_cylinder(re, pr)
            h = nu_num * k_oil / kp["R_p"]
            fo = ht.fling_off_hA(kp["z"], kp["width"], kp["h_t"], kp["R_p"], kp["h_i"], w, k_oil, op.alpha_m2_s, nu)
            G[i] = (self.net.link_G0[i] * h + fo.hA_w_per_k) * sc.all_oil_h
        # immersed layshaft bearings (Eq 52-53)
        i = self.idx[K_IMM_BRG]
        if i.size:
            kp = self.kp[K_IMM_BRG]
            w = np.maximum(speeds[kp["speed"].astype(int)], 1e-3)
            re = ht.reynolds_bearing(kp["Dm"], w, nu)
            h = ht.nusselt_rotating_cylinder(re, pr) * k_oil / (kp["Dm"] / 2)
            G[i] = self.net.link_G0[i] * h * sc.all_oil_h
        # bearing oil splash (Eq 63-64)
        i = self.idx[K_BRG_SPLASH]
        if i.size:
            kp = self.kp[K_BRG_SPLASH]
            w = np.maximum(speeds[kp["speed"].astype(int)], 1e-3)
            h = ht.harris_bearing_h_w_per_m2k(w, nu, kp["d_roller"], kp["Dm"], k_oil, pr)
            G[i] = self.net.link_G0[i] * h * sc.all_oil_h
        # ring gear
        i = self.idx[K_RING]
        if i.size:
            kp = self.kp[K_RING]
            if low_range:
                G[i] = self.net.link_G0[i] * self.h_house
            else:
                # rotating with the sun at high range: splash (Eq 59), never below the stationary housing value
                # (the ring always sits in oil; at standstill it must not be thermally isolated)
                w = speeds[kp["speed"].astype(int)]
                G[i] = self.net.link_G0[i] * np.maximum(self.h_nom * (w / self.w_nom) ** self.exp_splash, self.h_house)
            G[i] *= sc.all_oil_h
        # oil-system streams: flow linear in layshaft speed; effectiveness-limited
        i = self.idx[K_STREAM]
        if i.size:
            kp = self.kp[K_STREAM]
            mdot_tot = self.oil_mass_flow_kg_s(speeds[SPEED_NAMES.index("LS")], rho)
            mdot = np.maximum(mdot_tot * kp["frac"], 1e-9)
            sub = kp["sub"]
            h = np.empty(i.size)
            pipe = sub == S_PIPE
            if pipe.any():
                D = kp["D"][pipe]
                re = ht.pipe_reynolds(mdot[pipe], op.mu_pa_s, D)
                h[pipe] = ht.h_from_nusselt_w_per_m2k(ht.pipe_nusselt(re, pr, kp["L"][pipe], D), k_oil, D)
            ch = sub == S_CHANNEL
            if ch.any():
                h[ch] = ht.channel_h_w_per_m2k(k_oil, kp["D"][ch])
            imp = sub == S_IMPOSED
            if imp.any():
                h[imp] = kp["h"][imp] * sc.planet_oil_h
            hA = self.net.link_G0[i] * h * sc.all_oil_h
            G[i] = np.where(mdot_tot > 0, ht.oil_system_conductance_w_per_k(hA, mdot, cp), 0.0)
        # external convection
        i = self.idx[K_EXT_CONV]
        if i.size:
            G[i] = self.net.link_G0[i] * self.h_air * sc.housing_air_h
        self._update_radiation(G, T_nodes_c, T_bc_c)
        return G

    def _update_radiation(self, G, T_nodes_c, T_bc_c):
        # radiation, linearised around the current temperatures (Eq 6, 81)
        i = self.ext_rad_idx
        if i.size:
            if T_nodes_c is None or T_bc_c is None:
                h = ht.radiation_h_w_per_m2k(self.eps, 60.0, 40.0)
            else:
                h = ht.radiation_h_w_per_m2k(self.eps, T_nodes_c[self.ext_rad_a], T_bc_c[self.ext_rad_b])
            G[i] = self.net.link_G0[i] * h

    def evaluate_cached(self, T_oil_c, speeds, gear_row, mesh_torque_row, low_range, T_nodes_c, T_bc_c,
                        speed_rtol=0.01, oil_atol_c=0.25):
        """Like `evaluate`, but reuses the speed- and oil-dependent conductances while the gear is the same, the
        speeds are within `speed_rtol` and the oil within `oil_atol_c` of the last full evaluation (radiation is
        always updated). The error this allows is below 1 % on any conductance."""
        c = getattr(self, "_cache", None)
        if c is not None and c[0] == gear_row and abs(T_oil_c - c[1]) < oil_atol_c and np.all(
                np.abs(speeds - c[2]) <= speed_rtol * np.maximum(c[2], 1.0)):
            G = c[3]
            self._update_radiation(G, T_nodes_c, T_bc_c)
            return G
        G = self.evaluate(T_oil_c, speeds, gear_row, mesh_torque_row, low_range, T_nodes_c, T_bc_c)
        self._cache = (gear_row, float(T_oil_c), np.array(speeds, dtype=float), G)
        return G

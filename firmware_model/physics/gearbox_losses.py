"""Mechanical losses of the whole gearbox for arrays of (input speed, input torque, gear, oil temperature) samples,
and the heat each of them deposits (seed section 3.2).

Loss mechanisms: gear-contact slip (Eq 7-13) and rolling (14-22) of every loaded mesh, planetary meshes at low
range, churning of the immersed wheels (23-34), shaft bearings (35-40, Table 7) with loads from the mesh forces,
needle bearings of the idle wheels (36-37), synchronizer ring drag (41) and the oil pump (42).
Heat = loss x seed scale factor (0.75 gear contact, 0.80 planetary, 1.33 churning) x effect scale factor.
Oil properties are evaluated at the sump temperature (seed 3.2: "the oil sump temperature is sampled").

The same model generates the onboard sensor's loss maps, so plant and sensor share one description of the losses.
"""

from __future__ import annotations

import math

import numpy as np

from firmware_model.components import SHAFT_BEARINGS
from firmware_model.description import Description
from firmware_model.effects import EffectScales
from firmware_model.errors import ParameterError
from firmware_model.parameters import Parameters
from firmware_model.physics import losses as L
from firmware_model.physics import oil as oilprops
from firmware_model.physics.drivetrain import gear_kinematics, kinematics_of
from firmware_model.physics.geometry import Geometry, build_geometry
from firmware_model.physics.kinematics import GEAR_MIN, MESHES

#: the GRS905's loss sources in reporting order (the onboard tables and the run tables index it): "mesh:<m>" for
#: the meshes between fixed axes, the planetary sets, the shaft bearings, then the lumped ones; a gearbox's own are
#: GearboxLosses.sources (sources_of its description), the same for the GRS905
SOURCES = (
    tuple(f"mesh:{m}" for m in MESHES[:7])
    + ("planetary",)
    + tuple(f"bearing:{b}" for b in SHAFT_BEARINGS)
    + ("churning", "wheel_bearings", "synchronizers", "pump")
)
#: Gauss-Legendre points on each side of the pitch point for the rolling loss (~1 W terms, seed 3.2: coarse is plenty)
ROLL_POINTS = 4


def _planetary_members(d: Description) -> dict:
    """Planetary member -> its set."""
    return {m: ps for ps in d.planetary for m in (ps.sun, ps.planet, ps.ring)}


def sources_of(d: Description) -> tuple:
    """A description's loss sources in reporting order: its meshes between fixed axes, ``planetary`` (every set's
    meshes) when it has a planetary set, its shaft bearings, churning, the idle wheels' bearings, the synchronizers
    and the pump."""
    members = _planetary_members(d)
    out = [f"mesh:{m.id}" for m in d.meshes if not set(m.wheels) & set(members)]
    out += ["planetary"] if d.planetary else []
    out += [f"bearing:{b.id}" for b in d.bearings if b.wheel is None]
    return tuple(out) + ("churning", "wheel_bearings", "synchronizers", "pump")


def _sync_ring(p: Parameters, d: Description, joins: tuple) -> tuple:
    """(rings, ring radius, axial clearance) of a synchronizer: the range synchronizer's rings where it engages a
    planetary member, the split synchronizer's where it engages the input shaft, else the main box's (seed 3.2)."""
    if joins[0] in _planetary_members(d):
        return p["sync.n_ring_range"], p["sync.R_ring_range"], p["sync.J_ax_range"]
    if d.drive.input_shaft in joins:
        return p["sync.n_ring_split"], p["sync.R_ring_split"], p["sync.J_ax"]
    return p["sync.n_ring_main"], p["sync.R_ring_main"], p["sync.J_ax"]


def _shaft_sides(d: Description) -> dict:
    """Shaft -> +1 or -1: the side of the mesh plane it sits on, the input shaft's +1, a mesh between two shafts
    (directly or through an idler on a pin, which sits beside the plane) changing side; a radial mesh force pushes
    each shaft away from its mate, so it takes the sign of its side."""
    shaft_of = {w.id: w.shaft for w in d.wheels}
    pins = {w.id for w in d.wheels if w.mount == "pin"}
    links = []
    for m in d.meshes:
        a, b = (shaft_of.get(w) for w in m.wheels)
        if a and b:
            links.append((a, b))
    for pin in pins:  # the shafts on either side of an idler
        ends = [shaft_of.get(w) for m in d.meshes if pin in m.wheels for w in m.wheels if w != pin]
        links += [(ends[0], e) for e in ends[1:] if ends[0] and e]
    side: dict = {}
    # the input shaft first; a shaft no mesh joins to it (the sun shaft behind a planetary set: its members' forces
    # balance over the planets) starts its own chain on the +1 side
    for start in [d.drive.input_shaft] + [sh.id for sh in d.shafts]:
        if start in side:
            continue
        side[start] = 1.0
        grew = True
        while grew:
            grew = False
            for a, b in links:
                for u, v in ((a, b), (b, a)):
                    if u in side and v not in side:
                        side[v] = -side[u]
                        grew = True
    return side


class GearboxLosses:
    """The loss model of one parameter set and its geometry, built from the gearbox's description."""

    def __init__(self, p: Parameters, geometry: Geometry | None = None):
        self.p = p
        self.oil = oilprops.oil_of(p)  # the description's oil ([oil]; the seed's where it gives none)
        self.kin = kinematics_of(p)  # the gearbox's own description (docs/description.md)
        self.geo = geometry or build_geometry(p)
        d = self.d = self.geo.description
        self.sources = sources_of(d)
        self.mesh_ids = tuple(m.id for m in d.meshes)
        self.meshes = [self.geo.meshes[m] for m in self.mesh_ids]
        members = _planetary_members(d)
        # a planetary mesh is one per planet: its load splits over the set's planets
        self.mesh_planets = [members[m.wheels[0]].n_planets if set(m.wheels) & set(members) else 0 for m in d.meshes]
        # the first planetary set's planets (the onboard mesh tables split one set's load: onboard/reduce.py)
        self.n_planets = d.planetary[0].n_planets if d.planetary else 1
        self.E = p["material.steel.E"]
        self.poisson = p["material.steel.poisson"]
        self.sf_gear = p["scale.gear_contact_to_heat"]
        self.sf_planet = p["scale.planet_to_heat"]
        self.sf_churn = p["scale.churn_to_heat"]
        names = self.kin.speed_names
        # the speed column a wheel turns at: its shaft's (fixed, cut) or its own (idle, on a pin)
        self.col = {n: i for i, n in enumerate(names)}
        self.col.update({w.id: names.index(w.shaft) for w in d.wheels if w.mount in ("fixed", "cut")})
        self._bearing_tables()
        self._churn_geometry()
        # a pump on a shaft takes pump.k w^2 from it; a motor-driven pump (no pump_shaft) takes nothing from the drive
        self.pump_k = p["pump.k"] if d.oil.pump_shaft is not None else 0.0
        self.pump_col = None if d.oil.pump_shaft is None else names.index(d.oil.pump_shaft)
        self.sync_geo = [_sync_ring(p, d, c.joins) for c in d.couplings if c.kind == "sync"]

    # ------------------------------------------------------------------ geometry-derived tables
    def _mesh_forces(self, g) -> dict:
        """(x, Fy, Fz, Fa) per unit input torque on each shaft from the loaded meshes between fixed axes of a gear:
        tangential force from the driving wheel's torque on its working pitch radius, +Ft on the driving wheel's
        shaft and -Ft on the driven one's, radial force Ft tan(alpha_tw) by the shaft's side, axial Ft tan(beta); a
        shaft that takes the power in through one mesh and gives it out through another has wheels of opposite hand
        (the axial forces partly cancel)."""
        d, members = self.d, _planetary_members(self.d)
        wheel = {w.id: w for w in d.wheels}
        mesh = {m.id: m for m in d.meshes}
        side = _shaft_sides(d)
        forces: dict = {}
        entered: set = set()
        for mid, (w_in, torque) in g.driver.items():
            if set(mesh[mid].wheels) & set(members):
                continue
            gm = self.geo.meshes[mid]
            first = mesh[mid].wheels[0] == w_in
            Ft = torque / (gm.R_w1_m if first else gm.R_w2_m)
            Fr, Fa = Ft * math.tan(gm.alpha_tw_rad), Ft * math.tan(gm.beta_rad)
            for w in mesh[mid].wheels:
                shaft = wheel[w].shaft
                if shaft is None:  # an idler on a pin: its forces go to the casing
                    continue
                driving = w == w_in
                fa = -Fa if driving and shaft in entered else Fa
                forces.setdefault(shaft, []).append((wheel[w].x_m, Ft if driving else -Ft, side[shaft] * Fr, fa))
                if not driving:
                    entered.add(shaft)
        return forces

    def _supports(self) -> tuple:
        """Shaft -> (front, rear) bearing carrying it (its own, or a pilot bearing seated inside it), and shaft ->
        the bearing taking its axial force (the rearmost of its own seated in a housing)."""
        d = self.d
        seg_shaft = {s.id: sh.id for sh in d.shafts for s in sh.segments}
        seg_x = {s.id: s.x_m for sh in d.shafts for s in sh.segments}
        shaft_bearings = [b for b in d.bearings if b.wheel is None]
        supports, thrust = {}, {}
        for sh in d.shafts:
            carry = [b for b in shaft_bearings if b.shaft == sh.id or seg_shaft.get(b.inside) == sh.id]
            carry.sort(key=lambda b: b.x_m if b.x_m is not None else seg_x[b.segment])
            if len(carry) >= 2:
                supports[sh.id] = (carry[0].id, carry[-1].id)
            own = [b for b in carry if b.shaft == sh.id and b.housing is not None]
            if own:
                thrust[sh.id] = own[-1].id
        return supports, thrust

    def _bearing_tables(self):
        """Radial and axial load coefficients [N per N m of input torque], per gear and shaft bearing."""
        d = self.d
        shaft_bearings = [b for b in d.bearings if b.wheel is None]
        ids = self.bearing_ids = [b.id for b in shaft_bearings]
        nG = self.kin.speed.shape[0]
        self.Fr_coef = np.zeros((nG, len(ids)))
        self.Fa_coef = np.zeros((nG, len(ids)))
        seg_x = {s.id: s.x_m for sh in d.shafts for s in sh.segments}
        xb = {b.id: b.x_m if b.x_m is not None else seg_x[b.segment] for b in shaft_bearings}
        supports, thrust = self._supports()
        for gear in d.gears:
            r = gear.number - GEAR_MIN
            forces = self._mesh_forces(gear_kinematics(d, gear))
            for shaft, (bA, bB) in supports.items():
                if shaft not in forces:
                    continue
                xA, xB = xb[bA], xb[bB]
                RyA = RyB = RzA = RzB = 0.0
                fa = 0.0
                for x, fy, fz, fax in forces[shaft]:
                    s = (x - xA) / (xB - xA)  # lever rule (Eq 40 needs Fr and Fa of each bearing)
                    RyB += fy * s
                    RyA += fy * (1 - s)
                    RzB += fz * s
                    RzA += fz * (1 - s)
                    fa += fax
                jA, jB = ids.index(bA), ids.index(bB)
                self.Fr_coef[r, jA] += math.hypot(RyA, RzA)
                self.Fr_coef[r, jB] += math.hypot(RyB, RzB)
                if shaft in thrust:
                    self.Fa_coef[r, ids.index(thrust[shaft])] += abs(fa)
        self._bearing_torques(shaft_bearings)

    def _bearing_torques(self, shaft_bearings: list):
        """Palmgren's load torque per N m of input torque (Eq 38-40) of each shaft bearing, its speed column(s),
        and the idle wheels' needle bearings."""
        p, d = self.p, self.d
        self.load_torque_coef = np.zeros_like(self.Fr_coef)
        self.rr_coef = np.zeros_like(self.Fr_coef)  # SKF's rolling term (none unless bearing.R1_<kind> is given)
        self.f0 = np.zeros(len(shaft_bearings))
        self.Dm = np.zeros(len(shaft_bearings))
        for j, b in enumerate(shaft_bearings):
            typ = b.kind
            self.f0[j] = p[f"bearing.f0_{typ}"]
            self.Dm[j] = 0.5 * (b.bore_m + b.outer_m)
            P1 = L.bearing_p1_n(
                self.Fr_coef[:, j],
                self.Fa_coef[:, j],
                p[f"bearing.e_{typ}"],
                p[f"bearing.X1_{typ}"],
                p[f"bearing.Y1_{typ}"],
                p[f"bearing.X2_{typ}"],
                p[f"bearing.Y2_{typ}"],
            )
            self.load_torque_coef[:, j] = (
                p[f"bearing.f1_{typ}"] * (p["bearing.P0"] + P1) * self.Dm[j]
                + p["bearing.f2"] * self.Fa_coef[:, j] * self.Dm[j]
            )
            R1 = p.values.get(f"bearing.R1_{typ}", 0.0)
            if R1 > 0.0:
                self.rr_coef[:, j] = L.skf_rolling_coef(R1, self.Dm[j], P1, typ)
        # a bearing turns with its shaft; a pilot bearing at the difference of its shaft and the one around it
        seg_shaft = {s.id: sh.id for sh in d.shafts for s in sh.segments}
        names = self.kin.speed_names
        self.bearing_speed_idx = [names.index(b.shaft) for b in shaft_bearings]
        self.bearing_outer_idx = [
            None if b.inside is None else names.index(seg_shaft[b.inside]) for b in shaft_bearings
        ]
        # needle bearings under the idle wheels: mean diameter over the shaft under the wheel
        wheel = {w.id: w for w in d.wheels}
        needles = [b for b in d.bearings if b.wheel is not None]
        self.needle_Dm = np.array([2 * self.geo.R_shaft_m[wheel[b.wheel].shaft] + b.roller_m for b in needles])
        self.needle_f0 = p["wheel_bearing.f0_needle"] if needles else 0.0

    def _churn_geometry(self):
        """The wheels dipping into the sump (oil.dipping): their tip, pitch and tooth sizes and immersion."""
        W, imm, d = self.geo.wheels, self.geo.immersion_m, self.d
        dipping = [w.id for w in d.wheels if w.id in d.oil.dipping]
        rows = []
        for w in dipping:
            if w not in imm:
                raise ParameterError(f"{d.origin}: topology.oil.dipping names {w}, whose immersion is not known")
            g = W[w]
            h_i = imm[w]
            th = 2 * math.acos(float(np.clip(1 - h_i / g.R_a, -1, 1)))
            V_p = 0.5 * g.R_a**2 * (th - math.sin(th)) * g.width
            rows.append((g.R_a, g.R_p, g.h_t, g.width, h_i, V_p))
        a = np.array(rows).reshape(len(rows), 6)
        self.ch_Ra, self.ch_Rp, self.ch_ht, self.ch_w, self.ch_hi, self.ch_Vp = a.T
        self.ch_col = np.array([self.col[w] for w in dipping], dtype=np.int64)
        # an idler on a pin (the onboard churning table scales it from the layshaft speed: onboard/reduce.py)
        mount = {w.id: w.mount for w in d.wheels}
        self.ch_is_RI = np.array([1.0 if mount[w] == "pin" else 0.0 for w in dipping])
        self.ch_mask = self.ch_hi > 0
        self.V0 = d.oil.volume_m3
        self.h_t0 = self.p["oil.h_t0"] if dipping else 0.0  # Eq 34's reference tooth height (no wheel dips: unused)

    def _rolling_nm(self, j: int, row, T_in, nu, wb):
        """SKF's rolling frictional moment of shaft bearing j [N m] (0 where its kind gives no bearing.R1_<kind>)."""
        if not self.rr_coef[:, j].any():
            return 0.0
        return L.skf_rolling_torque_nm(self.rr_coef[row, j], L.skf_inlet_shear_coef(self.Dm[j]), T_in, nu, wb)

    # ------------------------------------------------------------------ evaluation
    def evaluate(self, omega_in_rad_s, torque_in_nm, gear, T_oil_c, churn_validity: bool = False) -> dict:
        """Mechanical loss [W] of every source in ``self.sources``, as arrays over the samples.

        omega_in_rad_s, torque_in_nm, gear: arrays (or scalars) of the same length; T_oil_c: scalar or array.
        """
        w_in = np.abs(np.atleast_1d(np.asarray(omega_in_rad_s, dtype=float)))
        T_in = np.abs(np.atleast_1d(np.asarray(torque_in_nm, dtype=float)))
        row = np.atleast_1d(np.asarray(gear, dtype=np.int64)) - GEAR_MIN
        n = max(w_in.size, T_in.size, row.size)
        w_in, T_in, row = (np.broadcast_to(a, (n,)) for a in (w_in, T_in, row))
        op = self.oil.properties(T_oil_c)
        rho, mu, nu, piezo = op.rho_kg_m3, op.mu_pa_s, op.nu_m2_s, op.piezo_per_pa
        kin = self.kin
        out = {}
        # meshes; a planetary mesh once per planet, its loss summed over the planets
        mt = kin.mesh_torque[row] * T_in[:, None]
        mw = kin.mesh_omega2[row] * w_in[:, None]
        planet = np.zeros(n)
        for j, m in enumerate(self.mesh_ids):
            T1 = mt[:, j]
            n_pl = self.mesh_planets[j]
            if not np.any(T1):
                P = np.zeros(n)
            else:
                mesh = self.meshes[j]
                if n_pl:
                    T1 = T1 / n_pl
                # rolling losses are ~1 W (seed 3.2): a coarse quadrature is plenty for them
                P = L.gear_slip_loss_w(mesh, T1, mw[:, j], rho, mu) + L.gear_rolling_loss_w(
                    mesh, T1, mw[:, j], mu, piezo, self.E, self.E, self.poisson, self.poisson, n_points=ROLL_POINTS
                )
                P = np.where(T1 > 0, P, 0.0)
                if n_pl:
                    P = P * n_pl
            if n_pl:
                planet = planet + P
            else:
                out[f"mesh:{m}"] = P
        if "planetary" in self.sources:
            out["planetary"] = planet
        # shaft bearings (Eq 35-40)
        sp = kin.speed[row] * w_in[:, None]
        for j, b in enumerate(self.bearing_ids):
            wb = sp[:, self.bearing_speed_idx[j]]
            if self.bearing_outer_idx[j] is not None:  # a pilot bearing: between its shaft and the one around it
                wb = wb - sp[:, self.bearing_outer_idx[j]]
            wb = np.abs(wb)
            T_oil = L.bearing_torque_nm(self.f0[j], 0.0, 0.0, self.Dm[j], nu, wb, 0.0, 0.0, 0.0)
            T_load = self.load_torque_coef[row, j] * T_in + self._rolling_nm(j, row, T_in, nu, wb)
            out[f"bearing:{b}"] = (T_oil + T_load) * wb
        # churning (Eq 23-34) of the wheels dipping into the sump, each at its own speed
        wc = np.abs(sp[:, self.ch_col])
        with np.errstate(divide="ignore", invalid="ignore"):  # wheels lifted out of the oil are masked below
            ch = L.churning_loss(
                wc, self.ch_Ra, self.ch_Rp, self.ch_ht, self.ch_w, self.ch_hi, self.ch_Vp, self.V0, rho, nu, self.h_t0
            )
        out["churning"] = np.sum(np.where(self.ch_mask, ch.power_w, 0.0), axis=1)
        if churn_validity:
            out["churning_valid"] = np.all(ch.valid | ~self.ch_mask, axis=1)
        # needle bearings of the idle wheels (Eq 36-37 on the relative speed)
        rel = kin.wheel_bearing_rel[row] * w_in[:, None]
        Tn = L.needle_bearing_torque_nm(self.needle_f0, self.needle_Dm[None, :], nu, rel)
        out["wheel_bearings"] = np.sum(Tn * rel, axis=1)
        # synchronizer rings (Eq 41)
        srel = kin.sync_rel[row] * w_in[:, None]
        Psync = np.zeros(n)
        s = self.p
        for k, (n_ring, R_ring, J_ax) in enumerate(self.sync_geo):
            Ts = L.sync_ring_drag_torque_nm(
                n_ring, mu, R_ring, s["sync.w_ring"], J_ax, s["sync.theta_ring"], srel[:, k]
            )
            Psync = Psync + Ts * srel[:, k]
        out["synchronizers"] = Psync
        # oil pump (Eq 42): torque linear in the pump shaft's speed (none for a motor-driven pump)
        w_pump = np.zeros(n) if self.pump_col is None else np.abs(sp[:, self.pump_col])
        out["pump"] = self.pump_k * w_pump * w_pump
        return out

    def heat(self, loss: dict, scales: EffectScales | None = None) -> dict:
        """Heat [W] per source: the seed's loss-to-heat scale factors times the effect scales."""
        sc = scales or EffectScales()
        h = {}
        for k, v in loss.items():
            if k.startswith("mesh:"):
                h[k] = v * self.sf_gear * sc.gear_friction_scale
            elif k == "planetary":
                h[k] = v * self.sf_planet * sc.planetary_scale
            elif k == "churning":
                h[k] = v * self.sf_churn * sc.churn_scale
            elif k.startswith("bearing:") or k == "wheel_bearings":
                h[k] = v * sc.bearing_scale
            elif k in ("synchronizers", "pump"):
                h[k] = v
        return h

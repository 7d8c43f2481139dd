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

from firmware_model.components import IDLE_WHEELS, LAYSHAFT_WHEELS, PAIRS, SHAFT_BEARINGS
from firmware_model.effects import EffectScales
from firmware_model.parameters import Parameters
from firmware_model.physics import losses as L
from firmware_model.physics import oil as oilprops
from firmware_model.physics.drivetrain import kinematics_of
from firmware_model.physics.geometry import Geometry, build_geometry
from firmware_model.physics.kinematics import GEAR_MIN, GEARS, MESHES, SPEED_NAMES, SYNCS, gear_state

#: loss sources in reporting order; "mesh:<m>" for the nine meshes, then the lumped ones
SOURCES = (
    tuple(f"mesh:{m}" for m in MESHES[:7])
    + ("planetary",)
    + tuple(f"bearing:{b}" for b in SHAFT_BEARINGS)
    + ("churning", "wheel_bearings", "synchronizers", "pump")
)
#: Gauss-Legendre points on each side of the pitch point for the rolling loss (~1 W terms, seed 3.2: coarse is plenty)
ROLL_POINTS = 4


class GearboxLosses:
    """The loss model of one parameter set and its geometry."""

    def __init__(self, p: Parameters, geometry: Geometry | None = None):
        self.p = p
        self.kin = kinematics_of(p)  # the gearbox's own description (docs/description.md)
        self.geo = geometry or build_geometry(p)
        self.meshes = [self.geo.meshes[m] for m in MESHES]
        self.n_planets = int(p["planetary.n_planets"])
        self.E = p["material.steel.E"]
        self.poisson = p["material.steel.poisson"]
        self.sf_gear = p["scale.gear_contact_to_heat"]
        self.sf_planet = p["scale.planet_to_heat"]
        self.sf_churn = p["scale.churn_to_heat"]
        self._bearing_tables()
        self._churn_geometry()
        self.i_ls = SPEED_NAMES.index("LS")
        self.i_is = SPEED_NAMES.index("IS")
        self.i_ms = SPEED_NAMES.index("MS")
        self.i_os = SPEED_NAMES.index("OS")
        self.pump_k = p["pump.k"]
        # synchronizer ring geometry per interface
        s = p
        self.sync_geo = []
        for name in SYNCS:
            if name in ("LI/IS", "3M/IS"):
                self.sync_geo.append((s["sync.n_ring_split"], s["sync.R_ring_split"], s["sync.J_ax"]))
            elif name == "PR/range":
                self.sync_geo.append((s["sync.n_ring_range"], s["sync.R_ring_range"], s["sync.J_ax_range"]))
            else:
                self.sync_geo.append((s["sync.n_ring_main"], s["sync.R_ring_main"], s["sync.J_ax"]))

    # ------------------------------------------------------------------ geometry-derived tables
    def _bearing_tables(self):
        """Radial and axial load coefficients [N per N m of input torque], per gear and shaft bearing."""
        p, W = self.p, self.geo.wheels
        nG = len(GEARS)
        self.Fr_coef = np.zeros((nG, len(SHAFT_BEARINGS)))
        self.Fa_coef = np.zeros((nG, len(SHAFT_BEARINGS)))
        xb = {b: p[f"bearing.{b}.x"] for b in SHAFT_BEARINGS}
        supports = {"IS": ("BIF", "BIM"), "LS": ("BLF", "BLR"), "MS": ("BIM", "BMR")}
        thrust = {"IS": "BIF", "LS": "BLR", "MS": "BMR"}
        for g in GEARS:
            st = gear_state(g, p.split_inverted)
            r = g - GEAR_MIN
            if st.main_pair is None or st.direct:
                continue
            forces = {"IS": [], "LS": [], "MS": []}  # (x, Fy, Fz, Fa) per unit input torque
            iw, lw = PAIRS[st.split_pair]
            mesh = self.geo.meshes[st.split_pair]
            Ft = 1.0 / mesh.R_w1_m
            Fr, Fa = Ft * math.tan(mesh.alpha_tw_rad), Ft * math.tan(mesh.beta_rad)
            shaft_i = "IS" if iw == "LI" else "MS"
            forces[shaft_i].append((W[iw].x, +Ft, +Fr, Fa))
            forces["LS"].append((W[lw].x, -Ft, -Fr, Fa))
            T_ls = W[lw].z / W[iw].z
            mp = st.main_pair
            miw, mlw = PAIRS[mp]
            mesh = self.geo.meshes["R" if mp == "R" else mp]
            Ft = T_ls / (mesh.R_w1_m if mp == "R" else mesh.R_w2_m)
            Fr, Fa = Ft * math.tan(mesh.alpha_tw_rad), Ft * math.tan(mesh.beta_rad)
            forces["LS"].append((W[mlw].x, +Ft, -Fr, -Fa))  # opposite hand: axial forces partly cancel
            forces["MS"].append((W[miw].x, -Ft, +Fr, Fa))
            for shaft, (bA, bB) in supports.items():
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
                jA, jB = SHAFT_BEARINGS.index(bA), SHAFT_BEARINGS.index(bB)
                self.Fr_coef[r, jA] += math.hypot(RyA, RzA)
                self.Fr_coef[r, jB] += math.hypot(RyB, RzB)
                self.Fa_coef[r, SHAFT_BEARINGS.index(thrust[shaft])] += abs(fa)
        # torque per N m of input torque from the load terms (Eq 38-40), per gear and bearing
        self.load_torque_coef = np.zeros_like(self.Fr_coef)
        self.f0 = np.zeros(len(SHAFT_BEARINGS))
        self.Dm = np.zeros(len(SHAFT_BEARINGS))
        for j, b in enumerate(SHAFT_BEARINGS):
            typ = "ball" if b == "BO" else "tapered"
            self.f0[j] = p[f"bearing.f0_{typ}"]
            self.Dm[j] = 0.5 * (p[f"bearing.{b}.d_bore"] + p[f"bearing.{b}.d_out"])
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
        shaft_of = {b.id: b.shaft for b in self.geo.description.bearings}
        self.bearing_speed_idx = [SPEED_NAMES.index(shaft_of[b]) for b in SHAFT_BEARINGS]
        # needle bearings
        d_r = p["wheel_bearing.d_roller"]
        R_s = {"LI": self.geo.R_shaft_m["IS"]}
        self.needle_Dm = np.array([2 * (R_s.get(w, self.geo.R_shaft_m["MS"])) + d_r for w in IDLE_WHEELS])
        self.needle_f0 = p["wheel_bearing.f0_needle"]

    def _churn_geometry(self):
        W, imm = self.geo.wheels, self.geo.immersion_m
        rows = []
        for w in LAYSHAFT_WHEELS + ("RI",):
            g = W[w]
            h_i = imm[w]
            th = 2 * math.acos(float(np.clip(1 - h_i / g.R_a, -1, 1)))
            V_p = 0.5 * g.R_a**2 * (th - math.sin(th)) * g.width
            rows.append((g.R_a, g.R_p, g.h_t, g.width, h_i, V_p, 1.0 if w == "RI" else 0.0))
        a = np.array(rows)
        self.ch_Ra, self.ch_Rp, self.ch_ht, self.ch_w, self.ch_hi, self.ch_Vp, self.ch_is_RI = a.T
        self.ch_mask = self.ch_hi > 0
        self.V0 = self.p["oil.volume"]
        self.h_t0 = self.p["oil.h_t0"]

    # ------------------------------------------------------------------ evaluation
    def evaluate(self, omega_in_rad_s, torque_in_nm, gear, T_oil_c, churn_validity: bool = False) -> dict:
        """Mechanical loss [W] of every source in SOURCES, as arrays over the samples.

        omega_in_rad_s, torque_in_nm, gear: arrays (or scalars) of the same length; T_oil_c: scalar or array.
        """
        w_in = np.abs(np.atleast_1d(np.asarray(omega_in_rad_s, dtype=float)))
        T_in = np.abs(np.atleast_1d(np.asarray(torque_in_nm, dtype=float)))
        row = np.atleast_1d(np.asarray(gear, dtype=np.int64)) - GEAR_MIN
        n = max(w_in.size, T_in.size, row.size)
        w_in, T_in, row = (np.broadcast_to(a, (n,)) for a in (w_in, T_in, row))
        op = oilprops.oil_properties(T_oil_c)
        rho, mu, nu, piezo = op.rho_kg_m3, op.mu_pa_s, op.nu_m2_s, op.piezo_per_pa
        kin = self.kin
        out = {}
        # meshes
        mt = kin.mesh_torque[row] * T_in[:, None]
        mw = kin.mesh_omega2[row] * w_in[:, None]
        planet = np.zeros(n)
        for j, m in enumerate(MESHES):
            T1 = mt[:, j]
            if not np.any(T1):
                P = np.zeros(n)
            else:
                mesh = self.meshes[j]
                if m in ("PSP", "PPR"):
                    T1 = T1 / self.n_planets
                # rolling losses are ~1 W (seed 3.2): a coarse quadrature is plenty for them
                P = L.gear_slip_loss_w(mesh, T1, mw[:, j], rho, mu) + L.gear_rolling_loss_w(
                    mesh, T1, mw[:, j], mu, piezo, self.E, self.E, self.poisson, self.poisson, n_points=ROLL_POINTS
                )
                P = np.where(T1 > 0, P, 0.0)
                if m in ("PSP", "PPR"):
                    P = P * self.n_planets
            if m in ("PSP", "PPR"):
                planet = planet + P
            else:
                out[f"mesh:{m}"] = P
        out["planetary"] = planet
        # shaft bearings (Eq 35-40)
        sp = kin.speed[row] * w_in[:, None]
        for j, b in enumerate(SHAFT_BEARINGS):
            if b == "BIM":
                wb = np.abs(sp[:, self.i_is] - sp[:, self.i_ms])
            else:
                wb = np.abs(sp[:, self.bearing_speed_idx[j]])
            T_oil = L.bearing_torque_nm(self.f0[j], 0.0, 0.0, self.Dm[j], nu, wb, 0.0, 0.0, 0.0)
            T_load = self.load_torque_coef[row, j] * T_in
            out[f"bearing:{b}"] = (T_oil + T_load) * wb
        # churning (Eq 23-34) of the immersed layshaft wheels and the reverse idler
        w_ls = np.abs(sp[:, self.i_ls])
        w_ri = np.abs(sp[:, SPEED_NAMES.index("RI")])
        wc = np.where(self.ch_is_RI[None, :] > 0, w_ri[:, None], w_ls[:, None])
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
        # oil pump (Eq 42): torque linear in layshaft speed
        out["pump"] = self.pump_k * w_ls * w_ls
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

"""Gearbox oil properties as functions of the oil temperature in degC (seed Appendix 2, section 2.5).

Every function takes a float or a numpy array ``T_c`` and broadcasts. The input temperature is clipped to
``T_MIN_C .. T_MAX_C`` (-40..200 degC) before any property is evaluated, so a wild sensor value cannot
produce NaN or a negative viscosity inside the solver loop.

Each gearbox has its oil (:class:`Oil`): the seed's Appendix 2 oil (:data:`SEED_OIL`: density, viscosity and the
piezo-viscosity coefficient from its table, Walther / ASTM D341 between the viscosity rows), or an oil from its data
sheet (:meth:`Oil.grade`, a description's ``[oil]``: :func:`oil_of`); conductivity and specific heat are assumed.
The module-level functions below are the seed oil's. docs/physics.md, "Oil properties", says where each property
comes from, how it is extended beyond its data, and where an oil stops being described.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from firmware_model.errors import InputError
from firmware_model.units import KELVIN_OFFSET_K

#: clip range of the input temperature [degC]
T_MIN_C = -40.0
T_MAX_C = 200.0


def check_temperature_c(label: str, value_c) -> float:
    """A temperature a user sets for the gearbox (an initial or a held temperature), checked: a finite number within
    T_MIN_C..T_MAX_C, the range the oil model describes (outside it every property is clipped; no gearbox in use
    is colder or hotter). InputError naming ``label`` (e.g. ``"--initial-temp"``) otherwise."""
    if (
        isinstance(value_c, bool)
        or not isinstance(value_c, (int, float, np.floating, np.integer))
        or not (math.isfinite(value_c) and T_MIN_C <= value_c <= T_MAX_C)
    ):
        raise InputError(
            f"{label} {value_c!r} degC is not a plausible gearbox temperature: use "
            f"{T_MIN_C:g}..{T_MAX_C:g} degC (the oil model's range)"
        )
    return float(value_c)


# --- Appendix 2 table -------------------------------------------------------------------------------------
#: table temperatures [degC]
TABLE_T_C = np.array([-20.0, 0.0, 20.0, 40.0, 60.0, 80.0, 100.0, 120.0, 140.0])
#: density [kg/m3]
TABLE_RHO_KG_M3 = np.array([896.438, 885.902, 875.366, 864.830, 854.294, 843.758, 833.222, 822.686, 812.150])
#: kinematic viscosity [cSt = mm2/s]
TABLE_NU_CST = np.array([9486.0, 1397.0, 337.6, 115.0, 49.9, 25.8, 15.2, 9.84, 6.84])
#: temperatures with a piezo-viscosity entry [degC]
TABLE_PIEZO_T_C = np.array([20.0, 40.0, 60.0, 80.0, 100.0, 120.0])
#: piezo-viscosity coefficient [1/Pa]
TABLE_PIEZO_PER_PA = np.array([24.0, 21.6, 19.3, 16.9, 14.7, 12.0]) * 1e-9
#: the 1000 degC row (T_c, rho_kg_m3, nu_cst, piezo_per_pa): documentation only, not used
_ROW_1000C = (1000.0, 359.102, 1.00, 1.00e-9)

#: lower bound of the extrapolated piezo-viscosity coefficient [1/Pa] (the seed's 1000 degC value)
PIEZO_FLOOR_PER_PA = 1.0e-9

# Density: exact straight line through the table (Eq: rho = RHO_0 + SLOPE * T_c)
_RHO_0_KG_M3 = 885.902
_RHO_SLOPE_KG_M3K = (TABLE_RHO_KG_M3[-1] - TABLE_RHO_KG_M3[0]) / (TABLE_T_C[-1] - TABLE_T_C[0])  # -0.5268

# Walther (ASTM D341): W = log10(log10(nu_cSt + 0.7)), X = log10(T_K); W is piecewise linear in X.
_WALTHER_C = 0.7

# Assumed, typical gear oil (not in the seed's table): k = K0 + K1*T_c, cp = CP0 + CP1*T_c
K0_W_PER_MK = 0.134
K1_W_PER_MK2 = -7.0e-5
CP0_J_PER_KGK = 1880.0
CP1_J_PER_KGK2 = 3.7

#: a grade's density falls by this much per kelvin from its 15 degC value [kg/m3/K] (ASTM D1250 / API MPMS 11.1,
#: table 54D, lubricating oils: the thermal expansion coefficient at 15 degC is K1 / rho_15 with K1 = 0.6278 kg/(m3 K),
#: 6.8-7.1e-4 /K for 880-920 kg/m3, so rho_15 alpha_15 = K1 whatever the density; the standard's exponential form
#: linearised at 15 degC, within 0.1 % of it to 100 degC. The seed's table: 0.5268)
GRADE_DENSITY_SLOPE_KG_M3K = -0.6278
#: the ISO 3448 viscosity grades: the mid-point of each grade's +-10 % band at 40 degC [mm2/s]
ISO_VG = (2, 3, 5, 7, 10, 15, 22, 32, 46, 68, 100, 150, 220, 320, 460, 680, 1000, 1500, 2200, 3200)
#: the temperatures of an ISO VG grade's data sheet viscosities [degC]
GRADE_T_C = (40.0, 100.0)
#: the dynamic viscosity at a gear oil's coldest temperature of use [Pa s] (SAE J306: a gear lubricant's winter grade
#: is the temperature it reaches 150 Pa s at); colder, the loss laws run on an oil that no longer flows to the
#: bearings and meshes as they assume
COLDEST_USE_MU_PA_S = 150.0
#: a grade's viscosity at 40 degC: from ISO VG 2's lower to ISO VG 3200's upper tolerance (ISO 3448, +-10 %) [mm2/s]
GRADE_NU_40_CST = (1.98, 3520.0)
#: the least viscosity Walther's equation with its constant 0.7 holds at (ASTM D341: 2 cSt) [mm2/s]: a grade's at
#: 100 degC
GRADE_NU_100_MIN_CST = 2.0
#: a grade's ASTM D341 slope, -dW/dlog10(T_K) between 40 and 100 degC: mineral gear oils of viscosity index 0-100
#: about 3.3-4.2, PAO and other synthetics 2.2-3.0, the highest-index polyglycols about 2 (derived from data sheets
#: through Walther); outside 1.5-5 the two points are not one oil's
GRADE_SLOPE = (1.5, 5.0)


class OilProperties(NamedTuple):
    """All oil properties at one temperature (or array of temperatures); a tuple, cheap to build."""

    T_c: np.ndarray | float
    rho_kg_m3: np.ndarray | float
    nu_m2_s: np.ndarray | float
    mu_pa_s: np.ndarray | float
    piezo_per_pa: np.ndarray | float
    k_w_per_mk: np.ndarray | float
    cp_j_per_kgk: np.ndarray | float
    alpha_m2_s: np.ndarray | float
    pr: np.ndarray | float


def _clip_t(T_c):
    return np.clip(T_c, T_MIN_C, T_MAX_C)


def _conductivity(Tc):
    return K0_W_PER_MK + K1_W_PER_MK2 * Tc


def _specific_heat(Tc):
    return CP0_J_PER_KGK + CP1_J_PER_KGK2 * Tc


class Oil:
    """One oil's properties as functions of its temperature: the viscosity by Walther (ASTM D341) through rows
    (T degC, nu cSt), piecewise linear in W = log10(log10(nu + 0.7)) against log10(T_K) and extended by the end
    rows' slopes; the density a straight line; the piezo-viscosity coefficient the seed's table times
    ``piezo_scale``; conductivity and specific heat the assumed typical gear oil's. :data:`SEED_OIL` is the seed's
    Appendix 2 oil (the GRS905's); :meth:`grade` an oil from its data sheet (a description's ``[oil]``)."""

    def __init__(self, name, visc_T_c, visc_nu_cst, rho_0_kg_m3, rho_slope_kg_m3k, piezo_scale=1.0):
        self.name = str(name)
        self.visc_T_c = np.asarray(visc_T_c, dtype=float)
        self.visc_nu_cst = np.asarray(visc_nu_cst, dtype=float)
        self.rho_0_kg_m3 = float(rho_0_kg_m3)
        self.rho_slope_kg_m3k = float(rho_slope_kg_m3k)
        self.piezo_scale = float(piezo_scale)
        x = np.log10(self.visc_T_c + KELVIN_OFFSET_K)
        w = np.log10(np.log10(self.visc_nu_cst + _WALTHER_C))
        self._x_rows, self._w_rows = x, w
        self._w_slope_first = (w[1] - w[0]) / (x[1] - x[0])
        self._w_slope_last = (w[-1] - w[-2]) / (x[-1] - x[-2])
        self._x_first, self._x_last = float(x[0]), float(x[-1])
        #: the last few scalar temperatures' properties: a plant step asks for the sump's three times (cooler,
        #: inlet drop, conductances); the tuple is immutable, so a hit returns the same values bit for bit
        self._memo: dict = {}

    @classmethod
    def grade(cls, nu_40_cst: float, nu_100_cst: float, rho_15_kg_m3: float, piezo_40_per_pa: float | None = None):
        """An oil from its data sheet: the kinematic viscosity at 40 and 100 degC [cSt] (Walther's line through
        the two: ASTM D341 with two points), the density at 15 degC (falling by GRADE_DENSITY_SLOPE_KG_M3K), the
        piezo-viscosity coefficient at 40 degC (None: the seed oil's; the seed's table's shape scaled to it).
        InputError when the values are not a plausible oil's."""
        nu40, nu100, rho15 = float(nu_40_cst), float(nu_100_cst), float(rho_15_kg_m3)
        if not (math.isfinite(nu40) and math.isfinite(nu100) and 0.0 < nu100 < nu40):
            raise InputError(
                f"an oil's viscosity at 40 degC ({nu40:g} mm2/s) must be above its viscosity at 100 degC "
                f"({nu100:g} mm2/s), both positive"
            )
        _check_grade_viscosity(nu40, nu100)
        if not (math.isfinite(rho15) and 600.0 <= rho15 <= 1200.0):
            raise InputError(f"an oil's density at 15 degC of {rho15:g} kg/m3 is not a plausible oil's (600-1200)")
        scale = 1.0
        if piezo_40_per_pa is not None:
            a40 = float(piezo_40_per_pa)
            if not (math.isfinite(a40) and 1.0e-9 <= a40 <= 1.0e-7):
                raise InputError(
                    f"an oil's piezo-viscosity coefficient of {a40 * 1e9:g} 1/GPa is not a plausible oil's (1-100)"
                )
            scale = a40 / float(TABLE_PIEZO_PER_PA[1])
        slope = GRADE_DENSITY_SLOPE_KG_M3K
        vg = next((g for g in ISO_VG if abs(nu40 - g) <= 0.1 * g), None)
        name = f"ISO VG {vg:g} (its data sheet)" if vg else f"an oil of {nu40:g} mm2/s at 40 degC (its data sheet)"
        return cls(name, GRADE_T_C, (nu40, nu100), rho15 - 15.0 * slope, slope, scale)

    def temperature_at_mu_c(self, mu_pa_s: float) -> float:
        """The temperature [degC] at which the oil's dynamic viscosity is ``mu_pa_s``, within T_MIN_C..T_MAX_C
        (an end where the oil is thinner or thicker than that over the whole range): bisection, the viscosity
        falls with temperature."""
        lo, hi = T_MIN_C, T_MAX_C
        if self.dynamic_viscosity_pa_s(lo) <= mu_pa_s:
            return lo
        if self.dynamic_viscosity_pa_s(hi) >= mu_pa_s:
            return hi
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if self.dynamic_viscosity_pa_s(mid) > mu_pa_s else (lo, mid)
        return 0.5 * (lo + hi)

    # --- the properties (each clips T_c to T_MIN_C..T_MAX_C first) ----------------------------------------------
    def _density(self, Tc):
        return self.rho_0_kg_m3 + self.rho_slope_kg_m3k * Tc

    def _kinematic(self, Tc):
        x = np.log10(Tc + KELVIN_OFFSET_K)
        # np.interp holds the end rows; add the end-segment slopes outside the table (linear extrapolation of W)
        w = (
            np.interp(x, self._x_rows, self._w_rows)
            + self._w_slope_first * np.minimum(x - self._x_first, 0.0)
            + self._w_slope_last * np.maximum(x - self._x_last, 0.0)
        )
        nu_cst = 10.0 ** (10.0**w) - _WALTHER_C  # always > 0.3 cSt: 10**(10**w) > 1
        return nu_cst * 1e-6

    def _piezo(self, Tc):
        a = (
            np.interp(Tc, TABLE_PIEZO_T_C, TABLE_PIEZO_PER_PA)
            + _PIEZO_SLOPE_FIRST * np.minimum(Tc - _PIEZO_T_FIRST, 0.0)
            + _PIEZO_SLOPE_LAST * np.maximum(Tc - _PIEZO_T_LAST, 0.0)
        )
        if self.piezo_scale != 1.0:  # the floor scaled too: the seed's shape throughout, positive
            return np.maximum(a * self.piezo_scale, PIEZO_FLOOR_PER_PA * self.piezo_scale)
        return np.maximum(a, PIEZO_FLOOR_PER_PA)

    def density_kg_m3(self, T_c):
        """Density [kg/m3], a straight line in T."""
        return self._density(_clip_t(T_c))

    def kinematic_viscosity_m2_s(self, T_c):
        """Kinematic viscosity [m2/s], Walther/ASTM D341 through the oil's rows."""
        return self._kinematic(_clip_t(T_c))

    def dynamic_viscosity_pa_s(self, T_c):
        """Dynamic viscosity [Pa s] = rho * nu (section 2.5)."""
        Tc = _clip_t(T_c)
        return self._density(Tc) * self._kinematic(Tc)

    def piezo_viscosity_per_pa(self, T_c):
        """Barus piezo-viscosity coefficient [1/Pa] (Appendix 2's shape; linear, floored at 1e-9 /Pa)."""
        return self._piezo(_clip_t(T_c))

    def properties(self, T_c) -> OilProperties:
        """Every property at once (one clip, one Walther evaluation); for the solver loop."""
        if type(T_c) in (float, np.float64):
            hit = self._memo.get(T_c)
            if hit is None:
                hit = self._properties(T_c)
                if len(self._memo) >= _SCALAR_MEMO_SIZE:
                    self._memo.clear()
                self._memo[T_c] = hit
            return hit
        return self._properties(T_c)

    def _properties(self, T_c) -> OilProperties:
        Tc = _clip_t(T_c)
        rho = self._density(Tc)
        nu = self._kinematic(Tc)
        k = _conductivity(Tc)
        cp = _specific_heat(Tc)
        alpha = k / (rho * cp)
        return OilProperties(Tc, rho, nu, rho * nu, self._piezo(Tc), k, cp, alpha, nu / alpha)


def walther_slope(nu_a_cst: float, T_a_c: float, nu_b_cst: float, T_b_c: float) -> float:
    """ASTM D341's slope between two (T degC, nu cSt) points: -dW/dlog10(T_K), W = log10(log10(nu + 0.7))."""
    w_a, w_b = (math.log10(math.log10(n + _WALTHER_C)) for n in (nu_a_cst, nu_b_cst))
    return (w_a - w_b) / (math.log10(T_b_c + KELVIN_OFFSET_K) - math.log10(T_a_c + KELVIN_OFFSET_K))


def _check_grade_viscosity(nu40: float, nu100: float) -> None:
    """InputError when a data sheet's two viscosities [mm2/s] are not one oil's: 40 degC outside the ISO 3448
    grades (most often a unit slip), 100 degC under Walther's range, or a fall between them no oil has."""
    lo, hi = GRADE_NU_40_CST
    if not lo <= nu40 <= hi:
        raise InputError(
            f"an oil's viscosity at 40 degC of {nu40:g} mm2/s is outside the ISO 3448 grades ({lo:g}-{hi:g} mm2/s, "
            "VG 2 to VG 3200 with their tolerance): check the value and its unit"
        )
    if nu100 < GRADE_NU_100_MIN_CST:
        raise InputError(
            f"an oil's viscosity at 100 degC of {nu100:g} mm2/s is under the {GRADE_NU_100_MIN_CST:g} mm2/s down to "
            "which Walther's equation (ASTM D341) describes it: check the value and its unit"
        )
    b = walther_slope(nu40, GRADE_T_C[0], nu100, GRADE_T_C[1])
    if not GRADE_SLOPE[0] <= b <= GRADE_SLOPE[1]:
        how = "less" if b < GRADE_SLOPE[0] else "more"
        raise InputError(
            f"an oil of {nu40:g} mm2/s at 40 degC and {nu100:g} mm2/s at 100 degC thins {how} with temperature than "
            f"any oil does (ASTM D341 slope {b:.2f}; mineral and synthetic oils "
            f"{GRADE_SLOPE[0]:g}-{GRADE_SLOPE[1]:g}): check both values"
        )


_PIEZO_SLOPE_FIRST = (TABLE_PIEZO_PER_PA[1] - TABLE_PIEZO_PER_PA[0]) / (TABLE_PIEZO_T_C[1] - TABLE_PIEZO_T_C[0])
_PIEZO_SLOPE_LAST = (TABLE_PIEZO_PER_PA[-1] - TABLE_PIEZO_PER_PA[-2]) / (TABLE_PIEZO_T_C[-1] - TABLE_PIEZO_T_C[-2])
_PIEZO_T_FIRST = float(TABLE_PIEZO_T_C[0])
_PIEZO_T_LAST = float(TABLE_PIEZO_T_C[-1])
_SCALAR_MEMO_SIZE = 8

#: the seed's oil (Appendix 2; the GRS905's, and every description's without an oil of its own)
SEED_OIL = Oil("the seed's gear oil (Appendix 2)", TABLE_T_C, TABLE_NU_CST, _RHO_0_KG_M3, _RHO_SLOPE_KG_M3K)

#: the [oil] keys of a grade (oil_of): the viscosity at 40 and 100 degC, the density at 15 degC, the piezo-viscosity
#: coefficient at 40 degC
GRADE_KEYS = ("oil.nu_40", "oil.nu_100", "oil.rho_15", "oil.piezo_40")


def oil_of(p) -> Oil:
    """The oil of a parameter set ``p`` (anything with ``get(key)``, values in SI): its grade where its [oil] gives
    one (oil.nu_40 and oil.nu_100 [m2/s], optionally oil.rho_15 [kg/m3] and oil.piezo_40 [1/Pa]), else the seed's.
    InputError for half a grade."""
    nu40, nu100, rho15, a40 = (p.get(k) for k in GRADE_KEYS)
    if nu40 is None and nu100 is None:
        if rho15 is not None or a40 is not None:
            raise InputError("oil.rho_15 or oil.piezo_40 needs the viscosity too: give oil.nu_40 and oil.nu_100")
        return SEED_OIL
    if nu40 is None or nu100 is None:
        raise InputError("an oil's grade needs both oil.nu_40 and oil.nu_100 (its viscosity at 40 and 100 degC)")
    rho = float(SEED_OIL.density_kg_m3(15.0)) if rho15 is None else rho15
    return Oil.grade(nu40 * 1e6, nu100 * 1e6, rho, a40)


def density_kg_m3(T_c):
    """The seed oil's density [kg/m3] (Appendix 2 table, exactly linear in T)."""
    return SEED_OIL.density_kg_m3(T_c)


def kinematic_viscosity_m2_s(T_c):
    """The seed oil's kinematic viscosity [m2/s], Walther/ASTM D341 interpolation of the Appendix 2 table."""
    return SEED_OIL.kinematic_viscosity_m2_s(T_c)


def dynamic_viscosity_pa_s(T_c):
    """The seed oil's dynamic viscosity [Pa s] = rho * nu (section 2.5)."""
    return SEED_OIL.dynamic_viscosity_pa_s(T_c)


def piezo_viscosity_per_pa(T_c):
    """The seed oil's Barus piezo-viscosity coefficient [1/Pa] (Appendix 2; linear, floored at 1e-9 /Pa outside
    20..120 degC)."""
    return SEED_OIL.piezo_viscosity_per_pa(T_c)


def thermal_conductivity_w_per_mk(T_c):
    """Oil thermal conductivity [W/(m K)]; assumed, typical gear oil: 0.134 - 7e-5 T_c."""
    return _conductivity(_clip_t(T_c))


def specific_heat_j_per_kgk(T_c):
    """Oil specific heat [J/(kg K)]; assumed, typical gear oil: 1880 + 3.7 T_c."""
    return _specific_heat(_clip_t(T_c))


def thermal_diffusivity_m2_s(T_c):
    """The seed oil's thermal diffusivity alpha = k / (rho cp) [m2/s] (section 2.5)."""
    Tc = _clip_t(T_c)
    return _conductivity(Tc) / (SEED_OIL._density(Tc) * _specific_heat(Tc))


def prandtl(T_c):
    """The seed oil's Prandtl number Pr = nu / alpha [-] (section 2.5)."""
    Tc = _clip_t(T_c)
    return SEED_OIL._kinematic(Tc) * SEED_OIL._density(Tc) * _specific_heat(Tc) / _conductivity(Tc)


def oil_properties(T_c) -> OilProperties:
    """Every property of the seed oil at once (:meth:`Oil.properties`)."""
    return SEED_OIL.properties(T_c)

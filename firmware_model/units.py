"""Unit conversions and physical constants, each defined once (SI in the core; rpm and degC only at the edges).

Names say both units: ``RAD_S_PER_RPM`` turns rpm into rad/s (``omega_rad_s = speed_rpm * RAD_S_PER_RPM``),
``RPM_PER_RAD_S`` the other way. Bit-for-bit the same numbers as the expressions they replace: 2 pi / 60 and pi / 30
round to the same double, and so do 60 / (2 pi) and 30 / pi.
"""

from __future__ import annotations

import math

#: rpm -> rad/s
RAD_S_PER_RPM = 2.0 * math.pi / 60.0
#: rad/s -> rpm
RPM_PER_RAD_S = 60.0 / (2.0 * math.pi)
#: degC -> K offset
KELVIN_OFFSET_K = 273.15
#: Stefan-Boltzmann constant
SIGMA_W_PER_M2K4 = 5.670374419e-8
#: litres per cubic metre
L_PER_M3 = 1000.0
#: seconds per minute and per hour
S_PER_MIN = 60.0
S_PER_H = 3600.0
#: km/h -> m/s
M_S_PER_KMH = 1.0 / 3.6

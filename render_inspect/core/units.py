"""Unit conversions: the one place the package's conversion factors are written.

Lengths are millimetres in code and files, angles radians, time seconds, spindle speed
rpm and feed mm/min (the scene's units).  Any other unit is a boundary, and a boundary
multiplies by one of these names rather than by a bare ``1e6``::

    Sq_nm = Sq_mm * MM_TO_NM          # mm -> nm
    omega = rpm * RPM_TO_RAD_PER_S    # rpm -> rad/s

The names read as "from unit _TO_ to unit": ``x_mm * MM_TO_NM`` is in nanometres.
"""

from __future__ import annotations

import math

#: millimetres -> nanometres
MM_TO_NM = 1e6
#: nanometres -> millimetres
NM_TO_MM = 1e-6
#: millimetres -> micrometres
MM_TO_UM = 1e3
#: micrometres -> millimetres
UM_TO_MM = 1e-3
#: micrometres -> nanometres
UM_TO_NM = 1e3
#: nanometres -> micrometres
NM_TO_UM = 1e-3
#: metres -> millimetres
M_TO_MM = 1e3
#: millimetres -> metres
MM_TO_M = 1e-3
#: kilometres -> millimetres (cutting distances)
KM_TO_MM = 1e6

#: minutes -> seconds
MIN_TO_S = 60.0
#: a rate per minute -> the same rate per second (feed mm/min -> mm/s)
PER_MIN_TO_PER_S = 1.0 / 60.0
#: spindle speed rpm -> angular speed rad/s
RPM_TO_RAD_PER_S = 2.0 * math.pi / 60.0
#: spindle speed rpm -> revolutions per second (Hz)
RPM_TO_HZ = 1.0 / 60.0

#: seconds -> milliseconds
S_TO_MS = 1e3
#: seconds -> microseconds
S_TO_US = 1e6

#: bytes -> GiB
BYTES_TO_GIB = 1.0 / 2**30
#: GiB -> bytes
GIB_TO_BYTES = 2**30
#: bytes -> MiB
BYTES_TO_MIB = 1.0 / 2**20
#: MiB -> bytes
MIB_TO_BYTES = 2**20

#: standard gravity in mm/s^2 (CGPM 1901; 9.80665 m/s^2)
STANDARD_GRAVITY_MM_S2 = 9806.65

__all__ = ["MM_TO_NM", "NM_TO_MM", "MM_TO_UM", "UM_TO_MM", "UM_TO_NM", "NM_TO_UM", "M_TO_MM",
           "MM_TO_M", "MIN_TO_S", "PER_MIN_TO_PER_S", "RPM_TO_RAD_PER_S", "RPM_TO_HZ",
           "S_TO_MS", "S_TO_US", "BYTES_TO_GIB", "GIB_TO_BYTES", "BYTES_TO_MIB",
           "MIB_TO_BYTES", "STANDARD_GRAVITY_MM_S2", "KM_TO_MM"]

#: radians -> microradians
RAD_TO_URAD = 1e6
#: microradians -> radians
URAD_TO_RAD = 1e-6
#: hertz -> kilohertz
HZ_TO_KHZ = 1e-3

__all__ += ["RAD_TO_URAD", "URAD_TO_RAD", "HZ_TO_KHZ"]

#: TiB -> bytes
TIB_TO_BYTES = 2**40

__all__ += ["TIB_TO_BYTES"]

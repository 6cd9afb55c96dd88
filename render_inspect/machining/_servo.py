"""The commands of a tool-servo program: the compensated Z program of the whole design,
z_cmd(t), split between the slow slide and the fast tool servo (Kong et al. 2020's
hybrid tool servo, S3 + FTS).

* ``hts``: the slow slide's share ``z_base`` = the compensated program of the design's
  *base* (``design.base`` of a compound design, e.g. the toric form), and the FTS stroke
  ``z_fts = z_cmd - z_base`` (the microstructure, e.g. the lenslet array);
* ``fts``: the slow slide's share = the rotationally symmetric part of the program (its
  mean over the centred spindle revolution, with the curvature bias of that window removed
  as 2 M(z) - M(M(z))), the FTS stroke = the rest.

Each share is then followed by its axis of the machine (``[machine.z]``, ``[machine.fts]``:
:mod:`render_inspect.machining._axes`, the package's one servo model), and the machined
surface is the envelope of the tool nose along the followed path.
"""

from __future__ import annotations

import math
from typing import Any, cast

import numpy as np

from ..core.errors import InputError, check_range
from ..core.toolpath import ToolPath
from ..toolpath import z_compensation

__all__ = ["split_commands"]


def _revolution_mean(theta, z):
    """Mean of z over the centred spindle revolution [theta - pi, theta + pi] (the
    rotationally symmetric part of a turning program), by the cumulative integral."""
    c = np.concatenate([[0.0], np.cumsum(0.5 * (z[1:] + z[:-1]) * np.diff(theta))])
    lo = np.clip(theta - math.pi, theta[0], theta[-1])
    hi = np.clip(theta + math.pi, theta[0], theta[-1])
    width = hi - lo
    mean = (np.interp(hi, theta, c) - np.interp(lo, theta, c)) / np.where(width > 0, width, 1.0)
    return np.where(width > 0, mean, z)


def split_commands(path: ToolPath, kind: str, *, base: Any = None,
                   nose_radius: float | None = None, compensation: str = "z",
                   half_width: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Split a turning program into the slow slide's and the FTS's commands.

    Parameters
    ----------
    path : ToolPath
        The compensated program of the whole design (tool tip).
    kind : {"hts", "fts"}
        ``hts``: slow slide = the program of ``base``; ``fts``: slow slide = the
        revolution mean of the program.
    base : Surface
        The base surface (``hts`` only).
    nose_radius, half_width : float, mm
        Tool nose radius and arc half-width (``hts`` with compensation).
    compensation : {"none", "normal", "z"}
        How the base program is compensated (``normal`` uses the Z form on the path's radii,
        which keeps the split in Z only).

    Returns
    -------
    z_slow, z_fts : (n,) float64, mm; z_slow + z_fts == path.z.
    """
    z = np.asarray(path.z, dtype=np.float64)
    if kind == "fts":
        th = np.asarray(path.theta, dtype=np.float64)
        m1 = _revolution_mean(th, z)
        # the window mean of a curved radial profile sits (F'' / 2) var(d rho) off it;
        # 2 M(z) - M(M(z)) cancels that term (harmonics in theta are removed by both)
        z_slow = 2 * m1 - _revolution_mean(th, m1)
    elif kind == "hts":
        if base is None:
            raise InputError("split_commands(kind='hts') needs the base surface")
        theta, rho = path.theta, path.rho
        if compensation == "none":
            z_slow = base.height(rho * np.cos(theta), rho * np.sin(theta))
        else:
            check_range("nose_radius", nose_radius, 0.0, None, lo_open=True)
            z_slow = z_compensation(base, theta, rho, cast(float, nose_radius), half_width=half_width)
    else:
        raise InputError(f"kind must be 'hts' or 'fts', received {kind!r}")
    z_slow = np.asarray(z_slow, dtype=np.float64)
    return z_slow, z - z_slow

"""The turning path prepared for the cutting-mechanics kernel (:mod:`._cut_kernel`): its
segments, the lookup table of their angles, the cutting distance and the material's
constants, for the whole path or the run of it one tile needs; and the cut by the direct
model for a path the kernel does not take (one that does not feed towards the axis)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..core.errors import InputError
from ..core.toolpath import ToolPath
from ._cut_inputs import Grooves, cutting_distance, mechanics_window
from ._cutting import cut_turning_mechanics, mechanics_path
from ._envelope_path import (EnvelopePath, _lookup_table, _nominal_spiral, _nose_arc, edge_table, edge_window,
                             path_radial_slope, path_revolution_step)

__all__ = ["CutPath", "prepare_cut"]


@dataclass(frozen=True)
class CutPath:
    """A turning path prepared for the cutting-mechanics kernel (or the run of it one tile
    needs, :meth:`slice_for`).

    Attributes
    ----------
    ep : EnvelopePath
        Segments, angles, the lookup table (always built) and the whole path's constants;
        ``ep.window`` is the mechanics window (:func:`mechanics_window`).
    dist : (m + 1,) float64
        Cutting distance at the segment ends (mm, counted from the whole path's start).
    h_min, kappa : float
        Minimum chip thickness (mm) and elastic recovery.
    side_flow : bool
    h_seg : (m,) float64
        The minimum chip thickness of each segment's pass (mm; a tool wearing along the
        path), or empty: ``h_min`` for every pass.
    z_rev : (float, float)
        The whole path's least and largest change of the tip's height from one
        revolution to the next at one angle (mm, signed; :func:`path_revolution_step`);
        (-inf, inf): unknown (the kernel then visits every pass of the window).
    """

    ep: EnvelopePath
    dist: np.ndarray
    h_min: float
    kappa: float
    side_flow: bool
    h_seg: np.ndarray = field(default_factory=lambda: np.zeros(0))
    z_rev: tuple[float, float] = (-math.inf, math.inf)

    def slice_for(self, region: Sequence[float]) -> "CutPath":
        """The passes whose nose arcs the kernel visits for pixels in ``region``
        (x0, y0, x1, y1; mm)."""
        sl = self.ep.slice_for(region)
        i0 = sl.offset - self.ep.offset
        h_seg = self.h_seg if self.h_seg.size == 0 else \
            np.ascontiguousarray(self.h_seg[i0:i0 + sl.seg.shape[0]])
        return replace(self, ep=sl, dist=np.ascontiguousarray(self.dist[i0:i0 + sl.theta.size]), h_seg=h_seg)

    def reach(self, rmin: float, rmax: float) -> float:
        """Largest radial distance (mm) between a pixel at rmin..rmax from the axis and a
        pass the kernel may visit there."""
        return self.ep.reach(rmin, rmax)

    @property
    def nbytes(self) -> int:
        return int(self.ep.nbytes + self.dist.nbytes + self.h_seg.nbytes)


def prepare_cut(path: ToolPath, *, nose_radius: float, half_width: float | None = None,
                h_min: float = 0.0,
                kappa: float = 0.0, side_flow: bool = True, slope_bound: float | None = None,
                edge: Any = None,
                h_min_points: np.ndarray | None = None) -> CutPath:
    """Prepare a turning path (``theta``, ``rho``, ``z``, mm and rad) for :func:`cut_fill`
    (parameters as :func:`~render_inspect.machining.cut_turning_mechanics`; ``edge``: the
    measured cutting edge, ``toolpath.EdgeProfile``, None for the circular nose;
    ``h_min_points``: the minimum chip thickness (mm) at each point of the path, the edge
    worn along it: each segment's pass takes its first point's, ``h_min`` then unused)."""
    theta, rho, z = mechanics_path(path, h_min=h_min, kappa=kappa)
    Rc, hw = _nose_arc(nose_radius, half_width)
    a, cc, dev, f = _nominal_spiral(theta, rho)
    m = path_radial_slope(theta, rho, z) if slope_bound is None else float(slope_bound)
    h_seg = np.zeros(0)
    if h_min_points is not None:
        hp = np.ascontiguousarray(h_min_points, dtype=np.float64)
        if hp.shape != theta.shape or not np.all(np.isfinite(hp)) or np.any(hp < 0):
            raise InputError(f"h_min_points must hold one finite value >= 0 per path point ({theta.size}), "
                             f"received {hp.size} values")
        h_seg = np.ascontiguousarray(hp[:-1])
        h_min = float(hp.max())
    W = mechanics_window(Rc, f, m, h_min, hw)
    etab = edge_table(edge, Rc, hw)
    W = edge_window(W, Rc, hw, etab)
    seg = np.empty((theta.size - 1, 4))
    seg[:, 0] = rho[:-1]
    seg[:, 1] = rho[1:] - rho[:-1]
    seg[:, 2] = z[:-1]
    seg[:, 3] = z[1:] - z[:-1]
    tab, tt0, tw = _lookup_table(theta)
    dth = (theta[-1] - theta[0]) / (theta.size - 1)
    ep = EnvelopePath(seg, theta, tab, tt0, tw, False, 1.0 / dth if dth > 0 else 0.0, 0, 0, theta.size,
                      float(theta[0]), float(theta[-1]), a, float(cc), dev, f, Rc, hw, float(W), etab)
    return CutPath(ep, cutting_distance(theta, rho), float(h_min), float(kappa), bool(side_flow), h_seg,
                   path_revolution_step(theta, z))


def _cut_direct(cp: CutPath, grooves: Grooves, *, region, pixel: float) -> dict:
    """:func:`cut_turning` by the direct model (a path that does not feed towards the axis)."""
    ep = cp.ep
    if cp.h_seg.size:
        raise InputError("tool.wear with a [material]: the edge worn along the path needs a path "
                         "that feeds towards the spindle axis")
    if ep.edge.size:
        raise InputError("tool.edge_profile / tool.waviness: a measured cutting edge needs a path "
                         "that feeds towards the spindle axis; remove the edge keys for this path")
    theta = ep.theta
    rho = np.append(ep.seg[:, 0], ep.seg[-1, 0] + ep.seg[-1, 1])
    z = np.append(ep.seg[:, 2], ep.seg[-1, 2] + ep.seg[-1, 3])
    c = cut_turning_mechanics(ToolPath(theta, rho, z, theta), nose_radius=ep.nose_radius, region=region,
                              pixel=pixel, half_width=ep.half_width, h_min=cp.h_min, kappa=cp.kappa,
                              side_flow=cp.side_flow)
    m = c["machined"]
    ok = np.isfinite(m) & np.isfinite(c["edge_pos"])
    along = np.interp(np.where(ok, c["pass_theta"], theta[0]), theta, cp.dist)
    g = np.zeros(m.shape)
    for i in range(grooves.ku.size):
        g += np.cos(grooves.ku[i] * c["edge_pos"] + grooves.kv[i] * along + grooves.ph[i])
    g = np.where(ok, g * grooves.scale, 0.0)
    m = np.where(ok, m + g, m)
    added = c["added"]
    return {"machined": m, "pass_theta": c["pass_theta"], "added": added,
            "grooves_sumsq": float(np.sum(g * g)) if grooves.ku.size else 0.0,
            "grooves_n": int(ok.sum()) if grooves.ku.size else 0,
            "added_max": float(np.max(added[ok])) if ok.any() else -math.inf}

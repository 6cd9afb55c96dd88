"""The BSDF of diamond-turned aluminium: a reflection grating with microroughness.

A turned surface carries its feed marks: grooves of period ``d`` (the feed per
revolution) running around the spindle axis, each a circular arc of the tool's nose
radius ``Rc``.  Light reflected by it is diffracted (scalar Kirchhoff theory, thin-element
approximation; Beckmann & Spizzichino 1963, Harvey 1976):

* directions are written as direction cosines in the surface's tangent plane:
  ``u`` across the marks (along the grating vector, the radial direction from the
  spindle axis for turning) and ``v`` along them;
* the grating equation: incident light of direction cosines ``(u_i, v_i)`` (the
  direction towards the light) leaves in the orders
  ``u_m = -u_i + m lambda / d``, ``v_m = -v_i`` (conical diffraction keeps ``v``),
  those with ``u_m^2 + v_m^2 < 1`` propagate;
* order ``m`` carries the fraction ``eta_m = |c_m|^2`` of the light, with
  ``c_m = (1/d) integral_0^d exp(-2 i k q h(x)) exp(-2 pi i m x / d) dx``, ``h`` the
  groove profile, ``k = 2 pi / lambda`` and ``q`` the cosine of the incidence
  (``(cos theta_i + cos theta_o) / 2`` in Beckmann's form; the cosine towards the camera
  here, so that one sampled order serves every light);
* the microroughness spreads each order into a lobe that is a Gaussian in direction
  cosines (Harvey-Shack: scatter is shift-invariant in direction-cosine space), of
  standard deviations ``sigma_u`` across and ``sigma_v`` along the marks (the
  anisotropic scatter of turned surfaces);
* the whole is weighted by aluminium's Fresnel reflectance at the wavelength
  (Mitsuba's spectral data for Al: ``data/ior/Al.{eta,k}.spd``).

So ``f(wi, wo) cos(theta_o) = R(lambda) sum_m eta_m G(u_o - u_m, v_o - v_m) cos(theta_o)``,
reciprocal and energy conserving up to the evanescent orders.  The orders fan out with
the wavelength: that is the rainbow of turned parts.  The model needs a spectral
Mitsuba variant (each path carries four wavelengths; a direction is sampled for one of
them, chosen at random, and every wavelength is weighted by its own BSDF over the mean
of the four sampling densities: one-sample multiple importance sampling over the
wavelengths, as hero-wavelength spectral rendering does).

Without a period (marks finer than a wavelength, or the micro view where the marks are
in the mesh) only the order ``m = 0`` is left: an anisotropic rough conductor whose
lobe is stretched across the marks.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any, cast

import numpy as np
from numpy.typing import ArrayLike

from ..core.errors import InputError
from ..core.units import NM_TO_MM
from ._variant import import_mitsuba

__all__ = ["grating_efficiencies", "efficiency_tables", "aluminium_nk", "register_turned_bsdf",
           "WAVELENGTHS_NM", "Q_NODES", "LOBE_TERMS"]

#: wavelength grid of the efficiency tables, nm (the visible range of Mitsuba's spectral
#: variants, 5 nm apart)
WAVELENGTHS_NM = np.arange(360.0, 830.0 + 1e-9, 5.0)
#: incidence cosines of the efficiency tables
Q_NODES = np.linspace(0.3, 1.0, 8)
#: orders summed on each side of the nearest one when a BSDF value is evaluated
LOBE_TERMS = 6
#: the most orders on either side kept in a table
MAX_ORDER = 3000

_TABLES: dict = {}
_REGISTERED: set = set()


def grating_efficiencies(profile_mm: ArrayLike, *, period: float, wavelength_nm: float, q: float = 1.0,
                         orders: int) -> np.ndarray:
    """Diffraction efficiencies of a reflection grating in the thin-element (Kirchhoff)
    approximation.

    Parameters
    ----------
    profile_mm : (n,) array
        Groove height over one period, sampled at ``(i + 0.5) period / n``, mm.
    period : float
        mm.
    wavelength_nm : float
    q : float
        Cosine of the incidence (scales the phase depth).
    orders : int
        Orders ``-orders .. orders`` are returned.

    Returns
    -------
    (2 orders + 1,) float64
        ``eta_m = |c_m|^2``; they sum to 1 over all (propagating and evanescent) orders.
    """
    h = np.asarray(profile_mm, dtype=np.float64)
    n = h.size
    if n < 2 * orders + 1:
        raise InputError(f"profile_mm needs at least {2 * orders + 1} samples for {orders} "
                         f"orders, got {n}")
    k = 2 * math.pi / (wavelength_nm * NM_TO_MM)
    c = np.fft.fft(np.exp(-2j * k * q * h)) / n
    m = np.arange(-orders, orders + 1)
    return np.abs(c[m % n]) ** 2


def arc_profile(period: float, nose_radius: float, n: int) -> np.ndarray:
    """One period of the feed scallop: circular arcs of radius ``nose_radius`` (mm)
    meeting in cusps ``period`` apart; ``n`` samples, heights mm (cusp highest)."""
    x = (np.arange(n) + 0.5) / n * period - period / 2
    r = float(nose_radius)
    return -(r - np.sqrt(np.maximum(r * r - x * x, 0.0)))


def efficiency_tables(*, period: float | None, nose_radius: float | None) -> dict:
    """Efficiencies, their cumulative sums (for sampling an order) and normalisation per
    (wavelength, incidence cosine), for marks of ``period`` (mm) cut by a nose of
    ``nose_radius`` (mm).  ``period=None``: the single order 0.

    Returns
    -------
    dict with ``eta``, ``cdf`` ((L, Q, 2M + 1) float32), ``norm`` ((L, Q) float32),
    ``orders`` (M), ``period_mm``, ``first_order_efficiency_550nm`` (normal incidence).
    The arrays are read-only: the tables of the last few (period, nose radius) pairs are
    kept, so that the passes of one image (the same marks, every pass a render) compute
    them once.
    """
    return dict(_efficiency_tables(None if period is None else float(period),
                                   None if nose_radius is None else float(nose_radius)))


@functools.lru_cache(maxsize=8)
def _efficiency_tables(period: float | None, nose_radius: float | None) -> dict:
    L, Q = WAVELENGTHS_NM.size, Q_NODES.size
    if period is None:
        eta = np.ones((L, Q, 1))
        M = 0
    else:
        M = int(min(math.ceil(period / (WAVELENGTHS_NM[0] * NM_TO_MM)) + 1, MAX_ORDER))
        n = 1 << int(math.ceil(math.log2(max(8 * (2 * M + 1), 4096))))
        h = arc_profile(period, cast(float, nose_radius), n)  # (marks with a period have a nose)
        eta = np.empty((L, Q, 2 * M + 1))
        for i, lam in enumerate(WAVELENGTHS_NM):
            for j, q in enumerate(Q_NODES):
                eta[i, j] = grating_efficiencies(h, period=period, wavelength_nm=lam, q=q,
                                                 orders=M)
    cdf = np.cumsum(eta, axis=-1)
    norm = cdf[..., -1].copy()
    cdf = cdf / norm[..., None]
    i550 = int(np.argmin(np.abs(WAVELENGTHS_NM - 550.0)))
    first = float(eta[i550, -1, M + 1]) if M > 0 else 0.0
    arrays = {"eta": eta.astype(np.float32), "cdf": cdf.astype(np.float32),
              "norm": norm.astype(np.float32)}
    for a in arrays.values():
        a.flags.writeable = False
    return {**arrays, "orders": M, "period_mm": period, "first_order_efficiency_550nm": first,
            "zero_order_efficiency_550nm": float(eta[i550, -1, M])}


def aluminium_nk(wavelengths_nm: np.ndarray | Sequence[float] = WAVELENGTHS_NM) -> tuple[np.ndarray, np.ndarray]:
    """Complex refractive index (n, k) of aluminium at ``wavelengths_nm``, from the
    spectral data Mitsuba ships (``mitsuba/data/ior/Al.eta.spd``, ``Al.k.spd``)."""
    mi, _, _ = import_mitsuba()
    root = Path(mi.__file__).resolve().parent / "data" / "ior"
    out = []
    for name in ("Al.eta.spd", "Al.k.spd"):
        a = np.loadtxt(root / name, comments="#")
        out.append(np.interp(wavelengths_nm, a[:, 0], a[:, 1]))
    return out[0], out[1]


def register_turned_bsdf(mi: Any, dr: Any) -> str:
    """Register the ``turned_al`` BSDF plugin for the current (spectral) variant; return
    its plugin name."""
    variant = mi.variant()
    if variant in _REGISTERED:
        return "turned_al"
    if "spectral" not in variant:
        raise InputError(f"the turned-aluminium BSDF needs a spectral Mitsuba variant, got {variant}")
    cls = _make_class(mi, dr)
    mi.register_bsdf("turned_al", lambda props: cls(props))
    _REGISTERED.add(variant)
    return "turned_al"


def store_tables(key: str, tables: dict) -> None:
    """Keep the tables a ``turned_al`` BSDF with ``table_key = key`` reads."""
    _TABLES[key] = tables


def _fresnel_conductor(dr, cos_i, eta, k):
    """Unpolarised Fresnel reflectance of a conductor (eta + i k) at incidence cosine
    ``cos_i`` (exact)."""
    c2 = cos_i * cos_i
    s2 = 1.0 - c2
    e2 = eta * eta
    k2 = k * k
    t0 = e2 - k2 - s2
    a2b2 = dr.sqrt(dr.maximum(t0 * t0 + 4.0 * e2 * k2, 0.0))
    a = dr.sqrt(dr.maximum(0.5 * (a2b2 + t0), 0.0))
    t1 = a2b2 + c2
    t2 = 2.0 * cos_i * a
    rs = (t1 - t2) / (t1 + t2)
    t3 = c2 * a2b2 + s2 * s2
    t4 = t2 * s2
    rp = rs * (t3 - t4) / (t3 + t4)
    return 0.5 * (rp + rs)


def _make_class(mi, dr):
    lam0 = float(WAVELENGTHS_NM[0])
    dlam = float(WAVELENGTHS_NM[1] - WAVELENGTHS_NM[0])
    nl = WAVELENGTHS_NM.size
    nq = Q_NODES.size
    q0 = float(Q_NODES[0])
    dq = float(Q_NODES[1] - Q_NODES[0])
    n_al, k_al = aluminium_nk()

    class TurnedAluminium(mi.BSDF):
        """Aluminium with feed marks: grating orders spread by an anisotropic Gaussian
        lobe (see the module docstring).  Properties: ``table_key`` (str), ``period_mm``
        (float, <= 0: no grating), ``sigma_u``, ``sigma_v`` (lobe widths in direction
        cosines across / along the marks), ``kind`` (0: circular marks about
        (``cx``, ``cy``); 1: straight marks along (``dx``, ``dy``))."""

        def __init__(self, props):
            mi.BSDF.__init__(self, props)
            t = _TABLES[str(props.get("table_key"))]
            self.period = float(props.get("period_mm", 0.0))
            self.su = float(props.get("sigma_u", 0.01))
            self.sv = float(props.get("sigma_v", 0.004))
            self.kind = int(props.get("kind", 0))
            self.cx = float(props.get("cx", 0.0))
            self.cy = float(props.get("cy", 0.0))
            self.dx = float(props.get("dx", 0.0))
            self.dy = float(props.get("dy", 1.0))
            self.M = int(t["orders"])
            self.W = 2 * self.M + 1
            self.eta = mi.Float(np.ascontiguousarray(t["eta"]).ravel())
            self.cdf = mi.Float(np.ascontiguousarray(t["cdf"]).ravel())
            self.norm = mi.Float(np.ascontiguousarray(t["norm"]).ravel())
            self.n_al = mi.Float(n_al.astype(np.float32))
            self.k_al = mi.Float(k_al.astype(np.float32))
            # orders summed around the nearest one: enough to cover 3.5 lobe widths
            if self.period > 0 and self.M > 0:
                spacing = lam0 * NM_TO_MM / self.period
                self.terms = int(min(LOBE_TERMS, math.ceil(3.5 * self.su / spacing)))
            else:
                self.terms = 0
            flags = (mi.BSDFFlags.GlossyReflection | mi.BSDFFlags.FrontSide
                     | mi.BSDFFlags.Anisotropic)
            self.m_flags = flags
            self.m_components = [flags]

        # --- geometry -------------------------------------------------------------
        def _frame(self, si):
            """Unit vector across the marks in the local shading frame (gx, gy)."""
            if self.kind == 0:
                g = si.to_local(mi.Vector3f(si.p.x - self.cx, si.p.y - self.cy, 0.0))
            else:
                # straight marks along (dx, dy): across is the perpendicular
                g = si.to_local(mi.Vector3f(-self.dy, self.dx, 0.0))
            gn = dr.sqrt(g.x * g.x + g.y * g.y)
            ok = gn > 1e-12
            return dr.select(ok, g.x / gn, 1.0), dr.select(ok, g.y / gn, 0.0)

        def _bins(self, lam, q):
            li = dr.clip(mi.UInt32(dr.round((lam - lam0) / dlam)), 0, nl - 1)
            qi = dr.clip(mi.UInt32(dr.round((q - q0) / dq)), 0, nq - 1)
            return li, qi

        def _lobes(self, lam, au, av, u, v, q, active):
            """sum_m eta_m G(u - u_m, v + av) and the table's normalisation, for one
            wavelength (nm)."""
            li, qi = self._bins(lam, q)
            row = li * nq + qi
            base = row * self.W
            dv = (v + av) / self.sv
            gv = -0.5 * dv * dv
            s = mi.Float(0.0)
            if self.terms == 0:
                e = dr.gather(mi.Float, self.eta, base + self.M, active)
                du = (u + au) / self.su
                s = e * dr.exp(gv - 0.5 * du * du)
            else:
                rel = lam * NM_TO_MM / self.period
                m0 = dr.round((u + au) / rel)
                for kk in range(-self.terms, self.terms + 1):
                    m = m0 + kk
                    ok = active & (dr.abs(m) <= self.M)
                    idx = mi.UInt32(dr.clip(m + self.M, 0, self.W - 1))
                    e = dr.gather(mi.Float, self.eta, base + idx, ok)
                    du = (u + au - m * rel) / self.su
                    s += dr.select(ok, e * dr.exp(gv - 0.5 * du * du), 0.0)
            nrm = dr.gather(mi.Float, self.norm, row, active)
            return s / (2.0 * math.pi * self.su * self.sv), nrm

        def _reflectance(self, lam, cos_i):
            li = dr.clip(mi.UInt32(dr.round((lam - lam0) / dlam)), 0, nl - 1)
            return _fresnel_conductor(dr, cos_i, dr.gather(mi.Float, self.n_al, li),
                                      dr.gather(mi.Float, self.k_al, li))

        def _eval_pdf(self, si, wo, active):
            wi = si.wi
            gx, gy = self._frame(si)
            au = wi.x * gx + wi.y * gy
            av = -wi.x * gy + wi.y * gx
            u = wo.x * gx + wo.y * gy
            v = -wo.x * gy + wo.y * gx
            act = active & (wi.z > 0) & (wo.z > 0)
            vals = []
            pdf = mi.Float(0.0)
            n = dr.size_v(mi.Spectrum)
            for j in range(n):
                lam = si.wavelengths[j]
                s, nrm = self._lobes(lam, au, av, u, v, wi.z, act)
                vals.append(s * self._reflectance(lam, wi.z) * wo.z)
                pdf += s / nrm * wo.z
            val = mi.Spectrum(*vals)
            pdf = pdf / n
            return dr.select(act, val, 0.0), dr.select(act, pdf, 0.0)

        def eval(self, ctx, si, wo, active=True):
            return self._eval_pdf(si, wo, active)[0]

        def pdf(self, ctx, si, wo, active=True):
            return self._eval_pdf(si, wo, active)[1]

        def eval_pdf(self, ctx, si, wo, active=True):
            return self._eval_pdf(si, wo, active)

        def sample(self, ctx, si, sample1, sample2, active=True):
            wi = si.wi
            gx, gy = self._frame(si)
            au = wi.x * gx + wi.y * gy
            av = -wi.x * gy + wi.y * gx
            n = dr.size_v(mi.Spectrum)
            jf = dr.minimum(dr.floor(sample1 * n), n - 1)
            s1 = dr.clip(sample1 * n - jf, 0.0, 1.0)
            lam = si.wavelengths[n - 1]
            for j in range(n - 2, -1, -1):
                lam = dr.select(jf < j + 0.5, si.wavelengths[j], lam)
            u = -au
            if self.terms > 0 or self.M > 0:
                li, qi = self._bins(lam, wi.z)
                base = (li * nq + qi) * self.W
                idx = dr.binary_search(0, self.W - 1,
                                       lambda i: dr.gather(mi.Float, self.cdf, base + i) < s1)
                m = mi.Float(mi.Int32(idx) - self.M)
                if self.period > 0:
                    u = u + m * (lam * NM_TO_MM / self.period)
            r = dr.sqrt(-2.0 * dr.log(dr.maximum(1.0 - sample2.x, 1e-12)))
            ph = 2.0 * math.pi * sample2.y
            u = u + self.su * r * dr.cos(ph)
            v = -av + self.sv * r * dr.sin(ph)
            z2 = 1.0 - u * u - v * v
            ok = active & (z2 > 1e-8) & (wi.z > 0)
            wo = mi.Vector3f(u * gx - v * gy, u * gy + v * gx, dr.safe_sqrt(z2))
            bs = dr.zeros(mi.BSDFSample3f)
            bs.wo = wo
            bs.eta = 1.0
            bs.sampled_type = mi.UInt32(+mi.BSDFFlags.GlossyReflection)
            bs.sampled_component = mi.UInt32(0)
            val, pdf = self._eval_pdf(si, wo, ok)
            bs.pdf = pdf
            ok &= pdf > 0
            return bs, dr.select(ok, val / dr.maximum(pdf, 1e-20), 0.0)

        def traverse(self, callback):
            pass

        def to_string(self):
            return (f"TurnedAluminium[period_mm={self.period}, orders={self.M}, "
                    f"sigma_u={self.su}, sigma_v={self.sv}]")

    return TurnedAluminium

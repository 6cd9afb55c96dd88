"""The lights of the diffuse views, beyond the dome and the ring: a photo studio for the
whole part, and a microscope's brightfield for the close-up.  Plain numbers in, plain
numbers out (the Mitsuba scene turns them into an ``envmap`` image).

Studio (macro view of a part with tool marks).  How a diamond-turned part is
photographed: in a dim room (a ceiling brighter than the walls, a dark grey floor and
backdrop), under a large softbox whose mirror image covers part of the face, and a small
bright lamp whose highlight the feed marks fan out into the rainbow of a grating.  All
of it is at infinity (an environment), so the part's mirror shows the softbox as a sharp
bright shape, distorted by the form, and the turning marks spread its edges and the
lamp radially (across the marks).  Where the lights are is staging; what the surface
does with them (the conductor's Fresnel reflectance, the grating orders of the feed
marks, the roughness lobe wider across the marks than along them) is the model.

Brightfield (micro view).  A reflected-light microscope illuminates through its
objective (Koehler illumination filling the pupil) and accepts the light that comes
back within its numerical aperture: a flat mirror is bright, a facet tilted by ``s``
sends the illumination cone off by ``2 s`` and darkens as the two cones overlap less,
black beyond ``asin(NA_ill) + asin(NA)``.  :func:`brightfield_profile` is that overlap as
a function of the reflected axis' angle from the optical axis: the light at infinity an
orthographic camera sees through a mirror (the pupil's average over its cone is baked
into the profile, so a pinhole render gives the aperture's picture).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["brightfield_profile", "studio_light", "studio_environment", "cap_overlap",
           "STUDIO_ROOM", "SOFTBOX_RADIANCE", "LAMP_RADIUS_DEG"]

#: the room of the studio: radiance against zenith angle (ceiling, walls), and the floor
STUDIO_ROOM = {"zenith_profile": [[0.0, 0.10], [60.0, 0.05], [90.0, 0.025]], "floor": 0.02}
#: radiance of the softbox (aluminium reflects ~0.92 of it: a light grey in the image, so
#: the colours at its edges show)
SOFTBOX_RADIANCE = 0.8
#: a softbox's radiance at its upper and lower edge, relative to its middle
SOFTBOX_EDGE = 0.3
#: angular size of the softbox (deg): across (azimuth) and along the zenith angle
SOFTBOX_SIZE_DEG = (28.0, 16.0)
#: the strip light behind the camera (its image: the front chamfer's bright line)
STRIP_ELEVATION_DEG = 20.0
STRIP_SIZE_DEG = (80.0, 20.0)
STRIP_RADIANCE = 0.6
#: angular radius of the small lamp (deg): a bulb of 5 cm at 3 m
LAMP_RADIUS_DEG = 1.0
#: knots of a brightfield profile (renderers take piecewise-linear profiles)
PROFILE_KNOTS = 32


def cap_overlap(a: float, b: float, d: ArrayLike) -> np.ndarray:
    """Fraction of a disc of angular radius ``a`` centred ``d`` away from the centre of a
    disc of radius ``b`` that lies inside it (flat-angle approximation, rad)."""
    d = np.abs(np.asarray(d, dtype=np.float64))
    out = np.zeros_like(d)
    inside = d <= abs(b - a)
    out[inside] = 1.0 if b >= a else (b * b) / (a * a)
    part = (d < a + b) & ~inside
    dd = d[part]
    with np.errstate(invalid="ignore"):
        t1 = a * a * np.arccos(np.clip((dd * dd + a * a - b * b) / (2 * dd * a), -1, 1))
        t2 = b * b * np.arccos(np.clip((dd * dd + b * b - a * a) / (2 * dd * b), -1, 1))
        t3 = 0.5 * np.sqrt(np.maximum((-dd + a + b) * (dd + a - b) * (dd - a + b) * (dd + a + b), 0))
    out[part] = (t1 + t2 - t3) / (math.pi * a * a)
    return out


def brightfield_profile(na: float, illumination_na: float | None = None) -> list:
    """The brightfield light of an objective of numerical aperture ``na`` (its
    illumination filling ``illumination_na``, default the same) as ``[angle_deg,
    radiance]`` pairs against the angle of the reflected optical axis from the axis: the
    fraction of the pupil's cone the illumination cone covers (:func:`cap_overlap`)."""
    a = math.asin(min(float(na), 0.99))
    b = math.asin(min(float(illumination_na if illumination_na is not None else na), 0.99))
    top = math.degrees(a + b)
    ang = np.linspace(0.0, top, PROFILE_KNOTS - 1)
    val = cap_overlap(a, b, np.radians(ang))
    pairs = [[float(x), float(v)] for x, v in zip(ang, val)]
    pairs[-1][1] = 0.0
    pairs.append([180.0, 0.0])
    return pairs


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v)


def studio_light(camera_origin: ArrayLike, target: ArrayLike, *,
                 lamp_direction: ArrayLike | None = None,
                 lamp_radiance: float | None = None) -> dict:
    """The studio of the macro view as plain numbers: the room; a softbox placed where the
    part's mirror image of it faces the camera (behind the part, a little above the
    camera's elevation: it covers the far half of the face); a strip light behind the
    camera, low, whose image is the bright line along the front chamfer; and the lamp
    (``lamp_direction``: the unit vector from the part to it; its radiance).

    Returns a dict ``type = "studio"`` with ``zenith_profile`` and ``floor`` (the room),
    ``softboxes`` (each ``direction``, ``size_deg`` = (across, up), ``radiance``) and
    ``lamp`` (``direction``, ``radius_deg``, ``radiance``: None until the renderer chooses
    it) or None."""
    view = _unit(np.subtract(target, camera_origin))
    mirror = view * np.array([1.0, 1.0, -1.0])        # off a flat face: towards the softbox
    el = math.degrees(math.asin(np.clip(mirror[2], -1, 1)))
    az = math.atan2(mirror[1], mirror[0])

    def at(elevation_deg, azimuth):
        e = math.radians(elevation_deg)
        return [math.cos(e) * math.cos(azimuth), math.cos(e) * math.sin(azimuth), math.sin(e)]

    boxes = [{"direction": at(min(el + 0.3 * SOFTBOX_SIZE_DEG[1], 80.0), az),
              "size_deg": list(SOFTBOX_SIZE_DEG), "radiance": SOFTBOX_RADIANCE},
             {"direction": at(STRIP_ELEVATION_DEG, az + math.pi),
              "size_deg": list(STRIP_SIZE_DEG), "radiance": STRIP_RADIANCE}]
    return {"type": "studio", "zenith_profile": STUDIO_ROOM["zenith_profile"],
            "floor": STUDIO_ROOM["floor"], "softboxes": boxes,
            "lamp": None if lamp_direction is None else {
                "direction": [float(v) for v in _unit(lamp_direction)],
                "radius_deg": LAMP_RADIUS_DEG,
                "radiance": None if lamp_radiance is None else float(lamp_radiance)},
            "up": [0.0, 0.0, 1.0]}


def _edge(x, half, soft):
    """1 inside ``|x| < half``, 0 outside, linear over ``soft`` at the edge."""
    return np.clip((half - np.abs(x)) / soft + 0.5, 0.0, 1.0)


def studio_environment(light: dict, *, height: int = 361) -> np.ndarray:
    """The studio as a lat-long RGB image (rows: zenith angle 0..180 deg; columns: the
    azimuth convention of :func:`~render_inspect.render.environment_map`)."""
    theta = np.arange(height) / (height - 1) * math.pi
    width = 2 * (height - 1)
    alpha = math.pi / 2 - (np.arange(width) + 0.5) / width * 2 * math.pi
    st, ct = np.sin(theta)[:, None], np.cos(theta)[:, None]
    d = np.stack([st * np.cos(alpha)[None, :], st * np.sin(alpha)[None, :],
                  np.broadcast_to(ct, (height, width))], axis=-1)
    prof = np.asarray(light["zenith_profile"], dtype=np.float64)
    zen = np.degrees(theta)
    room = np.interp(zen, prof[:, 0], prof[:, 1])
    rad = np.where(zen <= 90.0, room, light["floor"])[:, None] * np.ones((1, width))
    soft = math.radians(360.0 / width)
    for box in light.get("softboxes") or ():
        c = _unit(box["direction"])
        u = _unit(np.cross([0.0, 0.0, 1.0], c))          # horizontal across the box
        v = np.cross(c, u)                                 # up along the box
        dc = d @ c
        with np.errstate(invalid="ignore", divide="ignore"):
            au = np.arctan2(d @ u, dc)
            av = np.arctan2(d @ v, dc)
        w, h = (math.radians(x) / 2 for x in box["size_deg"])
        m = np.where(dc > 0, _edge(au, w, soft) * _edge(av, h, soft), 0.0)
        # a gradient softbox: brightest along its middle, so a flat mirror shows a gradient
        g = SOFTBOX_EDGE + (1 - SOFTBOX_EDGE) * np.cos(np.clip(av / h, -1, 1) * math.pi / 2) ** 2
        rad = rad * (1 - m) + m * float(box["radiance"]) * g
    lamp = light.get("lamp")
    if lamp and lamp.get("radiance"):
        ang = np.arccos(np.clip(d @ _unit(lamp["direction"]), -1, 1))
        m = _edge(ang, math.radians(lamp["radius_deg"]), soft)
        rad = rad * (1 - m) + m * float(lamp["radiance"])
    return np.ascontiguousarray(np.repeat(rad.astype(np.float32)[..., None], 3, axis=2))

"""``[design]``: the design surface.  Lengths in mm; angles in rad unless ``_deg``."""

from __future__ import annotations

from typing import Annotated, Literal, Union

from pydantic import Field, model_validator

from ._base import Section


class SinusoidalGrid(Section):
    """z = Ax cos(2 pi x / lx + px) + Ay cos(2 pi y / ly + py) + offset (seed 000)."""
    type: Literal["sinusoidal_grid"]
    amplitude_x: float = Field(0.002, ge=0, le=1.0, description="mm")
    amplitude_y: float = Field(0.002, ge=0, le=1.0, description="mm")
    wavelength_x: float = Field(2.5, gt=0, description="mm")
    wavelength_y: float = Field(2.5, gt=0, description="mm")
    phase_x: float = Field(0.0, description="rad")
    phase_y: float = Field(0.0, description="rad")
    offset: float = Field(0.0, description="mm")


class Plane(Section):
    """z = slope_x x + slope_y y + offset."""
    type: Literal["plane"]
    slope_x: float = Field(0.0, ge=-10, le=10, description="dz/dx")
    slope_y: float = Field(0.0, ge=-10, le=10, description="dz/dy")
    offset: float = 0.0


class Sphere(Section):
    """Sphere with apex at (x0, y0, offset); radius > 0 convex (cap up), < 0 concave."""
    type: Literal["sphere"]
    radius: float = Field(..., description="mm; > 0 convex, < 0 concave; |radius| > 0")
    x0: float = 0.0
    y0: float = 0.0
    offset: float = 0.0

    @model_validator(mode="after")
    def _nonzero(self):
        if self.radius == 0:
            raise ValueError("radius must be non-zero (> 0 convex, < 0 concave), received 0")
        return self


class Toric(Section):
    """Toric surface with principal radii along x (radius_x) and y (radius_y).
    Sign as for sphere: > 0 convex, < 0 concave."""
    type: Literal["toric"]
    radius_x: float
    radius_y: float
    offset: float = 0.0

    @model_validator(mode="after")
    def _nonzero(self):
        for k in ("radius_x", "radius_y"):
            if getattr(self, k) == 0:
                raise ValueError(f"{k} must be non-zero, received 0")
        return self


class Biconic(Section):
    """Biconic sag; conic 0 = sphere-like sections, -1 = paraboloid.
    Sign as for sphere: > 0 convex, < 0 concave.  ``type = "paraboloid"`` is the biconic
    with conic_x = conic_y = -1 (the default there; other conics are rejected)."""
    type: Literal["biconic", "paraboloid"]
    radius_x: float
    radius_y: float
    conic_x: float = 0.0
    conic_y: float = 0.0
    offset: float = 0.0

    @model_validator(mode="before")
    @classmethod
    def _paraboloid(cls, data):
        if isinstance(data, dict) and data.get("type") == "paraboloid":
            data = dict(data)
            for k in ("conic_x", "conic_y"):
                v = data.setdefault(k, -1.0)
                if v != -1:
                    raise ValueError(f"{k} must be -1 for type = 'paraboloid' (use type = "
                                     f"'biconic' for other conics), received {v!r}")
        return data

    @model_validator(mode="after")
    def _nonzero(self):
        for k in ("radius_x", "radius_y"):
            if getattr(self, k) == 0:
                raise ValueError(f"{k} must be non-zero, received 0")
        return self


class LensletArray(Section):
    """Spherical lenslets on a rectangular grid (seed 000 Table 4, seed 002, seed 003).

    ``cells = "round"``: each lenslet is a spherical cap of aperture radius
    ``aperture_radius`` on a flat (base) surface at ``offset``; concave lenslets are
    dimples below it, convex ones bumps above it.  ``cells = "quad"``: sharp-edged
    quadrilateral cells filling the grid (seed 003), ``z = offset +- s^2/(r + sqrt(r^2 - s^2))``
    (the cell centre at ``offset``), the blank outside the array at the corners' level.
    Give either ``lens_radius`` or (round cells) ``sag``, the chord height of one
    lenslet: ``lens_radius = (aperture_radius^2 + sag^2) / (2 sag)``.
    Centres: ``center + (j - (cols-1)/2) pitch_x``, ``center + (i - (rows-1)/2) pitch_y``."""
    type: Literal["lenslet_array"]
    rows: int = Field(2, ge=1, le=1000)
    cols: int = Field(2, ge=1, le=1000)
    pitch_x: float = Field(..., gt=0, description="mm, centre spacing along x")
    pitch_y: float = Field(..., gt=0, description="mm, centre spacing along y")
    lens_radius: float | None = Field(None, gt=0, description="mm, radius of curvature of each lenslet")
    sag: float | None = Field(None, gt=0, description="mm, chord height of a round lenslet "
                                                      "(instead of lens_radius)")
    aperture_radius: float | None = Field(None, gt=0, description="mm, round cells only")
    concave: bool = True
    cells: Literal["round", "quad"] = "round"
    center_x: float = 0.0
    center_y: float = 0.0
    offset: float = 0.0

    @model_validator(mode="after")
    def _aperture(self):
        if (self.lens_radius is None) == (self.sag is None):
            raise ValueError("give exactly one of lens_radius (mm, radius of curvature) and sag "
                             f"(mm, chord height), received lens_radius={self.lens_radius}, "
                             f"sag={self.sag}")
        if self.cells == "round":
            if self.aperture_radius is None:
                raise ValueError("aperture_radius is required for cells = 'round'")
            half = min(self.pitch_x, self.pitch_y) / 2
            if self.aperture_radius > half:
                raise ValueError(f"aperture_radius must be <= half the smaller pitch ({half:g} mm; "
                                 f"round lenslets may not overlap), received {self.aperture_radius}")
            if self.sag is not None and self.sag >= self.aperture_radius:
                raise ValueError(f"sag must be < aperture_radius ({self.aperture_radius} mm, a "
                                 f"lenslet is at most a hemisphere), received {self.sag}")
            if self.lens_radius is not None and self.aperture_radius >= self.lens_radius:
                raise ValueError(f"aperture_radius must be < lens_radius ({self.lens_radius}), "
                                 f"received {self.aperture_radius}")
        else:
            if self.sag is not None:
                raise ValueError("sag is only defined for cells = 'round' (give lens_radius for "
                                 f"quad cells), received sag={self.sag}")
            if self.aperture_radius is not None:
                raise ValueError("aperture_radius is only used with cells = 'round' (a quad cell's "
                                 f"aperture is the pitch), received {self.aperture_radius}")
            half_diag = 0.5 * (self.pitch_x ** 2 + self.pitch_y ** 2) ** 0.5
            if half_diag >= self.lens_radius:
                raise ValueError(f"lens_radius must be > half the cell diagonal ({half_diag:g} mm) "
                                 f"for cells = 'quad', received {self.lens_radius}")
        return self


class LensletRings(Section):
    """Lenslets (spherical elements) on concentric rings (seed 004)."""
    type: Literal["lenslet_rings"]
    ring_radii: list[float] = Field(..., min_length=1, description="mm, ring radii")
    counts: list[int] = Field(..., min_length=1, description="elements per ring")
    element_radius: float = Field(..., gt=0, description="mm, plane (aperture) radius of an element")
    depth: float = Field(..., gt=0, description="mm, sag of an element")
    concave: bool = True
    phase_deg: float = 0.0
    offset: float = 0.0

    @model_validator(mode="after")
    def _lengths(self):
        if len(self.ring_radii) != len(self.counts):
            raise ValueError(f"ring_radii and counts must have the same length, received "
                             f"{len(self.ring_radii)} and {len(self.counts)}")
        if any(r < 0 for r in self.ring_radii):
            raise ValueError(f"ring_radii must be >= 0, received {self.ring_radii}")
        if any(c < 1 for c in self.counts):
            raise ValueError(f"counts must be >= 1, received {self.counts}")
        if self.depth >= self.element_radius:
            raise ValueError(f"depth must be < element_radius ({self.element_radius}), received {self.depth}")
        return self


class Expression(Section):
    """A user expression in x and y (mm), evaluated safely (whitelisted functions)."""
    type: Literal["expression"]
    expr: str = Field(..., min_length=1, max_length=2000)
    constants: dict[str, float] = Field(default_factory=dict)


class HeightMapDesign(Section):
    """A height map loaded from EXR (channel ``channel``) or .npy, interpolated."""
    type: Literal["heightmap"]
    path: str
    channel: str = "design"
    pixel: float | None = Field(None, gt=0, description="mm; required for .npy")
    origin: tuple[float, float] | None = Field(None, description="mm, centre of pixel [0, 0]; .npy")
    interpolation: Literal["linear", "cubic"] = "cubic"


class Compound(Section):
    """Base + feature (seed 001, seed 002): heights add."""
    type: Literal["compound"]
    base: "DesignConfig"
    feature: "DesignConfig"


DesignConfig = Annotated[
    Union[SinusoidalGrid, Plane, Sphere, Toric, Biconic, LensletArray, LensletRings,
          Expression, HeightMapDesign, Compound],
    Field(discriminator="type"),
]
Compound.model_rebuild()

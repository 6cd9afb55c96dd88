"""``[metrology]``: how measured or simulated maps are characterised."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from ..core.section import Section


class MetrologyConfig(Section):
    form_removal: Literal["none", "plane", "polynomial", "sphere", "design"] = "plane"
    polynomial_degree: int = Field(2, ge=1, le=10)
    s_filter: float | None = Field(None, gt=0, description="mm, ISO 16610-61 S-filter nesting index "
                                                          "(None: chosen from the tool marks)")
    l_filter: float | None = Field(None, gt=0, description="mm, L-filter nesting index (None: "
                                                          "chosen from the design's feature size)")
    filter_edges: Literal["cut", "mirror"] = Field(
        "cut", description="edges of the S/L-filtered maps: cut half the nesting index, or "
                           "extend by the mirror image (cut falls back to mirror on small windows)")
    outlier_sigma: float = Field(3.0, gt=0, le=20,
                                 description="k of the k-sigma spike (outlier) rule")
    outliers: Literal["none", "sigma"] = Field(
        "none", description="leave the k-sigma outliers out of the parameters of a measured map "
                            "(they are always left out of its registration and counted)")
    registration: Literal["none", "lsq", "icp"] = "lsq"
    registration_dof: list[Literal["tx", "ty", "tz", "alpha", "beta", "gamma"]] = Field(
        default_factory=lambda: ["tx", "ty", "tz", "alpha", "beta", "gamma"],  # type: ignore[arg-type]
        min_length=1,
        description="rigid-body parameters the registration fits")
    registration_stages: Literal["base_then_all", "base"] = Field(
        "base_then_all", description="a microstructure on a base: register on the base, then on "
                                     "all data; or on the base only (the lenslets are then "
                                     "located against the base, what their relative timing "
                                     "turns stays visible)")
    template_oversample: int = Field(10, ge=1, le=50, description="ICP template density / measured")
    msa_inner: float = Field(0.95, gt=0, le=1, description="fraction of the aperture that is MSA data")
    msa_outer: float = Field(1.05, ge=1, le=3, description="beyond this fraction of the aperture: base")
    profile_sampling_lengths: int = Field(5, ge=1, le=50, description="sampling lengths for Rz")
    min_coverage: float = Field(0.95, ge=0, le=1,
                                description="warn when a measurement covers less of the region")
    min_overlap: float = Field(0.8, ge=0, le=1,
                               description="compare --measured refuses a registered overlap below "
                                           "this fraction of the smaller of the two areas")
    # phase retrieval from the rendered interferograms (render_inspect.metrology._phase)
    phase_algorithm: Literal["auto", "4step", "5step", "lsq"] = Field(
        "auto", description="PSI: 4-step, 5-step (Hariharan), least squares; auto by frame count")
    csi_refine: Literal["envelope", "phase"] = Field(
        "envelope", description="CSI height: envelope peak, or refined by the fringe phase")
    min_modulation: float = Field(0.05, ge=0, le=1,
                                  description="pixels with lower fringe contrast are not measured")

    @model_validator(mode="after")
    def _filters_nest(self) -> MetrologyConfig:
        if self.s_filter is not None and self.l_filter is not None and not self.l_filter > self.s_filter:
            raise ValueError(f"metrology.l_filter must be > metrology.s_filter ({self.s_filter} mm), "
                             f"received {self.l_filter} mm")
        return self

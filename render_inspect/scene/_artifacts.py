"""``[artifacts]``: process errors added to the ideal cut (servo, vibration, burrs, noise)."""

from __future__ import annotations

from pydantic import Field

from ..core.section import Section


class ServoConfig(Section):
    delay_s: float = Field(0.0, ge=0, le=10, description="lag between spindle angle and FTS stroke")
    bandwidth_hz: float | None = Field(None, gt=0, description="second-order servo bandwidth; None = ideal")
    damping: float = Field(0.7, gt=0, le=10)
    slow_bandwidth_hz: float | None = Field(None, gt=0, description="slow slide (S3) servo bandwidth; None = ideal")
    slow_damping: float = Field(0.7, gt=0, le=10)


class VibrationConfig(Section):
    frequency_hz: float = Field(0.0, ge=0, le=1e7)
    amplitude: float = Field(0.0, ge=0, le=0.1, description="mm")
    samples_per_period: int = Field(16, ge=4, le=1000, description="time samples per vibration period")


class BurrConfig(Section):
    height: float = Field(0.0, ge=0, le=0.1, description="mm")
    width: float = Field(0.0, ge=0, le=1.0, description="mm")
    variation: float = Field(0.3, ge=0, le=1, description="relative seeded variation")
    edge_angle_deg: float = Field(1.0, gt=0, lt=90, description="smallest slope jump that is a sharp edge")
    correlation_length: float | None = Field(None, gt=0, description="mm, of the variation; None = 4 x width")


class ArtifactsConfig(Section):
    servo: ServoConfig = Field(default_factory=ServoConfig)
    vibration: VibrationConfig = Field(default_factory=VibrationConfig)
    burrs: BurrConfig = Field(default_factory=BurrConfig)

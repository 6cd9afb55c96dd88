"""Slow tool servo (STS) turning (Li et al. 2018): the Z axis follows the design along the
inward spiral; the machined surface is the envelope of the tool nose.  A part too large
for memory is simulated tile by tile."""

from __future__ import annotations

from typing import Literal

from ._registry import register_process
from ._turning import TiledTurningProcess, TurningProcessConfig

__all__ = ["StsProcessConfig", "StsProcess"]


class StsProcessConfig(TurningProcessConfig):
    """``[process]`` of slow-tool-servo turning."""
    kind: Literal["sts"] = "sts"


class StsProcess(TiledTurningProcess):
    """Slow-tool-servo turning: the turning defaults, tiled when large."""

    config = StsProcessConfig


register_process(StsProcess())

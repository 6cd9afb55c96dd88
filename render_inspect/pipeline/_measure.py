"""Measuring interferometer frames on disk, and evaluating the result against the truth a
simulation keeps beside them."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..io import read_exr, read_frames_exr, write_exr
from ..metrology import evaluate_measurement, measure_frames

__all__ = ["measure_and_evaluate"]


def measure_and_evaluate(path, *, algorithm: str = "auto", csi_refine: str = "envelope",
                         min_modulation: float = 0.05):
    """Measure the frames of ``interferogram.exr`` (frames and settings only), then evaluate
    the measurement against its ``height_true`` channel; add ``height_measured`` (mm,
    aligned to the truth by one constant per connected region, NaN where not measured)
    and ``valid_measured`` (0/1) to the file, rewriting it atomically, with the error
    metrics in the header as ``measured`` (JSON).

    Returns
    -------
    aligned : PhaseResult
    metrics : dict
        :func:`~render_inspect.metrology.evaluate_measurement`'s metrics.
    """
    path = Path(path)
    frames, extra, _ = read_frames_exr(path)
    result = measure_frames(frames, algorithm=algorithm, csi_refine=csi_refine,
                            min_modulation=min_modulation)
    aligned, metrics = evaluate_measurement(result, extra["height_true"])
    channels, attrs = read_exr(path)
    channels["height_measured"] = aligned.height
    channels["valid_measured"] = aligned.valid.astype(np.float32)
    attrs["measured"] = json.dumps(metrics, sort_keys=True)
    attrs["height_measured_piston"] = aligned.meta["piston"]
    write_exr(path, channels, attrs)
    return aligned, metrics

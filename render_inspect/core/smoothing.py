"""The weights of SciPy's Gaussian filter, for the compiled smoothing passes that must give
its numbers to the last bit (the burr model's and the interferometer's)."""

from __future__ import annotations

import numpy as np


def gaussian_weights(sigma: float, truncate: float = 4.0) -> np.ndarray:
    """The weights SciPy's ``gaussian_filter1d`` correlates with (its own kernel, reversed
    as it reverses it), radius ``int(truncate sigma + 0.5)``."""
    from scipy.ndimage import _filters

    radius = int(truncate * float(sigma) + 0.5)
    return np.ascontiguousarray(_filters._gaussian_kernel1d(float(sigma), 0, radius)[::-1],
                                dtype=np.float64)

"""The weights of SciPy's Gaussian filter, for the compiled smoothing passes that must give
its numbers to the last bit (the burr model's and the interferometer's)."""

from __future__ import annotations

import numpy as np


def gaussian_weights(sigma: float, truncate: float = 4.0) -> np.ndarray:
    """The weights SciPy's ``gaussian_filter1d`` correlates with (its own kernel, reversed
    as it reverses it), radius ``int(truncate sigma + 0.5)``.

    The kernel is computed here with the operations of SciPy's own (``ndimage``'s
    ``_gaussian_kernel1d`` of order 0: exp(-x^2 / 2 sigma^2) at the integers -radius ..
    radius, divided by its sum), so the numbers are SciPy's bit for bit (tested against
    it) without importing ``scipy.ndimage`` (0.02 s of a command, and SciPy's linear
    algebra with it, 0.06 s more, where nothing else loads that)."""
    sigma = float(sigma)
    radius = int(truncate * sigma + 0.5)
    sigma2 = sigma * sigma
    x = np.arange(-radius, radius + 1)
    phi_x = np.exp(-0.5 / sigma2 * x ** 2)
    phi_x = phi_x / phi_x.sum()
    return np.ascontiguousarray(phi_x[::-1], dtype=np.float64)

"""Second-order Butterworth low-pass pre-filter (paper Sec. 5.1, Eqs. (58)-(60))."""

from __future__ import annotations

import math

from glider_plant.params import ParameterError

#: the paper's pre-filter (Sec. 5.1): 10 Hz cut-off, sampled at 50 Hz
DEFAULT_F_CUTOFF = 10.0
DEFAULT_F_SAMPLE = 50.0


def butterworth_coefficients(f_sample: float, f_cutoff: float) -> tuple[float, ...]:
    """Coefficients ``(a0, a1, a2, b1, b2)`` of Eq. (58) from the Sec. 5.1 formula.

    Parameters
    ----------
    f_sample : float
        Sampling frequency, Hz.
    f_cutoff : float
        Cut-off frequency, Hz; must lie in ``(0, f_sample / 2)``.

    Returns
    -------
    tuple of 5 floats
        ``H(z) = (a0 + a1 z^-1 + a2 z^-2) / (1 + b1 z^-1 + b2 z^-2)``.
    """
    if not (math.isfinite(f_sample) and f_sample > 0.0):
        raise ParameterError(f"f_sample = {f_sample!r} is invalid: expected a finite value > 0 Hz")
    if not (math.isfinite(f_cutoff) and 0.0 < f_cutoff < 0.5 * f_sample):
        raise ParameterError(
            f"f_cutoff = {f_cutoff!r} is invalid: expected a value in (0, {0.5 * f_sample:g}) Hz "
            "(below the Nyquist frequency f_sample/2)"
        )
    f_r = f_sample / f_cutoff  # Eq. (59)
    wc = math.tan(math.pi / f_r)
    k = 2.0 * math.cos(math.pi / 4.0) * wc
    c = 1.0 + k + wc * wc
    a0 = wc * wc / c
    return (a0, 2.0 * a0, a0, 2.0 * (wc * wc - 1.0) / c, (1.0 - k + wc * wc) / c)


class ButterworthFilter:
    """Recursive form of Eq. (60), one sample per call.

    The history is initialised at the first sample (steady state), so a constant input
    passes without a start-up transient.
    """

    def __init__(self, f_sample: float, f_cutoff: float) -> None:
        self.coefficients = butterworth_coefficients(f_sample, f_cutoff)
        self.history: list[float] | None = None  # [x(n-1), x(n-2), y(n-1), y(n-2)]

    def __call__(self, x: float) -> float:
        a0, a1, a2, b1, b2 = self.coefficients
        if self.history is None:
            self.history = [x, x, x, x]
        x1, x2, y1, y2 = self.history
        y = a0 * x + a1 * x1 + a2 * x2 - b1 * y1 - b2 * y2
        self.history = [x, x1, y, y1]
        return y

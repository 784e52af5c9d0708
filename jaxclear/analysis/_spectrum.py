"""Single-sided amplitude spectra of signals sampled on a uniform grid (docs/chaos.md, "Spectra").

A periodic response has a line spectrum (the crank frequency and its harmonics, plus subharmonics
after a period doubling); a chaotic one has a broadband floor between the lines.
"""

from collections.abc import Callable

import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float

from .._core._checks import is_concrete
from ._signals import signal_names, signals

UNIFORM_RTOL = 1e-6
"""Largest deviation of a time step from the mean step, relative to it, for a grid to count as
uniform: ``simulate``'s grid (``numpy.linspace`` in float64) deviates by ~1e-12 relative; a grid
from the solver's own steps deviates by tens of per cent."""


def _cosine_sum(coefficients: tuple[float, ...]) -> Callable[[int], np.ndarray]:
    """Periodic (DFT-even) cosine-sum window w[n] = Σ_k (−1)^k a_k cos(2πkn/N), n = 0..N−1."""

    def window(n: int) -> np.ndarray:
        phase = 2.0 * np.pi * np.arange(n) / n
        terms = [(-1) ** k * a * np.cos(k * phase) for k, a in enumerate(coefficients)]
        return np.sum(terms, axis=0)

    return window


WINDOWS: dict[str, Callable[[int], np.ndarray]] = {
    "rectangular": lambda n: np.ones(n),
    "hann": _cosine_sum((0.5, 0.5)),
    "hamming": _cosine_sum((0.54, 0.46)),
    "blackman": _cosine_sum((0.42, 0.5, 0.08)),
    # coefficients of scipy.signal.windows.flattop (D'Antona & Ferrero, 2006): amplitude error
    # about 0.01 dB (0.12 %) at most for a tone between two bins, main lobe ±5 bins wide
    "flattop": _cosine_sum((0.21557895, 0.41663158, 0.277263158, 0.083578947, 0.006947368)),
}
"""Window functions by name (periodic forms, as ``scipy.signal.get_window``'s default). ``hann``
(default): leakage falls off fast, a tone between two bins reads up to 15 % (1.42 dB) low;
``flattop``: amplitudes of tones between bins within about 0.12 %, poorer frequency resolution;
``rectangular``: no window, exact for tones on a bin, strong leakage otherwise."""

DETRENDS = ("constant", "linear", "none")


def _detrend_name(detrend) -> str:
    if detrend is True:
        return "constant"
    if detrend is False or detrend is None:
        return "none"
    if detrend in DETRENDS:
        return detrend
    raise ValueError(
        f"detrend must be True, False or one of {', '.join(map(repr, DETRENDS))}; got {detrend!r}."
    )


def _check_grid(t: np.ndarray) -> float:
    """Step of a concrete uniform grid, s; ValueError naming ``t`` otherwise."""
    if t.ndim != 1 or t.size < 2:
        raise ValueError(f"t must be a 1-D array of at least 2 times, got shape {t.shape}.")
    if not np.all(np.isfinite(t)):
        raise ValueError("t must be finite.")
    steps = np.diff(t)
    dt = (t[-1] - t[0]) / (t.size - 1)
    if not dt > 0:
        raise ValueError(f"t must be increasing; got t[0] = {t[0]}, t[-1] = {t[-1]}.")
    worst = float(np.max(np.abs(steps - dt)) / dt)
    if worst > UNIFORM_RTOL:
        raise ValueError(
            f"t must be a uniform grid (steps within {UNIFORM_RTOL:g} of their mean, relative); its steps "
            f"range from {steps.min():.6g} to {steps.max():.6g} s. Resample first, e.g. simulate with "
            "num_points=... or ts=numpy.linspace(...), or numpy.interp onto a uniform grid."
        )
    return float(dt)


def amplitude_spectrum(
    t: ArrayLike,
    x: ArrayLike,
    *,
    window: str = "hann",
    detrend: "bool | str" = True,
) -> tuple[Float[Array, " F"], Float[Array, "*batch F"]]:
    """Single-sided amplitude spectrum of a signal on a uniform time grid.

    With N samples at step Δt, window w[n] and X_k = Σ_n w[n] x[n] e^{−2πikn/N}, the amplitude at
    f_k = k/(N Δt) is

        A_k = 2 |X_k| / Σ_n w[n]   for 0 < k < N/2,     A_0 = |X_0| / Σ w,   A_{N/2} = |X_{N/2}| / Σ w,

    so that x(t) = A sin(2π f t + φ) with f on a bin gives a peak of exactly A at f (the division by
    Σ w = N × coherent gain undoes the window's attenuation). A tone between bins spreads over its
    neighbours: the peak then reads low by the window's scalloping loss (``WINDOWS``).

    Pure ``jax.numpy`` (batched over leading axes of ``x``; works under ``jax.jit``, where the
    uniformity of a traced ``t`` cannot be checked).

    Args:
        t: sample times (N,), s, uniformly spaced.
        x: samples (*batch, N), any unit.
        window: a name in ``WINDOWS`` (``"hann"``, ``"flattop"``, ``"rectangular"``, ...).
        detrend: ``True``/``"constant"`` subtract the mean before windowing (default; otherwise
            the mean leaks into the lowest bins through the window), ``"linear"`` subtract the
            least-squares line, ``False``/``"none"`` keep the signal as it is (A_0 is then its mean).

    Returns:
        ``(frequency, amplitude)``: frequencies (N//2 + 1,), Hz, from 0 to the Nyquist frequency
        1/(2Δt), and amplitudes (*batch, N//2 + 1) in the unit of ``x``.

    Raises:
        ValueError: ``t`` is not a uniform increasing 1-D grid (concrete ``t``), ``x``'s last axis
            does not match ``t``, or an unknown ``window`` or ``detrend``.
    """
    if window not in WINDOWS:
        raise ValueError(f"window {window!r} is unknown; choose one of {', '.join(WINDOWS)}.")
    how = _detrend_name(detrend)
    x = jnp.asarray(x, dtype=float)
    if not is_concrete(t):
        t = jnp.asarray(t, dtype=float)
        if t.ndim != 1 or t.shape[0] < 2:
            raise ValueError(f"t must be a 1-D array of at least 2 times, got shape {t.shape}.")
        dt = (t[-1] - t[0]) / (t.shape[0] - 1)
    else:
        t_np = np.asarray(t, dtype=float)
        dt = _check_grid(t_np)
        t = jnp.asarray(t_np)
    n = t.shape[0]
    if x.ndim < 1 or x.shape[-1] != n:
        raise ValueError(f"x must have t's length {n} on its last axis, got shape {x.shape}.")
    lead = (1,) * (x.ndim - 1)  # explicit broadcasting over the batch axes (no rank promotion)
    if how == "constant":
        x = x - jnp.mean(x, axis=-1, keepdims=True)
    elif how == "linear":
        s = jnp.reshape((t - jnp.mean(t)) / (t[-1] - t[0]), lead + (n,))
        slope = jnp.sum(x * s, axis=-1, keepdims=True) / jnp.sum(s * s)
        x = x - jnp.mean(x, axis=-1, keepdims=True) - slope * s
    w = jnp.asarray(WINDOWS[window](n))
    spectrum = jnp.abs(jnp.fft.rfft(x * jnp.reshape(w, lead + (n,)), axis=-1)) / jnp.sum(w)
    # one-sided: every bin but DC (and Nyquist for even N) also holds its negative frequency
    factor = np.full(n // 2 + 1, 2.0)
    factor[0] = 1.0
    if n % 2 == 0:
        factor[-1] = 1.0
    frequency = jnp.arange(n // 2 + 1) / (n * dt)
    return frequency, spectrum * jnp.reshape(jnp.asarray(factor), lead + (n // 2 + 1,))


def signal_spectrum(
    traj,
    name: str,
    *,
    start: float | None = None,
    window: str = "hann",
    detrend: "bool | str" = True,
) -> tuple[Float[Array, " F"], Float[Array, "*batch F"]]:
    """Amplitude spectrum of one named signal of a trajectory (``amplitude_spectrum``).

    Args:
        traj: a ``Trajectory`` saved on a uniform grid (``simulate``'s default ``num_points``
            grid); a batched one gives one spectrum per member.
        name: a signal name (``jaxclear.signal_names``), e.g. ``"slider_a"`` or ``"crank_torque"``.
        start: leave out the samples before this time, s (start-up revolutions). For clean lines
            make the kept window a whole number of crank revolutions.
        window, detrend: as in ``amplitude_spectrum``.

    Returns:
        ``(frequency Hz, amplitude in the signal's unit)``.

    Raises:
        ValueError: an unknown ``name``, a non-uniform grid, fewer than 2 samples after ``start``.
    """
    names = signal_names(traj.mechanism)
    if name not in names:
        raise ValueError(f"name {name!r} is not a signal of this mechanism; choose one of {names}.")
    t = np.asarray(traj.t)
    t = t.reshape(-1, t.shape[-1])[0]  # a batch shares its grid
    x = signals(traj, [name])[name]
    if start is not None:
        keep = np.flatnonzero(t >= start)
        if keep.size < 2:
            raise ValueError(
                f"start = {start} s leaves {keep.size} samples (the grid ends at {t[-1]} s)."
            )
        t, x = t[keep], x[..., keep]
    return amplitude_spectrum(t, x, window=window, detrend=detrend)

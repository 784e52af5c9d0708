"""Amplitude spectra: known tones, windows, detrending, grid checks (jaxclear.analysis._spectrum)."""

import numpy as np
import pytest

import jaxclear
from jaxclear.analysis import WINDOWS, amplitude_spectrum, signal_spectrum

ON_BIN_RTOL = 1e-10
"""A tone on a bin reads its amplitude exactly (the coherent-gain correction is exact there): only
rounding of the FFT sums remains."""

FLATTOP_RTOL = 2e-3
"""Flat-top window: a tone anywhere between two bins reads within about 0.01 dB (0.12 %) of its
amplitude (scipy.signal.windows.flattop; measured 0.11 % half-way between bins)."""

HANN_SCALLOP = 1 - 0.8488
"""Hann window: the worst reading of a tone half-way between bins is 2/π·... = 0.8488 of its
amplitude (−1.42 dB scalloping loss, Harris 1978, Table 1)."""

LEAKAGE_FLOOR = 1e-3
"""Hann window, tones on bins: other bins hold at most rounding, nothing near the 1e-3 level."""


HARMONIC_RTOL = 1e-5
"""Whole revolutions put the harmonics on bins (read exactly); what remains is the solver's error
(Tsit5, rtol 1e-6)."""


def _grid(n=1000, dt=1e-3):
    return np.arange(n) * dt


def test_sinusoid_on_a_bin_reads_its_amplitude_and_frequency():
    t = _grid()  # 1 s at 1 kHz: bins every 1 Hz
    amplitude, frequency = 2.5, 50.0
    x = 0.7 + amplitude * np.sin(2 * np.pi * frequency * t + 0.3)
    for window in WINDOWS:
        f, a = amplitude_spectrum(t, x, window=window)
        f, a = np.asarray(f), np.asarray(a)
        assert f.shape == a.shape == (501,)
        assert f[-1] == pytest.approx(500.0)  # Nyquist
        k = int(np.argmax(a))
        assert f[k] == pytest.approx(frequency)
        assert a[k] == pytest.approx(amplitude, rel=ON_BIN_RTOL), window
        assert a[0] == pytest.approx(0.0, abs=1e-9)  # mean removed


def test_two_tones():
    t = _grid()
    x = 3.0 * np.cos(2 * np.pi * 40 * t) + 0.5 * np.sin(2 * np.pi * 120 * t)
    f, a = (np.asarray(v) for v in amplitude_spectrum(t, x))
    peaks = np.flatnonzero((a[1:-1] > a[:-2]) & (a[1:-1] > a[2:]) & (a[1:-1] > 0.1)) + 1
    np.testing.assert_array_equal(f[peaks], [40.0, 120.0])
    assert a[40] == pytest.approx(3.0, rel=ON_BIN_RTOL)
    assert a[120] == pytest.approx(0.5, rel=ON_BIN_RTOL)
    # Hann: a tone on a bin spreads into its two neighbours (half its amplitude each), no further
    far = np.ones(a.shape, bool)
    far[[39, 40, 41, 119, 120, 121]] = False
    assert np.max(a[far]) < LEAKAGE_FLOOR


def test_tone_between_bins():
    t = _grid()
    x = 1.5 * np.sin(2 * np.pi * 50.5 * t)
    _, a = amplitude_spectrum(t, x, window="flattop")
    assert float(np.max(a)) == pytest.approx(1.5, rel=FLATTOP_RTOL)
    _, a = amplitude_spectrum(t, x, window="hann")
    assert 1.5 * (1 - HANN_SCALLOP) * 0.999 < float(np.max(a)) < 1.5


def test_detrend_and_batches():
    t = _grid(n=999)  # odd length: no Nyquist bin
    x = 4.0 + 2.0 * t + np.sin(2 * np.pi * 100 * t)
    f, a = amplitude_spectrum(t, x, detrend=False, window="rectangular")
    assert f.shape == (500,)
    assert float(a[0]) == pytest.approx(np.mean(x))  # DC amplitude is the mean
    _, a = amplitude_spectrum(t, x, detrend="linear")
    assert float(np.max(np.asarray(a)[:5])) < 1e-2  # ramp gone: no low-frequency leakage
    batch = np.stack([x, 2 * x])
    _, ab = amplitude_spectrum(t, batch, detrend="linear")
    assert ab.shape == (2, 500)
    np.testing.assert_allclose(ab[1], 2 * ab[0], rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(ab[0], a, rtol=1e-12, atol=1e-14)


def test_bad_grids_and_options():
    t = _grid(n=100)
    x = np.sin(t)
    with pytest.raises(ValueError, match="uniform"):
        amplitude_spectrum(t * (1 + 0.01 * t), x)
    with pytest.raises(ValueError, match="increasing"):
        amplitude_spectrum(t[::-1], x)
    with pytest.raises(ValueError, match="at least 2"):
        amplitude_spectrum(t[:1], x[:1])
    with pytest.raises(ValueError, match="last axis"):
        amplitude_spectrum(t, x[:-1])
    with pytest.raises(ValueError, match="window"):
        amplitude_spectrum(t, x, window="kaiser")
    with pytest.raises(ValueError, match="detrend"):
        amplitude_spectrum(t, x, detrend="quadratic")


def test_signal_spectrum_of_the_ideal_slider_crank():
    """The ideal slider-crank's slider acceleration is periodic at the crank frequency: over whole
    revolutions its spectrum holds only the crank frequency and its harmonics; the second harmonic
    has amplitude ≈ r ω² (r/l) (the classic piston-acceleration series, r/l = 5/12)."""
    rpm = 5000.0
    mech = jaxclear.mechanisms.slider_crank(rpm=rpm, clearance_joints="")
    period = 60.0 / rpm
    ts = np.arange(800) * period / 200  # the last revolution ends one step before 4 periods
    traj = jaxclear.simulate(mech, ts[-1], ts=ts, extremes=False)
    f, a = signal_spectrum(traj, "slider_a", start=period)  # 3 whole revolutions: 600 points
    f, a = np.asarray(f), np.asarray(a)
    crank = rpm / 60.0
    omega = 2 * np.pi * crank
    r, rod = 0.05, 0.12
    first = a[np.argmin(np.abs(f - crank))]
    second = a[np.argmin(np.abs(f - 2 * crank))]
    # x = r cos θ + √(l² − r² sin² θ) holds cos θ and even harmonics only: the first harmonic of
    # ẍ is exactly r ω²; the second r ω² (r/l + (r/l)³/4 + ...), 4 % above r ω² r/l here
    assert first == pytest.approx(r * omega**2, rel=HARMONIC_RTOL)
    assert second == pytest.approx(r * omega**2 * r / rod, rel=0.1)
    with pytest.raises(ValueError, match="not a signal"):
        signal_spectrum(traj, "piston_a")
    with pytest.raises(ValueError, match="leaves"):
        signal_spectrum(traj, "slider_a", start=1.0)

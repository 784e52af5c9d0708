"""Measured responses for a fit: read from a CSV file or given as arrays, checked, with noise levels.

A measurement file has a header row of column names, ``t`` (s) and measured signals named as the
columns of ``jaxclear run``'s results.csv (``jaxclear.signal_names(mechanism)``: ``slider_a``,
``B_normal_force``, ...), then one row of numbers per instant, comma-separated, UTF-8 (a byte-order
mark is accepted). A results.csv written by ``jaxclear run`` is such a file: select the columns
to fit with ``columns=``. Every problem raises ``DataError`` with a one-line message naming the
file, the line and column, and the fix.

Each signal gets a noise level σ (its units), the scale of its residuals in a fit: given, or
estimated from the data (``estimate_noise``), and floored at ``NOISE_FLOOR`` times the signal's
RMS so that noise-free (synthetic) data do not divide by zero.
"""

import csv
import io
import math
from collections.abc import Collection, Mapping, Sequence
from pathlib import Path
from typing import NoReturn

import equinox as eqx
import numpy as np
from jaxtyping import Float

from .._core._errors import DataError

TIME = "t"
"""Name of the time column, s."""

NOISE_FLOOR = 1e-6
"""Smallest noise level used, relative to the signal's RMS √(mean y²): a σ below it (noise-free
synthetic data, or the 12 significant digits of results.csv, ~1e-12 relative) is raised to it and
marked in ``Measurements.noise_floored``. It caps a residual's weight at 1e6 / RMS."""

OUTLIER_CUTOFF = 4.0
"""Third differences farther than this many robust standard deviations from their median are
outliers (impacts, spikes) and left out of the noise estimate with their neighbours. 4: on white
Gaussian noise it leaves out 6e-5 of the clean differences (the estimate is then 0.4 % low, measured
on 2000 series of 600 points); 3.5 gives −0.7 %, 5 lets moderate spikes (5–20 σ) raise it by
1.4 %."""

MIN_POINTS_FOR_NOISE = 13
"""Fewest samples from which a noise level is estimated (10 third differences); give σ with
fewer."""

MAD_TO_SIGMA = 1.482602218505602
"""1 / Φ⁻¹(3/4): median absolute deviation to standard deviation for a normal distribution."""

THIRD_DIFFERENCE_GAIN = 20.0
"""Var(Δ³e) / σ² for white noise e: 1² + 3² + 3² + 1² (coefficients of Δ³)."""


def estimate_noise(values: Float[np.ndarray, " N"]) -> float:
    """Standard deviation σ of white noise on a sampled signal that is smooth except at isolated
    impacts, from its third differences.

    With y_k = s_k + e_k (e white, variance σ²) and s smooth on the sampling scale (its third
    difference Δ³s_k = s_{k+3} − 3 s_{k+2} + 3 s_{k+1} − s_k ≈ h³ s''' negligible against σ), the
    third differences d_k = Δ³y_k ≈ Δ³e_k have variance 20 σ² (1 + 9 + 9 + 1). Two stages:

    1. robust scale: s_d = 1.4826 · median |d_k − median d| (``MAD_TO_SIGMA``);
    2. outliers: every d_k with |d_k − median d| > 4 s_d (``OUTLIER_CUTOFF``) is an impact or
       spike; a sample j enters d_{j−3} … d_j, so the six neighbours of each outlier go with it;
       then σ² = mean(d_k²) / 20 over the d_k left.

    Stage 2 uses every remaining difference (the MAD alone discards most of the information): on
    600 samples of a sinusoid plus Gaussian noise (2000 draws) σ came out with a spread of 4.4 %
    and a bias of −0.4 %, and with 15 spikes of 5–100 σ +0.1 % and 5.2 %; the MAD estimate of
    stage 1 alone had a spread of 6.1 %, and +13 % bias with the 15 spikes.

    Limits: it counts as noise whatever part of the third differences is neither white noise
    nor an isolated outlier. A signal the sampling does not resolve (Δ³s not small against σ:
    contact oscillations in an acceleration, a dense train of impacts) gives too large a σ;
    noise correlated between samples (filtered data) gives a wrong one; values rounded to a few
    digits give the rounding noise (quantisation step / √12). Measured on the noise-free slider
    acceleration of the benchmark slider–crank at 5000 rpm sampled every 10 µs (second
    revolution, 1201 samples; ``simulate`` defaults): ideal joints 1.2e-3 m/s² (1e-7 of the
    signal's standard deviation of 1.06e4 m/s²); clearance 0.5 mm at B, hybrid contact and
    LuGre friction, 1.2 m/s² (1.1e-4 of 1.12e4); L-N contact and modified Coulomb μ = 0.01,
    3.1 m/s² (2.4e-4 of 1.30e4); the impacts themselves are left out as outliers (the RMS of all
    third differences would give 14 and 17 m/s²). With added white noise of 1e-3 of the standard
    deviation the estimate was 6 % and 18 % high for the two clearance cases, with 1e-2 within
    1 %. Slider position and velocity: below 1e-5 of their spread.

    Args:
        values: the samples (N,), N >= ``MIN_POINTS_FOR_NOISE``, uniformly or nearly uniformly
            spaced in time (the estimate ignores the spacing).

    Returns:
        σ in the units of ``values`` (0 for a signal that is a quadratic polynomial of the index).

    Raises:
        ValueError: fewer than ``MIN_POINTS_FOR_NOISE`` samples.
    """
    y = np.asarray(values, dtype=np.float64)
    if y.ndim != 1 or y.size < MIN_POINTS_FOR_NOISE:
        raise ValueError(
            f"estimate_noise needs at least {MIN_POINTS_FOR_NOISE} samples in a 1-D array, got "
            f"shape {y.shape}; give the noise level instead."
        )
    d = np.diff(y, 3)
    deviation = np.abs(d - np.median(d))
    scale = MAD_TO_SIGMA * np.median(deviation)
    outlier = deviation > OUTLIER_CUTOFF * scale
    if scale > 0 and np.any(outlier):
        # Dilate by 3 both ways: the differences that share a sample with an outlier.
        near = np.convolve(outlier.astype(float), np.ones(7), mode="same") > 0
        d = d[~near]
    if d.size == 0:
        return 0.0
    return float(np.sqrt(np.mean(d**2) / THIRD_DIFFERENCE_GAIN))


class Measurements(eqx.Module):
    """A measured response: sampled signals at increasing times, each with a noise level.

    An ``eqx.Module`` (a pytree) so that a fit can pass it whole as an argument of a function
    under ``eqx.filter_jit``/``eqx.filter_grad`` instead of closing over its arrays: ``t`` and
    the signals become traced inputs (a new data set of the same size does not recompile), the
    noise levels, flags and source stay Python values (static). A frozen dataclass could not be
    passed so. (JAX rebuilds dicts with their keys sorted; file order holds outside
    transformations.)

    Build it with ``from_csv`` or ``from_arrays``, which check the data; the constructor checks
    nothing.

    Attributes:
        t: measurement times (N,), s, strictly increasing, float64.
        signals: ``{name: values (N,)}`` float64, the measured columns in file order, SI units.
        noise: ``{name: σ}``, the noise standard deviation used for each signal, same units.
        noise_estimated: ``{name: bool}``, True where σ was estimated from the data
            (``estimate_noise``), False where it was given.
        noise_floored: ``{name: bool}``, True where σ was raised to ``NOISE_FLOOR`` · RMS.
        source: the file path, or ``"array"``.
    """

    t: Float[np.ndarray, " N"]
    signals: dict[str, Float[np.ndarray, " N"]]
    noise: dict[str, float]
    noise_estimated: dict[str, bool]
    noise_floored: dict[str, bool]
    source: str = eqx.field(static=True, default="array")

    @property
    def names(self) -> tuple[str, ...]:
        """The signal names, in file order."""
        return tuple(self.signals)

    @property
    def num_points(self) -> int:
        """Number of instants N."""
        return int(np.shape(self.t)[0])

    @property
    def num_values(self) -> int:
        """Number of measured values (instants × signals): the residuals of a fit."""
        return self.num_points * len(self.signals)

    # --- constructors -------------------------------------------------------------------------
    @classmethod
    def from_csv(
        cls,
        path: str | Path,
        *,
        known: Collection[str] | None = None,
        columns: Sequence[str] | None = None,
        noise: Mapping[str, float | int] | None = None,
    ) -> "Measurements":
        """Read measurements from a CSV file: header ``t,<signal>,...``, one row per instant.

        Blank lines are skipped; cells may have spaces around them; numbers as Python's
        ``float`` reads them (``0.5``, ``-1.2e-3``).

        Args:
            path: the file.
            known: valid signal names (``jaxclear.signal_names(mechanism)``); default: any name.
            columns: the signal columns to use (file order is kept); default every column but
                ``t``. Other columns are not read beyond the header and row lengths.
            noise: ``{name: σ}`` for some of the used columns, in their units; the others are
                estimated (``estimate_noise``).

        Returns:
            The ``Measurements``, ``source`` the path as given.

        Raises:
            DataError: the file cannot be read or is not UTF-8, malformed CSV (ragged rows,
                non-numeric cells, empty, header only), no ``t`` column, repeated column names,
                unknown or missing selected columns, no signal column, NaN or inf, times not
                strictly increasing, fewer than 2 rows, a bad noise level.
        """
        source = str(path)
        text = _read_text(source)
        header, rows, lines = _parse_csv(source, text)
        used = _select_columns(source, header, known, columns)
        if not rows:
            _fail(
                source,
                f"no data rows after the header (line {lines[0] if lines else 1})",
                "add one row of values per instant",
            )
        where = {name: header.index(name) for name in (TIME, *used)}
        width = len(header)
        table = np.empty((len(rows), len(where)))
        for r, (row, line) in enumerate(zip(rows, lines[1:], strict=True)):
            if len(row) != width:
                _fail(
                    source,
                    f"line {line} has {len(row)} cells but the header has {width} columns",
                    "give every row one value per column",
                )
            for c, (name, k) in enumerate(where.items()):
                cell = row[k].strip()
                try:
                    table[r, c] = float(cell)
                except ValueError:
                    shown = repr(cell) if cell else "an empty cell"
                    _fail(
                        source,
                        f"line {line}, column {name!r}: {shown} is not a number",
                        "write plain decimal numbers (e.g. 0.125 or -1.5e-3) in every cell",
                    )
        signals = {name: table[:, c] for c, name in enumerate(where) if name != TIME}
        return cls._checked(
            source, table[:, 0], signals, noise, row_name=lambda r: f"line {lines[r + 1]}"
        )

    @classmethod
    def from_arrays(
        cls,
        t,
        signals: Mapping[str, object],
        *,
        noise: Mapping[str, float | int] | None = None,
        known: Collection[str] | None = None,
        source: str = "array",
    ) -> "Measurements":
        """Measurements from arrays (synthetic data, data read by other means).

        Args:
            t: times (N,), s, strictly increasing.
            signals: ``{name: values (N,)}``, SI units.
            noise: ``{name: σ}`` for some signals; the others are estimated (``estimate_noise``).
            known: valid signal names (``jaxclear.signal_names(mechanism)``); default: any name.
            source: a label for messages and ``Measurements.source``.

        Raises:
            DataError: as ``from_csv`` for the values (shapes, names, non-finite values, times,
                noise levels).
        """
        times = np.array(t, dtype=np.float64)
        if times.ndim != 1:
            _fail(source, f"t has shape {times.shape}", "give the times as a 1-D array")
        names = list(signals)
        if TIME in names:
            _fail(source, "'t' is given as a signal", "pass the times as t only")
        _select_columns(source, [TIME, *names], known, None)
        values = {}
        for name in names:
            v = np.array(signals[name], dtype=np.float64)
            if v.shape != times.shape:
                _fail(
                    source,
                    f"signal {name!r} has shape {v.shape} but t has shape {times.shape}",
                    "give one value per instant",
                )
            values[name] = v
        return cls._checked(source, times, values, noise, row_name=lambda r: f"index {r}")

    @classmethod
    def _checked(cls, source, t, signals, noise, row_name) -> "Measurements":
        """Values checks shared by the constructors, then the noise levels."""
        if t.shape[0] < 2:
            _fail(
                source,
                f"{t.shape[0]} data row{'s' if t.shape[0] != 1 else ''}",
                "a fit needs at least 2 instants (and more values than fitted parameters)",
            )
        for name, values in {TIME: t, **signals}.items():
            bad = np.flatnonzero(~np.isfinite(values))
            if bad.size:
                r = int(bad[0])
                _fail(
                    source,
                    f"column {name!r}, {row_name(r)}: value {float(values[r])} is not finite"
                    + (f" ({bad.size} such rows)" if bad.size > 1 else ""),
                    "remove the row or fill in the value",
                )
        step = np.diff(t)
        bad = np.flatnonzero(~(step > 0))
        if bad.size:
            r = int(bad[0])
            what = "repeats" if t[r + 1] == t[r] else "goes back from"
            _fail(
                source,
                f"time not strictly increasing: {row_name(r + 1)} has t = {float(t[r + 1])!r} s, "
                f"which {what} t = {float(t[r])!r} s on {row_name(r)}",
                "sort the rows by t and remove repeated instants",
            )
        given = dict(noise or {})
        for name in given:
            if name not in signals:
                _fail(
                    source,
                    f"a noise level is given for {name!r}, which is not a used signal "
                    f"(signals: {', '.join(signals)})",
                    "give noise levels only for the signals used",
                )
        sigma, estimated, floored = {}, {}, {}
        for name, values in signals.items():
            if name in given:
                try:
                    s = float(given[name])
                except (TypeError, ValueError):
                    s = math.nan
                if not (math.isfinite(s) and s >= 0):
                    _fail(
                        source,
                        f"noise level of {name!r} is {given[name]!r}",
                        "give a finite σ >= 0 in the signal's units",
                    )
            else:
                if values.size < MIN_POINTS_FOR_NOISE:
                    _fail(
                        source,
                        f"column {name!r}: {values.size} rows are too few to estimate its noise "
                        f"(at least {MIN_POINTS_FOR_NOISE})",
                        f"give its noise level (noise={{{name!r}: sigma}})",
                    )
                s = estimate_noise(values)
            floor = NOISE_FLOOR * float(np.sqrt(np.mean(values**2)))
            if floor == 0.0 and s == 0.0:
                _fail(
                    source,
                    f"column {name!r} is zero at every instant and its noise level is 0, so its "
                    "residuals have no scale",
                    f"give its noise level (noise={{{name!r}: sigma}}) or leave the column out",
                )
            sigma[name] = max(s, floor)
            estimated[name] = name not in given
            floored[name] = s < floor
        return cls(
            t=t,
            signals=signals,
            noise=sigma,
            noise_estimated=estimated,
            noise_floored=floored,
            source=source,
        )

    # --- checks that need the model -----------------------------------------------------------
    def check_span(self, t0: float, t1: float) -> None:
        """Raise ``DataError`` unless every measured time lies in the simulated span [t0, t1] (s).

        A round-off of 1e-9 of the span's magnitude is allowed at either end.
        """
        t = np.asarray(self.t)
        slack = 1e-9 * max(abs(float(t0)), abs(float(t1)), 1e-300)
        if t[0] < t0 - slack or t[-1] > t1 + slack:
            outside = t[(t < t0 - slack) | (t > t1 + slack)]
            _fail(
                self.source,
                f"measured times {float(t[0])!r} to {float(t[-1])!r} s reach outside the simulated "
                f"span [{float(t0)!r}, {float(t1)!r}] s ({outside.size} instants, the first at "
                f"t = {float(outside[0])!r} s)",
                "simulate over the measured span, or drop the instants outside it",
            )

    def check_enough(self, num_parameters: int) -> None:
        """Raise ``DataError`` if there are fewer measured values than fitted parameters."""
        if self.num_values < num_parameters:
            _fail(
                self.source,
                f"{self.num_values} measured values ({self.num_points} instants × "
                f"{len(self.signals)} signals) for {num_parameters} fitted parameters",
                "measure more instants or signals, or fit fewer parameters",
            )


# --- reading -----------------------------------------------------------------------------------
def _fail(source: str, problem: str, fix: str) -> NoReturn:
    raise DataError(f"{source}: {problem}; {fix}.")


def _read_text(source: str) -> str:
    """The file's text: UTF-8, strict, a leading byte-order mark dropped."""
    try:
        data = Path(source).read_bytes()
    except OSError as error:
        reason = error.strerror or type(error).__name__
        _fail(source, f"cannot read the data file ({reason})", "check the path and permissions")
    bom = b"\xef\xbb\xbf"
    skip = len(bom) if data.startswith(bom) else 0
    try:
        return data[skip:].decode("utf-8")
    except UnicodeDecodeError as error:
        offset = skip + error.start
        line = data.count(b"\n", 0, offset) + 1
        _fail(
            source,
            f"byte {offset} (line {line}) is not UTF-8 (0x{data[offset]:02x})",
            "save the file as UTF-8 (plain ASCII names and numbers)",
        )


def _parse_csv(source: str, text: str) -> tuple[list[str], list[list[str]], list[int]]:
    """Header names (stripped), the data rows and the line numbers of the header and each row."""
    reader = csv.reader(io.StringIO(text, newline=""), strict=True, skipinitialspace=True)
    records, lines = [], []
    try:
        for row in reader:
            if row and any(cell.strip() for cell in row):
                records.append(row)
                lines.append(reader.line_num)
    except csv.Error as error:
        _fail(
            source,
            f"line {max(reader.line_num, 1)} is not valid CSV ({error})",
            "close or remove the quote character '\"' that opens a quoted cell there",
        )
    if not records:
        _fail(source, "the file is empty", "write a header row (t and signal names), then the data")
    header = [name.strip() for name in records[0]]
    for k, name in enumerate(header):
        if not name:
            _fail(source, f"column {k + 1} of the header (line {lines[0]}) has no name", "name it")
    seen = {}
    for k, name in enumerate(header):
        if name in seen:
            _fail(
                source,
                f"column name {name!r} appears twice (columns {seen[name] + 1} and {k + 1})",
                "give each column a unique name",
            )
        seen[name] = k
    if TIME not in header:
        hint = "name the time column 't' (seconds)"
        if len(header) == 1 and any(sep in header[0] for sep in ";\t"):
            hint = "separate the columns with commas and name the time column 't'"
        elif header[0].startswith("#"):
            hint = "remove the '#' at the start of the header line"
        _fail(source, f"no {TIME!r} column (columns: {', '.join(header)})", hint)
    return header, records[1:], lines


def _select_columns(
    source: str,
    header: Sequence[str],
    known: Collection[str] | None,
    columns: Sequence[str] | None,
) -> list[str]:
    """The signal columns to use, in file order; unknown or missing names raise ``DataError``."""
    present = [name for name in header if name != TIME]
    valid = ", ".join(n for n in known if n != TIME) if known is not None else ""
    if columns is not None:
        if isinstance(columns, str):
            raise TypeError(f"columns must be a sequence of names; write [{columns!r}].")
        for name in columns:
            if name != TIME and name not in present:
                _fail(
                    source,
                    f"selected column {name!r} is not in the file (columns: {', '.join(present)})",
                    "select columns the file has",
                )
        wanted = set(columns)
        present = [name for name in present if name in wanted]
    if known is not None:
        for name in present:
            if name not in known:
                _fail(
                    source,
                    f"column {name!r} is not a signal of the mechanism (valid names: {valid})",
                    "rename it to one of these, or select the columns to fit (columns=...)",
                )
    if not present:
        _fail(
            source,
            f"no signal column besides {TIME!r}"
            + (f" (valid names: {valid})" if known is not None else ""),
            "add at least one measured column",
        )
    return present

"""Vehicle motion recordings: what an IMU at the occupant's head measured, and its CSV file.

A recording holds, at times t (s), the angular velocity omega (rad/s) and the specific force
f (m/s^2) in head-frame axes: x forward, y left, z up (`mca_drake.conventions`). Specific force is
what an accelerometer reads: level and unaccelerated, f = (0, 0, +9.81).

File format (CSV, UTF-8):

    # mca-drake recording v1            <- optional comment lines, `# key: value` metadata
    # vehicle: light
    t [s],omega_x [rad/s],omega_y [rad/s],omega_z [rad/s],f_x [m/s^2],f_y [m/s^2],f_z [m/s^2]
    0.00,0.0,0.0,0.0,0.0,0.0,9.81
    ...

Columns may come in any order; units are SI. Optional columns named for the controls and
the vehicle's state (`mca_drake.references.vehicle_signals.SIGNALS`: aileron, throttle,
steering, speed, on_ground, ...) are kept as the recording's `signals`; other extra columns
are ignored. The loader
validates everything and resamples to a uniform grid (100 Hz by default); every error names
the file, the line and the column, and says how to fix it. What it checks:

- text: UTF-8 (a byte-order mark is fine), '.' for decimals (a decimal comma adds cells);
- time base: increasing, at least `MIN_RATE_HZ` (a time column in ms reads as 0.1 Hz), no
  gap longer than `MAX_GAP_S` (it would be interpolated into motion that never happened);
  absolute time stamps (Unix epoch) are shifted to start at 0, the start kept in metadata;
- units and axes (`check_units`): specific force in m/s^2 with gravity, z up (a mostly
  level vehicle: median f_z near +9.81, unless the header says `# level: false`), every
  value below `MAX_SPECIFIC_FORCE` (20 g) but for isolated glitches (a touchdown's
  ground contact: kept for the input plausibility guard), angular velocity in rad/s (a
  deg/s file is caught by its peak above 8 rad/s). A header may name units in brackets,
  `omega_x [deg/s]`, `f_z [g]`, `t [ms]`: they are converted to SI. A file whose angular
  velocity peaks where both readings are plausible (below 0.14, or from 2 to 8) must name
  its unit; this module always writes the units.
"""

from __future__ import annotations

import csv
import dataclasses
import io
import os
import re
from pathlib import Path

import numpy as np

from mca_drake.atomic_io import atomic_write_text
from mca_drake.conventions import GRAVITY
from mca_drake.references.vehicle_signals import SIGNALS, check_signal, signal_factor

COLUMNS = ("t", "omega_x", "omega_y", "omega_z", "f_x", "f_y", "f_z")
DEFAULT_RATE_HZ = 100.0
FORMAT_TAG = "mca-drake recording v1"
# Slowest sample rate, Hz: motion cues reach a few Hz, so slower files cannot hold them (and
# a time column in ms reads as 0.1 Hz).
MIN_RATE_HZ = 10.0
# Longest gap between samples, s: resampling would fill a longer one with invented motion.
MAX_GAP_S = 0.5
# Relative tolerance of the rate check: a 10 Hz file's steps read 0.1000000001 s in floats.
RATE_TOLERANCE = 1e-6
# Shortest recording, s: 20 control periods. A file of a few samples (two, say) would be
# cued and scored, and the correlation of a handful of samples is noise, not a figure.
MIN_DURATION_S = 0.2
# Anti-alias low-pass before resampling a faster recording: a zero-phase Butterworth of this
# order (twice that, run forward and back) with its cut-off at this share of the new rate
# (40 Hz for 100 Hz, below the new Nyquist frequency, above any motion cue). Without it a
# 99 Hz vibration in a 1 kHz file would come out as a 1 Hz surge.
ANTI_ALIAS_ORDER = 4
ANTI_ALIAS_CUTOFF_SHARE = 0.4
# Largest plausible specific force, m/s^2 (20 g: beyond any crewed vehicle).
MAX_SPECIFIC_FORCE = 20 * GRAVITY
# Samples beyond MAX_SPECIFIC_FORCE that a recording may hold as isolated glitches (a
# touchdown's ground contact, a physics hiccup): runs of at most this many samples...
GLITCH_MAX_SAMPLES = 3
# ...together at most this share of the samples, and none beyond this (100 g), m/s^2.
GLITCH_MAX_SHARE = 0.001
GLITCH_MAX_FORCE = 100 * GRAVITY
# Header values of `level` that say the vehicle is not mostly level (a parabolic or
# ballistic flight): the gravity check of `check_units` is skipped.
NOT_LEVEL = ("false", "no", "0")
# Unit plausibility thresholds (see `check_units`).
_MAX_PLAUSIBLE_RATE = 8.0  # rad/s; beyond aerobatic roll rates, typical of a file in deg/s
_G_FILE_RANGE = (0.5, 2.0)  # median |f| in this range, with f_z about +1: the file is in g
_SI_F_RANGE = (4.0, 25.0)  # median |f| of any real vehicle, in m/s^2
_SI_FZ_RANGE = (0.5 * GRAVITY, 1.5 * GRAVITY)  # median f_z of a vehicle that is mostly level


class RecordingError(ValueError):
    """A recording file or array that cannot be used; the message says where and why."""


@dataclasses.dataclass
class Recording:
    """An IMU recording at the head, head-frame axes, SI units.

    Attributes:
        t: sample times, s, shape (T,), strictly increasing.
        omega: angular velocity, rad/s, shape (T, 3).
        f: specific force, m/s^2, shape (T, 3) (level flight: (0, 0, 9.81)).
        metadata: free-form string key/values (vehicle, seed, source, ...).
        signals: optional controls and vehicle state on the same times, SI, each shape (T,)
            (`vehicle_signals.SIGNALS`: {"throttle": ..., "speed": ...}; empty: none).
    """

    t: np.ndarray
    omega: np.ndarray
    f: np.ndarray
    metadata: dict[str, str] = dataclasses.field(default_factory=dict)
    signals: dict[str, np.ndarray] = dataclasses.field(default_factory=dict)

    def __post_init__(self) -> None:
        self.t = np.asarray(self.t, dtype=float)
        self.omega = np.asarray(self.omega, dtype=float)
        self.f = np.asarray(self.f, dtype=float)
        n = self.t.shape[0] if self.t.ndim == 1 else -1
        if n < 2 or self.omega.shape != (n, 3) or self.f.shape != (n, 3):
            raise RecordingError(
                f"recording needs t (T,), omega (T, 3), f (T, 3) with T >= 2; got "
                f"{self.t.shape}, {self.omega.shape}, {self.f.shape}"
            )
        for name in ("t", "omega", "f"):
            if not np.all(np.isfinite(getattr(self, name))):
                raise RecordingError(f"recording {name} has non-finite values")
        if np.any(np.diff(self.t) <= 0):
            k = int(np.argmax(np.diff(self.t) <= 0))
            raise RecordingError(f"recording times must increase; t[{k + 1}] <= t[{k}]")
        self.signals = {name: np.asarray(v, dtype=float) for name, v in self.signals.items()}
        for name, values in self.signals.items():
            if name not in SIGNALS:
                raise RecordingError(f"unknown signal '{name}'; known: {', '.join(SIGNALS)}")
            if values.shape != (n,) or not np.all(np.isfinite(values)):
                raise RecordingError(
                    f"recording signal {name} must be {n} finite values; got {values.shape}"
                )
            why = check_signal(name, values)
            if why:
                raise RecordingError(f"column {why}")

    @property
    def duration_s(self) -> float:
        """Time from the first to the last sample [s]."""
        return float(self.t[-1] - self.t[0])

    @property
    def rate_hz(self) -> float:
        """Mean sample rate, Hz."""
        return float((self.t.size - 1) / self.duration_s)

    def as_array(self) -> np.ndarray:
        """Columns t, omega_x, omega_y, omega_z, f_x, f_y, f_z as one (T, 7) array."""
        return np.column_stack([self.t, self.omega, self.f])

    def resampled(self, rate_hz: float = DEFAULT_RATE_HZ) -> Recording:
        """Linear interpolation onto t0 + k / rate_hz (k = 0, 1, ...) up to the last sample.

        A recording faster than `rate_hz` is first low-passed (zero phase, Butterworth of
        `ANTI_ALIAS_ORDER`, cut-off `ANTI_ALIAS_CUTOFF_SHARE` x rate_hz, on its own uniform
        grid), so that what lies above the new Nyquist frequency does not fold into the cue
        band; the metadata then records `anti_alias_cutoff_hz`.
        """
        if not rate_hz > 0:
            raise RecordingError(f"rate_hz must be positive; got {rate_hz}")
        h = 1.0 / rate_hz
        n = int(np.floor(self.duration_s / h + 1e-9)) + 1
        t = self.t[0] + h * np.arange(n)
        if self.t.size == n and np.allclose(self.t, t, rtol=0, atol=1e-9):
            return dataclasses.replace(self, metadata=dict(self.metadata))  # already uniform
        source = self
        if self.rate_hz > rate_hz * (1 + RATE_TOLERANCE):
            source = self._low_passed(ANTI_ALIAS_CUTOFF_SHARE * rate_hz)
        columns = [np.interp(t, source.t, c) for c in np.column_stack([source.omega, source.f]).T]
        data = np.column_stack(columns)
        # the signals interpolated as they are: a control's step is a step, not a vibration
        signals = {name: np.interp(t, self.t, v) for name, v in self.signals.items()}
        return Recording(t, data[:, :3], data[:, 3:], dict(source.metadata), signals)

    def _low_passed(self, cutoff_hz: float) -> Recording:
        """The recording on its own uniform grid (its mean rate), low-passed at `cutoff_hz`
        by a zero-phase Butterworth filter (`ANTI_ALIAS_ORDER`)."""
        # scipy: only resampling a faster file needs it, and the module stays light without
        from scipy.signal import butter, sosfiltfilt

        rate = self.rate_hz
        t = np.linspace(self.t[0], self.t[-1], self.t.size)
        data = np.column_stack([self.omega, self.f])
        uniform = np.column_stack([np.interp(t, self.t, c) for c in data.T])
        sos = butter(ANTI_ALIAS_ORDER, cutoff_hz, fs=rate, output="sos")
        # the padding sosfiltfilt needs: a short file is filtered with what it has
        pad = min(3 * (2 * len(sos) + 1), t.size - 1)
        filtered = sosfiltfilt(sos, uniform, axis=0, padlen=pad)
        metadata = {**self.metadata, "anti_alias_cutoff_hz": f"{cutoff_hz:g}"}
        return Recording(t, filtered[:, :3], filtered[:, 3:], metadata)  # signals: `resampled`

    def sliced(self, start_s: float, stop_s: float) -> Recording:
        """Samples with start_s <= t - t0 < stop_s (times keep their values)."""
        rel = self.t - self.t[0]
        keep = (rel >= start_s - 1e-9) & (rel < stop_s - 1e-9)
        signals = {name: v[keep] for name, v in self.signals.items()}
        return Recording(self.t[keep], self.omega[keep], self.f[keep], dict(self.metadata), signals)


def check_units(recording: Recording, where: str = "recording") -> None:
    """Catches recordings in the wrong units or axes with a message that says how to fix them.

    - median |f| near 1 with f_z near +1: specific force in g, not m/s^2;
    - median f_z near -9.81: z-down (aircraft body) axes, not z-up head axes;
    - median |f| far from 9.81, or median f_z far from +9.81: not a specific force with
      gravity (gravity removed?), or the wrong units;
    - |f| components above MAX_SPECIFIC_FORCE beyond an isolated glitch: a corrupt or
      mis-scaled column (runs of at most `GLITCH_MAX_SAMPLES` samples, together at most
      `GLITCH_MAX_SHARE` of the file and below `GLITCH_MAX_FORCE`, are glitches, such as a
      landing gear's ground contact: kept, and handled by the input plausibility guard,
      `mca_drake.cueing.plausibility`);
    - |omega| above 8 rad/s: angular velocity in deg/s, not rad/s. A deg/s file whose rates
      stay below 8 deg/s is not told apart from data alone (the specific force of a vehicle
      in coordinated motion does not show its rotation); name the units in the header
      (`omega_x [deg/s]`, see `load_recording`) and it is converted.

    Raises:
        RecordingError: naming `where`, the column at fault and the fix.
    """
    f = recording.f
    worst = np.unravel_index(np.argmax(np.abs(f)), f.shape)
    if abs(f[worst]) > MAX_SPECIFIC_FORCE and (
        abs(f[worst]) > GLITCH_MAX_FORCE
        or not _isolated_glitches(np.any(np.abs(f) > MAX_SPECIFIC_FORCE, axis=1))
    ):
        raise RecordingError(
            f"{where}: column {COLUMNS[4 + worst[1]]} at t = {recording.t[worst[0]]:.6g} s is "
            f"{f[worst]:.3g} m/s^2, beyond any vehicle ({MAX_SPECIFIC_FORCE:.0f} m/s^2 = 20 g): "
            "a corrupt value or the wrong units"
        )
    f_norm = np.median(np.linalg.norm(f, axis=1))
    fz = float(np.median(f[:, 2]))
    if _G_FILE_RANGE[0] <= f_norm <= _G_FILE_RANGE[1] and 0.5 <= fz <= 1.5:
        raise RecordingError(
            f"{where}: columns f_x, f_y, f_z look like g (median |f| = {f_norm:.3g}, median "
            f"f_z = {fz:.3g}); the format needs m/s^2: multiply by {GRAVITY}"
        )
    if fz < -0.5 * GRAVITY:
        raise RecordingError(
            f"{where}: column f_z is about -9.81 (median {fz:.3g}): the axes look z-down "
            "(aircraft body axes); the format is x forward, y left, z up, so negate y and z "
            "of both omega and f"
        )
    level = recording.metadata.get("level", "true").strip().lower() not in NOT_LEVEL
    if level and not (
        _SI_F_RANGE[0] <= f_norm <= _SI_F_RANGE[1] and _SI_FZ_RANGE[0] <= fz <= _SI_FZ_RANGE[1]
    ):
        hint = (
            "gravity looks subtracted: the format wants the specific force, add 9.81 to f_z"
            if abs(fz) < 0.2 * GRAVITY
            else "check the units (m/s^2) and that z points up"
        )
        raise RecordingError(
            f"{where}: columns f_x, f_y, f_z have median |f| = {f_norm:.3g} and median f_z = "
            f"{fz:.3g} m/s^2; a specific force of a mostly level vehicle has about +9.81 on "
            f"z (gravity included): {hint}. If the values are right and the vehicle is not "
            "mostly level (a parabolic or ballistic flight), say so in the header: "
            "'# level: false'"
        )
    peak = np.max(np.abs(recording.omega), axis=0)
    if np.any(peak > _MAX_PLAUSIBLE_RATE):
        column = COLUMNS[1 + int(np.argmax(peak))]
        raise RecordingError(
            f"{where}: column {column} reaches {peak.max():.3g}, implausible in rad/s; the"
            " file looks like deg/s: multiply by pi/180"
        )


def _isolated_glitches(beyond: np.ndarray) -> bool:
    """Whether the samples marked in `beyond` (T booleans) are isolated glitches: runs of at
    most GLITCH_MAX_SAMPLES, together at most GLITCH_MAX_SHARE of the samples."""
    count = int(beyond.sum())
    if count > max(GLITCH_MAX_SAMPLES, GLITCH_MAX_SHARE * beyond.size):
        return False
    edges = np.diff(np.r_[0, beyond.astype(int), 0])
    runs = np.flatnonzero(edges == -1) - np.flatnonzero(edges == 1)
    return bool(np.all(runs <= GLITCH_MAX_SAMPLES))


def recording_to_csv(recording: Recording) -> str:
    """The CSV text of `recording` (round-trips exactly: floats are written with repr)."""
    out = io.StringIO()
    out.write(f"# {FORMAT_TAG}\n")
    for key, value in recording.metadata.items():
        clean = str(value).replace("\n", " ")
        out.write(f"# {key}: {clean}\n")
    names = [f"{c} [{u}]" for c, u in zip(COLUMNS, SI_UNITS, strict=True)]
    names += [f"{name} [{SIGNALS[name][0]}]" for name in recording.signals]
    out.write(",".join(names) + "\n")
    table = np.column_stack([recording.as_array(), *recording.signals.values()])
    for row in table:
        out.write(",".join(repr(float(v)) for v in row) + "\n")
    return out.getvalue()


def save_recording(path: str | os.PathLike, recording: Recording) -> Path:
    """Writes `recording` as CSV, atomically; returns the path."""
    return atomic_write_text(path, recording_to_csv(recording))


# Units a header may name in brackets, and the factor to SI.
UNITS = {
    "t": {"s": 1.0, "ms": 1e-3},
    "omega": {"rad/s": 1.0, "deg/s": np.pi / 180},
    "f": {"m/s^2": 1.0, "m/s2": 1.0, "g": GRAVITY},
}
# The units this module writes into a header, column by column.
SI_UNITS = ("s", "rad/s", "rad/s", "rad/s", "m/s^2", "m/s^2", "m/s^2")
# Peaks of an angular velocity without a declared unit that fit both readings, so the file
# must name its unit: below 8 deg/s in rad/s (0.14: all but still in deg/s too), and from 2
# to 8 (aerobatic in rad/s, gentle in deg/s). Between them rad/s is assumed: a deg/s file
# would have to peak below 2 deg/s, a vehicle that hardly turns. Above 8, deg/s (an error).
_AMBIGUOUS_RATES = ((0.0, np.deg2rad(8.0)), (2.0, 8.0))
_HEADER_CELL = re.compile(r"^\s*([A-Za-z_]\w*)\s*(?:[\[(]\s*([^\])]*?)\s*[\])])?\s*$")


def _text_lines(path: Path):
    """The file's lines as text, read as they are needed: UTF-8 (a byte-order mark dropped),
    no NUL byte; a clear error naming the line otherwise."""
    offset = 0
    with path.open("rb") as f:
        for line_no, raw in enumerate(f, start=1):
            if line_no == 1 and raw.startswith(b"\xef\xbb\xbf"):
                raw, offset = raw[3:], 3
            try:
                line = raw.decode("utf-8")
            except UnicodeDecodeError as err:
                raise RecordingError(
                    f"{path}: line {line_no}: byte {offset + err.start} is not UTF-8 text "
                    f"({err.reason}); save the file as UTF-8 CSV"
                ) from None
            if "\x00" in line:
                raise RecordingError(
                    f"{path}: line {line_no}: a NUL byte; this is not a text CSV (a binary or "
                    "damaged file?)"
                )
            offset += len(raw)
            yield line


def _parse_header(
    path: Path, line_no: int, row: list[str]
) -> tuple[list[str], list[float], set[str]]:
    """(column names, SI factor of each, names with a declared unit) of a header row."""
    names, factors, declared = [], [], set()
    for cell in row:
        match = _HEADER_CELL.match(cell)
        name, unit = (match.group(1), match.group(2)) if match else (cell.strip(), None)
        factor = 1.0
        if name in SIGNALS:
            try:
                factor = signal_factor(name, unit)
            except ValueError as err:
                raise RecordingError(f"{path}: line {line_no}, column {name}: {err}") from None
        elif unit is not None and name in COLUMNS:
            kind = name.split("_")[0]
            if unit not in UNITS[kind]:
                raise RecordingError(
                    f"{path}: line {line_no}, column {name}: unknown unit '{unit}'; valid: "
                    f"{', '.join(UNITS[kind])}"
                )
            factor = UNITS[kind][unit]
            declared.add(name)
        names.append(name)
        factors.append(factor)
    missing = [c for c in COLUMNS if c not in names]
    if missing:
        raise RecordingError(
            f"{path}: line {line_no}: missing columns {missing}; the header must name "
            f"{', '.join(COLUMNS)} (found {[cell.strip() for cell in row]})"
        )
    return names, factors, declared


def _check_time_base(path: Path, t: np.ndarray, lines: list[int]) -> None:
    """Increasing times, a rate of at least MIN_RATE_HZ, no gap over MAX_GAP_S."""
    steps = np.diff(t)
    if np.any(steps <= 0):
        k = int(np.argmax(steps <= 0))
        raise RecordingError(
            f"{path}: line {lines[k + 1]}, column t: time {t[k + 1]} does not increase "
            f"(previous line {lines[k]}: {t[k]})"
        )
    typical = float(np.median(steps))
    if typical > (1 + RATE_TOLERANCE) / MIN_RATE_HZ:
        hint = " (is t in ms? name it `t [ms]` or divide by 1000)" if typical >= 1 else ""
        raise RecordingError(
            f"{path}: column t: samples {typical:.6g} s apart ({1 / typical:.3g} Hz), slower "
            f"than the {MIN_RATE_HZ:g} Hz that motion cues need{hint}"
        )
    k = int(np.argmax(steps))
    if steps[k] > MAX_GAP_S:
        raise RecordingError(
            f"{path}: lines {lines[k]} to {lines[k + 1]}, column t: a gap of {steps[k]:.6g} s "
            f"(from {t[k]:.6g} to {t[k + 1]:.6g}); resampling would invent the motion in it: "
            "split the file there or fill the gap"
        )


def load_recording(
    path: str | os.PathLike,
    *,
    rate_hz: float | None = DEFAULT_RATE_HZ,
    validate_units: bool = True,
    max_duration_s: float | None = None,
) -> Recording:
    """Reads and validates a recording CSV; resamples it to `rate_hz` (None: keep as is).

    With `max_duration_s`, reading stops once the samples cover that long (and `MAX_GAP_S`
    more, for the interpolation at the end): a day-long file asked for 3 s is not parsed
    whole. Faster files are low-passed before resampling (`Recording.resampled`).

    Times start at 0: a file with absolute time stamps (Unix epoch) is shifted, its first
    stamp kept in the metadata as `t0_s`. Header cells may name units in brackets
    (`UNITS`: `t [ms]`, `omega_x [deg/s]`, `f_z [g]`); values are converted to SI.

    Raises:
        FileNotFoundError: no such file.
        RecordingError: a folder, FIFO or device instead of a file, text that is not UTF-8
            or holds a NUL byte, a missing column, a row with too many or too few values (a
            decimal comma?), a value that is not a finite number, times that do not
            increase or leave a gap, too slow a rate, fewer than `MIN_DURATION_S` seconds,
            or implausible units; the message names file, line and column and says how to
            fix it.
    """
    path = Path(path)
    if path.is_dir():
        raise RecordingError(f"{path} is a folder, not a recording CSV")
    if path.exists() and not path.is_file():
        raise RecordingError(f"{path} is not a regular file (a FIFO or a device?): not a CSV")
    if not path.is_file():
        raise FileNotFoundError(f"recording not found: {path}")
    metadata: dict[str, str] = {}
    header: list[str] | None = None
    rows: list[list[float]] = []
    line_numbers: list[int] = []
    for line_no, row in enumerate(csv.reader(_text_lines(path)), start=1):
        if not row or all(not cell.strip() for cell in row):
            continue
        if row[0].lstrip().startswith("#"):
            text = ",".join(row).lstrip()[1:].strip()
            if ":" in text:
                key, value = text.split(":", 1)
                metadata[key.strip()] = value.strip()
            continue
        if header is None:
            header, factors, declared = _parse_header(path, line_no, row)
            kept = [*COLUMNS, *(name for name in header if name in SIGNALS)]
            index = [header.index(c) for c in kept]
            scale = [factors[i] for i in index]
            continue
        if len(row) != len(header):
            hint = (
                ": a decimal comma? Use '.' for decimals, ',' between values"
                if len(row) > len(header)
                else ""
            )
            raise RecordingError(
                f"{path}: line {line_no}: {len(row)} values for {len(header)} columns{hint}"
            )
        values = []
        for column, i, factor in zip(kept, index, scale, strict=True):
            cell = row[i].strip()
            try:
                value = float(cell)
            except ValueError:
                raise RecordingError(
                    f"{path}: line {line_no}, column {column}: '{cell}' is not a number"
                ) from None
            if not np.isfinite(value):
                raise RecordingError(
                    f"{path}: line {line_no}, column {column}: value {cell} is not finite"
                )
            values.append(value * factor)
        rows.append(values)
        line_numbers.append(line_no)
        if max_duration_s is not None and values[0] - rows[0][0] > max_duration_s + MAX_GAP_S:
            metadata["read_until_s"] = repr(values[0] - rows[0][0])
            break
    if header is None:
        raise RecordingError(f"{path}: no header line; expected {','.join(COLUMNS)}")
    if len(rows) < 2:
        raise RecordingError(f"{path}: needs at least 2 samples; found {len(rows)}")
    data = np.array(rows)
    _check_time_base(path, data[:, 0], line_numbers)
    if data[-1, 0] - data[0, 0] < MIN_DURATION_S:
        raise RecordingError(
            f"{path}: {len(rows)} samples over {data[-1, 0] - data[0, 0]:.6g} s; a recording "
            f"needs at least {MIN_DURATION_S:g} s to be cued and scored"
        )
    t = data[:, 0]
    if t[0] != 0.0:
        metadata["t0_s"] = repr(float(t[0]))
        t = t - t[0]
    signals = {name: data[:, 7 + i] for i, name in enumerate(kept[7:])}
    try:
        recording = Recording(t, data[:, 1:4], data[:, 4:7], metadata, signals)
    except RecordingError as err:  # a signal out of its bounds: name the file
        raise RecordingError(f"{path}: {err}") from None
    if validate_units:
        check_units(recording, where=str(path))
        peak = float(np.max(np.abs(recording.omega)))
        undeclared = [c for c in COLUMNS[1:4] if c not in declared]
        if undeclared and any(low < peak <= high for low, high in _AMBIGUOUS_RATES):
            raise RecordingError(
                f"{path}: columns {', '.join(undeclared)} peak at {peak:.3g}: that is "
                f"{peak:.3g} rad/s or {peak:.3g} deg/s, and the numbers cannot tell; name the "
                "unit in the header, e.g. `omega_x [rad/s]` or `omega_x [deg/s]`"
            )
    if rate_hz is not None:
        recording = recording.resampled(rate_hz)
    return recording

"""Vehicle motion recordings: what an IMU at the occupant's head measured, and its CSV file.

A recording holds, at times t (s), the angular velocity omega (rad/s) and the specific force
f (m/s^2) in head-frame axes: x forward, y left, z up (`mca_drake.conventions`). Specific force is
what an accelerometer reads: level and unaccelerated, f = (0, 0, +9.81).

File format (CSV, UTF-8):

    # mca-drake recording v1            <- optional comment lines, `# key: value` metadata
    # vehicle: light
    t,omega_x,omega_y,omega_z,f_x,f_y,f_z
    0.00,0.0,0.0,0.0,0.0,0.0,9.81
    ...

Columns may come in any order and extra columns are ignored; units are SI. The loader
validates everything and resamples to a uniform grid (100 Hz by default); every error names
the file, the line and the column.
"""

from __future__ import annotations

import csv
import dataclasses
import io
import os
from pathlib import Path

import numpy as np

from mca_drake.atomic_io import atomic_write_text
from mca_drake.conventions import GRAVITY

COLUMNS = ("t", "omega_x", "omega_y", "omega_z", "f_x", "f_y", "f_z")
DEFAULT_RATE_HZ = 100.0
FORMAT_TAG = "mca-drake recording v1"
# Unit plausibility thresholds (see `check_units`).
_MAX_PLAUSIBLE_RATE = 8.0  # rad/s; beyond aerobatic roll rates, typical of a file in deg/s
_G_FILE_RANGE = (0.5, 2.0)  # median |f| in this range: the file is in g, not m/s^2
_SI_F_RANGE = (4.0, 25.0)  # median |f| of any real vehicle, in m/s^2


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
    """

    t: np.ndarray
    omega: np.ndarray
    f: np.ndarray
    metadata: dict[str, str] = dataclasses.field(default_factory=dict)

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
        """Linear interpolation onto t0 + k / rate_hz (k = 0, 1, ...) up to the last sample."""
        if not rate_hz > 0:
            raise RecordingError(f"rate_hz must be positive; got {rate_hz}")
        h = 1.0 / rate_hz
        n = int(np.floor(self.duration_s / h + 1e-9)) + 1
        t = self.t[0] + h * np.arange(n)
        if self.t.size == n and np.allclose(self.t, t, rtol=0, atol=1e-9):
            return dataclasses.replace(self, metadata=dict(self.metadata))  # already uniform
        columns = [np.interp(t, self.t, c) for c in np.column_stack([self.omega, self.f]).T]
        data = np.column_stack(columns)
        return Recording(t, data[:, :3], data[:, 3:], dict(self.metadata))

    def sliced(self, start_s: float, stop_s: float) -> Recording:
        """Samples with start_s <= t - t0 < stop_s (times keep their values)."""
        rel = self.t - self.t[0]
        keep = (rel >= start_s - 1e-9) & (rel < stop_s - 1e-9)
        return Recording(self.t[keep], self.omega[keep], self.f[keep], dict(self.metadata))


def check_units(recording: Recording, where: str = "recording") -> None:
    """Catches recordings in the wrong units or axes with a message that says how to fix them.

    - median |f| near 1: specific force in g, not m/s^2;
    - median f_z near -9.81: z-down (aircraft body) axes, not z-up head axes;
    - |omega| above 8 rad/s: angular velocity in deg/s, not rad/s;
    - median |f| far from 9.81 otherwise: not a specific force (gravity removed?).

    Raises:
        RecordingError: naming `where` and the column at fault.
    """
    f_norm = np.median(np.linalg.norm(recording.f, axis=1))
    if _G_FILE_RANGE[0] <= f_norm <= _G_FILE_RANGE[1]:
        raise RecordingError(
            f"{where}: columns f_x, f_y, f_z look like g (median |f| = {f_norm:.3g}); "
            f"the format needs m/s^2: multiply by {GRAVITY}"
        )
    if np.median(recording.f[:, 2]) < -0.5 * GRAVITY:
        raise RecordingError(
            f"{where}: column f_z is about -9.81 (median {np.median(recording.f[:, 2]):.3g}): the"
            " axes look z-down (aircraft body axes); the format is x forward, y left, z up, so"
            " negate y and z of both omega and f"
        )
    if not _SI_F_RANGE[0] <= f_norm <= _SI_F_RANGE[1]:
        raise RecordingError(
            f"{where}: columns f_x, f_y, f_z have median |f| = {f_norm:.3g} m/s^2; a specific"
            " force has about 9.81 (gravity included): is gravity subtracted, or are the units"
            " wrong?"
        )
    peak = np.max(np.abs(recording.omega), axis=0)
    if np.any(peak > _MAX_PLAUSIBLE_RATE):
        column = COLUMNS[1 + int(np.argmax(peak))]
        raise RecordingError(
            f"{where}: column {column} reaches {peak.max():.3g}, implausible in rad/s; the"
            " file looks like deg/s: multiply by pi/180"
        )


def recording_to_csv(recording: Recording) -> str:
    """The CSV text of `recording` (round-trips exactly: floats are written with repr)."""
    out = io.StringIO()
    out.write(f"# {FORMAT_TAG}\n")
    for key, value in recording.metadata.items():
        clean = str(value).replace("\n", " ")
        out.write(f"# {key}: {clean}\n")
    out.write(",".join(COLUMNS) + "\n")
    for row in recording.as_array():
        out.write(",".join(repr(float(v)) for v in row) + "\n")
    return out.getvalue()


def save_recording(path: str | os.PathLike, recording: Recording) -> Path:
    """Writes `recording` as CSV, atomically; returns the path."""
    return atomic_write_text(path, recording_to_csv(recording))


def load_recording(
    path: str | os.PathLike,
    *,
    rate_hz: float | None = DEFAULT_RATE_HZ,
    validate_units: bool = True,
) -> Recording:
    """Reads and validates a recording CSV; resamples it to `rate_hz` (None: keep as is).

    Raises:
        FileNotFoundError: no such file.
        RecordingError: a missing column, a value that is not a finite number, times that do
            not increase, or implausible units; the message names file, line and column.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"recording not found: {path}")
    metadata: dict[str, str] = {}
    header: list[str] | None = None
    rows: list[list[float]] = []
    line_numbers: list[int] = []
    with path.open(newline="", encoding="utf-8") as handle:
        for line_no, row in enumerate(csv.reader(handle), start=1):
            if not row or all(not cell.strip() for cell in row):
                continue
            if row[0].lstrip().startswith("#"):
                text = ",".join(row).lstrip()[1:].strip()
                if ":" in text:
                    key, value = text.split(":", 1)
                    metadata[key.strip()] = value.strip()
                continue
            if header is None:
                header = [cell.strip() for cell in row]
                missing = [c for c in COLUMNS if c not in header]
                if missing:
                    raise RecordingError(
                        f"{path}: line {line_no}: missing columns {missing}; the header must "
                        f"name {', '.join(COLUMNS)} (found {header})"
                    )
                index = [header.index(c) for c in COLUMNS]
                continue
            if len(row) < len(header):
                raise RecordingError(
                    f"{path}: line {line_no}: {len(row)} values for {len(header)} columns"
                )
            values = []
            for column, i in zip(COLUMNS, index, strict=True):
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
                values.append(value)
            rows.append(values)
            line_numbers.append(line_no)
    if header is None:
        raise RecordingError(f"{path}: no header line; expected {','.join(COLUMNS)}")
    if len(rows) < 2:
        raise RecordingError(f"{path}: needs at least 2 samples; found {len(rows)}")
    data = np.array(rows)
    steps = np.diff(data[:, 0])
    if np.any(steps <= 0):
        k = int(np.argmax(steps <= 0))
        raise RecordingError(
            f"{path}: line {line_numbers[k + 1]}, column t: time {data[k + 1, 0]} does not "
            f"increase (previous line {line_numbers[k]}: {data[k, 0]})"
        )
    recording = Recording(data[:, 0], data[:, 1:4], data[:, 4:7], metadata)
    if validate_units:
        check_units(recording, where=str(path))
    if rate_hz is not None:
        recording = recording.resampled(rate_hz)
    return recording

"""Atomic file writes (a file that matters is either the old one or the complete new one)
and file fingerprints.

Writes go to a temporary file in the same folder, are flushed to disk, then renamed over
the target (rename is atomic on POSIX), so a killed process never leaves half a file. A
process killed mid-write (kill -9: no cleanup runs) leaves its temporary file behind; the
next write of the same target removes those of processes that are gone.

`check_writable` tells, before a long job starts, whether its output can be written at all;
`load_npz_with_metadata` reads the .npz files the tool writes (arrays plus JSON metadata, no
pickle) with one clear error for every way such a file can be damaged.
"""

from __future__ import annotations

import hashlib
import io
import json
import math
import os
import tempfile
import zipfile
from pathlib import Path

import numpy as np


def _temporary_prefix(path: Path, pid: int | str) -> str:
    return f".{path.name}.{pid}."


def _remove_orphaned_temporaries(path: Path) -> None:
    """Deletes temporary files of `path` left by writers that no longer run."""
    for tmp in path.parent.glob(f".{path.name}.*.tmp"):
        pid = tmp.name[len(path.name) + 2 :].split(".", 1)[0]
        if pid.isdigit() and not _process_alive(int(pid)):
            tmp.unlink(missing_ok=True)


def _process_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True  # another user's process
    return True


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> Path:
    """Writes `data` to `path` atomically, creating parent folders; returns the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    _remove_orphaned_temporaries(path)
    fd, tmp = tempfile.mkstemp(
        prefix=_temporary_prefix(path, os.getpid()), suffix=".tmp", dir=path.parent
    )
    try:
        # mkstemp creates the file 0600; give it the permissions a plain open() would.
        umask = os.umask(0)
        os.umask(umask)
        os.fchmod(fd, 0o666 & ~umask)
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def atomic_write_text(path: str | os.PathLike, text: str) -> Path:
    """Writes UTF-8 `text` to `path` atomically."""
    return atomic_write_bytes(path, text.encode("utf-8"))


def atomic_write_json(path: str | os.PathLike, obj) -> Path:
    """Writes `obj` as indented JSON to `path` atomically. Non-finite floats (NaN, inf),
    which JSON cannot hold, are written as null rather than as invalid `NaN`/`Infinity`."""
    text = json.dumps(_finite_or_none(obj), indent=2, sort_keys=False, allow_nan=False)
    return atomic_write_text(path, text + "\n")


def atomic_write_npz(path: str | os.PathLike, arrays: dict) -> Path:
    """Writes `arrays` (name -> numpy array, none of dtype object) as an .npz file to `path`
    atomically; `np.load(path)` reads it back without pickle."""
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)
    return atomic_write_bytes(path, buffer.getvalue())


def _finite_or_none(obj):
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _finite_or_none(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_finite_or_none(v) for v in obj]
    return obj


def check_writable(path: str | os.PathLike, *, folder: bool = False) -> Path:
    """Raises OSError naming `path` unless a file can be written there (or, with
    `folder`, into that folder), creating missing parent folders: called before a long job
    so that its result is not lost at the end. Returns the path."""
    path = Path(path)
    target = path if folder else path.parent
    try:
        target.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise OSError(f"cannot create the folder {target}: {err.strerror}") from None
    if path.is_dir() and not folder:
        raise OSError(f"cannot write {path}: it is a folder")
    if not os.access(target, os.W_OK | os.X_OK):
        raise OSError(f"cannot write into {target}: permission denied")
    return path


def file_sha256(path: str | os.PathLike) -> str:
    """Hex SHA-256 of a file's bytes: which exact file (a policy, a dataset) a result came
    from. FileNotFoundError names the path."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"file not found: {path}")
    return hashlib.sha256(path.read_bytes()).hexdigest()


def load_npz_with_metadata(path: str | os.PathLike, what: str) -> tuple[dict, dict]:
    """(arrays, metadata) of an .npz holding numpy arrays and a `metadata_json` string,
    loaded without pickle.

    Raises:
        FileNotFoundError: no such file.
        ValueError: "<path> is not a <what> file: <reason>" for a truncated, empty, damaged
            or foreign file, or metadata that is not a JSON mapping.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{what} file not found: {path}")
    try:
        with np.load(path, allow_pickle=False) as data:
            metadata = json.loads(str(data["metadata_json"]))
            arrays = {k: data[k] for k in data.files if k != "metadata_json"}
    # a damaged, truncated or empty file fails inside numpy or zipfile in several ways
    except (OSError, KeyError, ValueError, EOFError, zipfile.BadZipFile) as err:
        raise ValueError(f"{path} is not a {what} file: {err}") from err
    if not isinstance(metadata, dict):
        raise ValueError(f"{path}: its metadata is a {type(metadata).__name__}, not a mapping")
    return arrays, metadata

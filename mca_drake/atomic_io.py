"""Atomic file writes (a file that matters is either the old one or the complete new one)
and file fingerprints.

Writes go to a temporary file in the same folder, are flushed to disk, then renamed over
the target (rename is atomic on POSIX), so a killed process never leaves half a file. A
process killed mid-write (kill -9: no cleanup runs) leaves its temporary file behind; the
next write of the same target removes those of processes that are gone.

An output path is a regular file or nothing yet: a device node, a FIFO or a socket there is
refused, never replaced (run as root, replacing /dev/null would break the machine), and a
symbolic link is written through (its target replaced, the link kept) only when it points
inside the folder it sits in (`output_target`).

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
import stat
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


_FILE_KINDS = (
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISFIFO, "a FIFO (named pipe)"),
    (stat.S_ISSOCK, "a socket"),
    (stat.S_ISDIR, "a folder"),
)


def output_target(path: str | os.PathLike) -> Path:
    """The file an atomic write of `path` replaces: `path` itself, or the target of a
    symbolic link that points inside the link's own folder.

    Raises:
        OSError: naming `path`, when it is a device node, a FIFO, a socket or a folder, or
            a symbolic link that points outside its folder (or to any of those).
    """
    path = Path(path)
    target = path
    if path.is_symlink():
        target = path.resolve()
        folder = path.parent.resolve()
        if not target.is_relative_to(folder):
            raise OSError(
                f"refusing to write {path}: it is a symbolic link to {target}, outside "
                f"{folder}; write to a regular file instead"
            )
    try:
        mode = os.stat(target).st_mode
    except FileNotFoundError:
        return target
    for is_kind, kind in _FILE_KINDS:
        if is_kind(mode):
            where = f" (a link to {target})" if target != path else ""
            raise OSError(f"refusing to write {path}{where}: it is {kind}, not a regular file")
    return target


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> Path:
    """Writes `data` to `path` atomically, creating parent folders; returns the path.

    Raises:
        OSError: `path` is not a regular file (`output_target`), or cannot be written.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    link, path = path, output_target(path)
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
    return link


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
    if not folder:
        output_target(path)
    if not os.access(target, os.W_OK | os.X_OK):
        raise OSError(f"cannot write into {target}: permission denied")
    return path


def file_sha256(path: str | os.PathLike) -> str:
    """Hex SHA-256 of a file's bytes: which exact file (a policy, a dataset) a result came
    from. FileNotFoundError names the path."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"file not found: {path}")
    digest = hashlib.sha256()
    with open(path, "rb") as f:  # in blocks: a dataset may be hundreds of MB
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


# Largest .npz the tool reads, inflated, bytes: a segment dataset of hundreds of flights is a
# few hundred MB; a file claiming more is refused before anything is inflated.
MAX_NPZ_BYTES = 4 * 2**30


def _check_npz_members(path: Path, what: str, max_bytes: int, names: frozenset[str] | None) -> None:
    """Reads the archive's directory and each array's header, inflating no array: refuses
    unknown names, object arrays, headers that claim more than the member holds and members
    that inflate beyond `max_bytes` (in total)."""
    total = 0
    with zipfile.ZipFile(path) as archive:
        for info in archive.infolist():
            name = info.filename.removesuffix(".npy")
            if names is not None and name not in names | {"metadata_json"}:
                raise ValueError(f"{path} is not a {what} file: it holds an array '{name}'")
            total += info.file_size
            if total > max_bytes:
                raise ValueError(
                    f"{path} is not a {what} file: it inflates to over {max_bytes} bytes "
                    f"(at '{name}')"
                )
            with archive.open(info) as member:
                version = np.lib.format.read_magic(member)
                read_header = (
                    np.lib.format.read_array_header_1_0
                    if version == (1, 0)
                    else np.lib.format.read_array_header_2_0
                )
                shape, _, dtype = read_header(member)
            if dtype.hasobject:
                raise ValueError(f"{path} is not a {what} file: '{name}' holds Python objects")
            claimed = math.prod(shape) * dtype.itemsize
            if claimed > info.file_size:
                raise ValueError(
                    f"{path} is not a {what} file: '{name}' claims shape {shape} "
                    f"({claimed} bytes) but holds {info.file_size}"
                )


def load_npz_with_metadata(
    path: str | os.PathLike,
    what: str,
    *,
    names: frozenset[str] | None = None,
    max_bytes: int = MAX_NPZ_BYTES,
) -> tuple[dict, dict]:
    """(arrays, metadata) of an .npz holding numpy arrays and a `metadata_json` string,
    loaded without pickle. The archive's directory and array headers are checked first, so
    a file that claims or inflates to more than `max_bytes` is refused before allocation.

    Args:
        path: the file.
        what: what the file should be, for messages ("policy", "segment dataset").
        names: the array names such a file may hold (`metadata_json` aside); None: any.
        max_bytes: the largest inflated size accepted, bytes.

    Raises:
        FileNotFoundError: no such file.
        ValueError: "<path> is not a <what> file: <reason>" for a truncated, empty, damaged,
            oversized or foreign file, or metadata that is not a JSON mapping.
    """
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{what} file not found: {path}")
    try:
        _check_npz_members(path, what, max_bytes, names)
        with np.load(path, allow_pickle=False) as data:
            metadata = json.loads(str(data["metadata_json"]))
            arrays = {k: data[k] for k in data.files if k != "metadata_json"}
    # a damaged, truncated or empty file fails inside numpy or zipfile in several ways
    except (OSError, KeyError, ValueError, EOFError, zipfile.BadZipFile) as err:
        if str(err).startswith(f"{path} is not a {what} file"):
            raise
        raise ValueError(f"{path} is not a {what} file: {err}") from err
    if not isinstance(metadata, dict):
        raise ValueError(f"{path}: its metadata is a {type(metadata).__name__}, not a mapping")
    return arrays, metadata

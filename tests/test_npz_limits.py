"""The .npz files the tool loads are checked before anything is inflated: a header that
claims more than its member holds, an archive that inflates beyond the limit, arrays of
Python objects or names the format does not define are refused with a message."""

from __future__ import annotations

import io
import json
import zipfile

import numpy as np
import pytest

from mca_drake.atomic_io import load_npz_with_metadata
from mca_drake.cueing.dpc import POLICY_MAX_BYTES, default_policy_path, load_policy_arrays


def _npy_bytes(header: dict, payload: bytes) -> bytes:
    buffer = io.BytesIO()
    np.lib.format.write_array_header_1_0(buffer, header)
    return buffer.getvalue() + payload


def _metadata_npy() -> bytes:
    buffer = io.BytesIO()
    np.save(buffer, np.array(json.dumps({"format": "test"})))
    return buffer.getvalue()


def test_a_header_claiming_a_huge_shape_is_refused_without_allocating(tmp_path):
    path = tmp_path / "huge.npz"
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("metadata_json.npy", _metadata_npy())
        header = {"descr": "<f8", "fortran_order": False, "shape": (10**12,)}
        archive.writestr("W1.npy", _npy_bytes(header, b"\0" * 64))
    with pytest.raises(ValueError, match=r"claims shape \(1000000000000,\)"):
        load_npz_with_metadata(path, "policy")


def test_an_archive_that_inflates_beyond_the_limit_is_refused(tmp_path):
    path = tmp_path / "bomb.npz"
    np.savez_compressed(path, metadata_json=np.array("{}"), W1=np.zeros(4 * 2**20))  # 32 MiB
    assert path.stat().st_size < 100_000  # small on disk
    with pytest.raises(ValueError, match=f"inflates to over {POLICY_MAX_BYTES} bytes"):
        load_policy_arrays(path)


def test_unknown_names_and_object_arrays_are_refused(tmp_path):
    named = tmp_path / "named.npz"
    np.savez(named, metadata_json=np.array("{}"), payload=np.zeros(3))
    with pytest.raises(ValueError, match="holds an array 'payload'"):
        load_policy_arrays(named)
    objects = tmp_path / "objects.npz"
    with zipfile.ZipFile(objects, "w") as archive:
        archive.writestr("metadata_json.npy", _metadata_npy())
        header = {"descr": "|O", "fortran_order": False, "shape": (1,)}
        archive.writestr("W1.npy", _npy_bytes(header, b"\0" * 8))
    with pytest.raises(ValueError, match="holds Python objects"):
        load_npz_with_metadata(objects, "policy")


def test_the_shipped_policy_passes_the_checks():
    arrays, metadata = load_policy_arrays(default_policy_path())
    assert arrays["W1"].ndim == 2 and metadata["format"]

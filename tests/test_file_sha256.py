"""`atomic_io.file_sha256`: the hash that ties results to the exact file they came from."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

from mca_drake.atomic_io import file_sha256


@pytest.mark.parametrize("size", [0, 1, (1 << 20) - 1, 1 << 20, 3 * (1 << 20) + 17])
def test_the_hash_of_a_file_read_in_blocks_is_that_of_its_bytes(tmp_path, size):
    """Against hashlib over the whole content at once, at sizes around the 1 MiB block."""
    data = np.random.default_rng(size).integers(0, 256, size, dtype=np.uint8).tobytes()
    path = tmp_path / "data.bin"
    path.write_bytes(data)
    assert file_sha256(path) == hashlib.sha256(data).hexdigest()


def test_a_missing_file_is_named(tmp_path):
    with pytest.raises(FileNotFoundError, match=r"nothing\.npz"):
        file_sha256(tmp_path / "nothing.npz")

"""Block files written by engine.io.npz: the .npz format np.load reads, every member's CRC
checked; a changed byte of the values is caught by the zip's CRC."""

from __future__ import annotations

import io
import zipfile

import numpy as np
import pytest

from engine.io.npz import write_npz


def _arrays():
    rng = np.random.default_rng(7)
    return {
        "orbit_class": rng.integers(0, 9, (2, 3, 4, 5)).astype(np.int8),
        "r_min": rng.random((2, 3, 4, 5)),
        "period": rng.random((2, 3, 4, 5)).astype(np.float32),
        "strided": rng.random((4, 6))[:, ::2],  # not contiguous: written as C order
        "empty": np.zeros((0, 3)),
    }


def test_np_load_reads_every_member_back_exactly():
    buf = io.BytesIO()
    arrays = _arrays()
    write_npz(buf, arrays)
    assert zipfile.ZipFile(io.BytesIO(buf.getvalue())).testzip() is None  # every CRC right
    with np.load(io.BytesIO(buf.getvalue()), allow_pickle=False) as z:
        assert list(z.files) == list(arrays)
        for name, arr in arrays.items():
            assert z[name].dtype == arr.dtype and z[name].shape == arr.shape
            np.testing.assert_array_equal(z[name], arr)


def test_a_changed_value_byte_fails_the_crc():
    buf = io.BytesIO()
    write_npz(buf, {"r_min": np.arange(1000, dtype=np.float64)})
    data = bytearray(buf.getvalue())
    data[500] ^= 0x01  # inside the values
    with (
        np.load(io.BytesIO(bytes(data)), allow_pickle=False) as z,
        pytest.raises(zipfile.BadZipFile),
    ):
        z["r_min"]

"""CRCs: check values of the catalogue, vectorised kernels against crccheck byte by byte."""

from __future__ import annotations

import numpy as np
from crccheck.crc import Crc8SaeJ1850, Crc16CcittFalse
from hypothesis import given, settings
from hypothesis import strategies as st

from bench.wire.crc import (
    crc8_can,
    crc8_can_rows,
    crc8_j1850,
    crc8_j1850_rows,
    crc16_ccitt_false,
    crc16_ccitt_false_rows,
)


def test_catalogue_check_values():
    # reveng catalogue: check = CRC of b"123456789"
    assert crc8_j1850(b"123456789") == 0x4B
    assert crc16_ccitt_false(b"123456789") == 0x29B1
    row = np.frombuffer(b"123456789", np.uint8)[None]
    assert crc8_j1850_rows(row)[0] == 0x4B
    assert crc16_ccitt_false_rows(row)[0] == 0x29B1


def _bitwise_crc8(data: bytes) -> int:
    crc = 0xFF
    for b in data:
        crc ^= b
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1D) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
    return crc ^ 0xFF


def _bitwise_crc16(data: bytes) -> int:
    crc = 0xFFFF
    for b in data:
        crc ^= b << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) & 0xFFFF if crc & 0x8000 else (crc << 1) & 0xFFFF
    return crc


@settings(max_examples=200, deadline=None)
@given(st.integers(1, 30), st.integers(0, 64), st.integers(0, 2**32 - 1))
def test_rows_match_crccheck_and_the_bit_loop(n, width, seed):
    rows = np.random.default_rng(seed).integers(0, 256, (n, width), dtype=np.uint8)
    c8 = crc8_j1850_rows(rows)
    c16 = crc16_ccitt_false_rows(rows)
    for i in range(n):
        data = rows[i].tobytes()
        assert c8[i] == Crc8SaeJ1850.calc(data) == _bitwise_crc8(data)
        assert c16[i] == Crc16CcittFalse.calc(data) == _bitwise_crc16(data)


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 0x7FF), st.binary(min_size=7, max_size=7))
def test_can_crc_is_over_the_id_byte_then_bytes_0_to_6(can_id, payload):
    want = _bitwise_crc8(bytes([can_id & 0xFF]) + payload)
    assert crc8_can(can_id, payload) == want
    row = np.frombuffer(payload + b"\x00", np.uint8)[None]
    assert crc8_can_rows(can_id, row)[0] == want
    assert crc8_can_rows(np.array([can_id]), row)[0] == want

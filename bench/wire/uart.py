"""What a UART receiving at one baud rate makes of characters sent at another.

The model of the ``baud_mismatch`` wire fault. The transmitter puts each byte of a burst
on the line back to back at ``tx_baud``: a start bit (0), the data bits LSB first, a
parity bit if the framing has one, the stop bit(s) (1); the line is idle (1) before and
after the burst. The receiver runs at ``rx_baud`` like a standard UART:

1. it waits for the line to be low (the falling edge of a start bit; right away if the
   line is still low where the previous character's stop bit was sampled);
2. it samples the middle of the start bit (``0.5`` receiver bit times on); if the line is
   high there it was a glitch and it waits again from that point;
3. it samples the middle of each data bit, the parity bit and the stop bit;
4. a stop bit read as 0 is a framing error: the character is delivered as ``0x00``,
   which is what Linux does for a serial port opened by pyserial (termios without
   ``IGNPAR`` and ``PARMRK``); a parity error likewise;
5. it looks for the next start bit from the stop-bit sample on.

Near the nominal rate (within a few per cent for 8N1) the bytes come through intact;
beyond it the receiver reads wrong bits, framing errors and a different number of
characters, as a real one does.
"""

from __future__ import annotations

import numpy as np

from bench.frames import parse_framing

__all__ = ["uart_receive", "line_bits"]


def _parity_bit(byte: int, data: int, parity: str) -> int:
    ones = bin(byte & ((1 << data) - 1)).count("1")
    return {"E": ones & 1, "O": 1 - (ones & 1), "M": 1, "S": 0}[parity]


def line_bits(data: bytes, framing: str = "8N1") -> np.ndarray:
    """The line levels (one entry per bit time, uint8 0/1) of ``data`` sent back to back.

    Half stop bits (1.5) are rounded up to whole bit times of the line.
    """
    nbits, parity, stop = parse_framing(framing)
    stop_bits = int(np.ceil(stop))
    out = []
    for b in data:
        bits = [0] + [(b >> i) & 1 for i in range(nbits)]
        if parity != "N":
            bits.append(_parity_bit(b, nbits, parity))
        out.extend(bits + [1] * stop_bits)
    return np.array(out, np.uint8)


def uart_receive(data: bytes, tx_baud: float, rx_baud: float, framing: str = "8N1") -> bytes:
    """The characters a receiver at ``rx_baud`` reads from ``data`` sent at ``tx_baud``."""
    if not data:
        return b""
    nbits, parity, _stop = parse_framing(framing)
    line = line_bits(data, framing)
    t_tx = 1.0 / tx_baud
    t_rx = 1.0 / rx_baud
    end = line.size * t_tx
    zeros = np.flatnonzero(line == 0)

    def level(t: float) -> int:
        if t < 0.0 or t >= end:
            return 1
        return int(line[int(t / t_tx)])

    def next_low(t: float) -> float | None:
        if level(t) == 0:
            return t
        k = np.searchsorted(zeros, int(t / t_tx) + 1)
        return None if k >= zeros.size else float(zeros[k]) * t_tx

    out = bytearray()
    t = 0.0
    frame_bits = 1 + nbits + (parity != "N")  # start, data, parity; the stop bit follows
    while True:
        start = next_low(t)
        if start is None:
            break
        if level(start + 0.5 * t_rx) != 0:  # glitch, not a start bit
            t = start + 0.5 * t_rx
            continue
        value = 0
        for i in range(nbits):
            value |= level(start + (1 + i + 0.5) * t_rx) << i
        ok = True
        if parity != "N":
            ok = level(start + (1 + nbits + 0.5) * t_rx) == _parity_bit(value, nbits, parity)
        stop_at = start + (frame_bits + 0.5) * t_rx
        if level(stop_at) != 1:
            ok = False
        out.append(value if ok else 0)
        t = stop_at
    return bytes(out)

"""Links: CAN buses over python-can and serial lines over pyserial and ptys.

Only this package touches ``can.Message`` and serial ports; it moves the bench's own
frame types (:mod:`bench.frames`) and knows nothing of their contents.

Modules
-------
:mod:`bench.transport.can_link`     :class:`~bench.transport.can_link.CanLink` on any python-can interface
:mod:`bench.transport.udp`          udp_multicast with sequence numbers and a drop count
:mod:`bench.transport.serial_link`  pty pairs, real ports, ``loop://``
:mod:`bench.transport.pacing`       real-time byte pacing at baud and framing
:mod:`bench.transport.export`       ASC and BLF export and read-back
:mod:`bench.transport.canlog`       field CAN logs (ASC, BLF, ...) read for replay

See docs/wire.md.
"""

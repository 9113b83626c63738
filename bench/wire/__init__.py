"""Codecs of the ICD: CAN messages by DBC (cantools), the IMU serial frame, NMEA 0183.

Symmetric and strict: every codec has ``encode`` and ``decode`` side by side, per frame
(raising :class:`bench.errors.CodecError` with a kind) and vectorised over many frames
(returning a status per frame, so receivers count bad frames without a Python loop).

Modules
-------
:mod:`bench.wire.dbc`          the DBC (models/can/icd_1_0.dbc) read with cantools
:mod:`bench.wire.can`          CAN message codecs, :class:`~bench.wire.can.CanEncoder`
:mod:`bench.wire.quantities`   SI quantity names of each CAN message
:mod:`bench.wire.imu`          the 42-byte IMU frame; :mod:`bench.wire.imu_stream` resync
:mod:`bench.wire.nmea`         RMC, GGA, GST, VTG, ZDA; :mod:`bench.wire.nmea_stream` framing
:mod:`bench.wire.receive`      NAV_* receiver (bench side), bench-traffic decoder (DUT side)
:mod:`bench.wire.crc`          CRC-8/SAE-J1850 and CRC-16/CCITT-FALSE, vectorised
:mod:`bench.wire.bits`         little-endian bit fields over many payloads
:mod:`bench.wire.sequence`     counters, duplicates, stale values
:mod:`bench.wire.tally`        counts by kind and the kept bad frames

Frame types (:class:`~bench.frames.CanBatch`, :class:`~bench.frames.SerialBatch`) live in
:mod:`bench.frames`, shared with the links of :mod:`bench.transport`. See docs/wire.md.
"""

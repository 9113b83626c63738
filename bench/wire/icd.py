"""The named values of the ICD's enumerated CAN fields (ICD 2.1, 2.2), written once.

The DBC (``models/can/icd_1_0.dbc``) gives these values in its signal comments and value
tables; the codecs carry them as plain integers (``mode``, ``frame``, ``valid``,
``fault_detected``, ``excluded``, ``odo_fault_class`` of the NAV records,
``command`` of BENCH_CMD). A DUT author gets them from :mod:`bench.dut`; the tests check
them against the DBC. Plain integers, no imports: any layer may use them.
"""

from __future__ import annotations

__all__ = [
    "FRAME_GEOGRAPHIC",
    "FRAME_GRID",
    "MODE_ALIGNING",
    "MODE_INERTIAL",
    "MODE_DOPPLER",
    "MODE_ODOMETER",
    "MODE_BDS",
    "MODE_MULTI_SENSOR",
    "MODE_NAMES",
    "SOLUTION_INVALID",
    "SOLUTION_VALID",
    "FAULT_ODOMETER",
    "FAULT_DOPPLER",
    "FAULT_BDS",
    "FAULT_IMU",
    "ODO_FAULT_NONE",
    "ODO_FAULT_LONGITUDINAL",
    "ODO_FAULT_LATERAL",
    "ODO_FAULT_VERTICAL",
    "CMD_SWITCH_TO_GRID",
    "CMD_SWITCH_TO_GEOGRAPHIC",
    "CMD_RESET_FILTER",
    "EPOCH_MODULUS",
]

# NAV_SOLUTION NavFrame: the navigation frame in use
FRAME_GEOGRAPHIC = 0
FRAME_GRID = 1

# NAV_SOLUTION Mode
MODE_ALIGNING = 0
MODE_INERTIAL = 1
MODE_DOPPLER = 2
MODE_ODOMETER = 3
MODE_BDS = 4
MODE_MULTI_SENSOR = 5
#: Mode value -> the ICD's name of it.
MODE_NAMES = {
    MODE_ALIGNING: "aligning",
    MODE_INERTIAL: "inertial only",
    MODE_DOPPLER: "Doppler-aided",
    MODE_ODOMETER: "odometer-aided",
    MODE_BDS: "BDS-aided",
    MODE_MULTI_SENSOR: "multi-sensor",
}

# NAV_SOLUTION SolutionValid
SOLUTION_INVALID = 0
SOLUTION_VALID = 1

# NAV_QUALITY fault_detected / excluded: one bit per sensor (a mask; combine with |)
FAULT_ODOMETER = 1 << 0
FAULT_DOPPLER = 1 << 1
FAULT_BDS = 1 << 2
FAULT_IMU = 1 << 3

# NAV_QUALITY OdoFaultClass
ODO_FAULT_NONE = 0
ODO_FAULT_LONGITUDINAL = 1  # slide, idle, no output
ODO_FAULT_LATERAL = 2  # sideslip, turning
ODO_FAULT_VERTICAL = 3  # bump

# BENCH_CMD Command
CMD_SWITCH_TO_GRID = 1
CMD_SWITCH_TO_GEOGRAPHIC = 2
CMD_RESET_FILTER = 3

#: The NAV epoch counters (EpochCounter) count modulo this.
EPOCH_MODULUS = 256

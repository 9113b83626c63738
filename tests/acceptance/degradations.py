"""The synthetic DUT's output degradations and the default integrity criterion that must
name each (tests of the INTEGRITY-* defaults)."""

#: output degradation kind -> the default criterion that must name it
KINDS = {
    "bad_crc": "INTEGRITY-bad-frames",
    "out_of_range": "INTEGRITY-range",
    "counter_stuck": "INTEGRITY-counter",
    "counter_skip": "INTEGRITY-counter",
    "time_frozen": "INTEGRITY-repeated",
    "time_backwards": "INTEGRITY-order",
    "time_jump": "INTEGRITY-jump",
    "no_quality": "INTEGRITY-quality",
    "drop": "INTEGRITY-missing",
    "invalid": "INTEGRITY-invalid",
}

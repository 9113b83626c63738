"""The run engine: one run of a scenario with a DUT over its links, recorded."""

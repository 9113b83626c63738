"""Reports of acceptance runs: results JSON, JUnit XML, summary tables, plots.

See :mod:`~bench.report.outputs` for what ``bench accept`` writes.
"""

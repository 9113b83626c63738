"""Acceptance: test cases, criteria, verdicts, and the runs that feed them.

* :mod:`~bench.acceptance.case` -- the test-case file (schema in
  :mod:`~bench.acceptance.schema`, :mod:`~bench.acceptance.criteria_schema`,
  :mod:`~bench.acceptance.run_schema`);
* :mod:`~bench.acceptance.criteria` -- limits by meaning, marginal bands, Monte Carlo
  statistics; :mod:`~bench.acceptance.verdict` -- PASS, MARGINAL, FAIL, ERROR;
* :mod:`~bench.acceptance.integrity_criteria` -- the output-integrity criteria every case
  gets by default; :mod:`~bench.acceptance.corrupt` -- broken DUT output for its tests;
* :mod:`~bench.acceptance.runner` -- the :class:`CaseRunner` seam that executes one run and
  returns its recording; :mod:`~bench.acceptance.synthetic` -- the synthetic-DUT runner;
* :mod:`~bench.acceptance.judge` -- recordings judged against cases;
  :mod:`~bench.acceptance.suite` -- cases run and judged.

See ``docs/test_cases.md`` and ``docs/scoring.md``.
"""

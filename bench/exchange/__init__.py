"""Exchange of runs with estimators that work on files (``docs/exchange.md``).

* :mod:`~bench.exchange.i2nav_export`: a recording's sensor streams, truth and (optionally)
  DUT solution in the i2Nav text formats (KF-GINS, OB_GINS) with a KF-GINS configuration;
* :mod:`~bench.exchange.nav_import`: a ``.nav`` result made into a run's DUT output, in a
  recording ``bench score`` judges like any run;
* :mod:`~bench.exchange.batch`: the ``batch`` DUT kind, a command run on the exported
  files whose result is imported and judged.

Formats and frames: :mod:`~bench.exchange.i2nav_text`; time base: :mod:`~bench.exchange.gpstime`.
"""

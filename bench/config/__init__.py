"""Configuration values as they enter the bench: one validation layer for every loader.

* :mod:`~bench.config.table` -- :class:`~bench.config.table.Table`, a TOML table read
  key by key (types, units, choices, finite numbers, bounds, unknown keys);
  :func:`~bench.config.table.check_keys` for loaders that walk raw tables;
* :mod:`~bench.config.bounds` -- the physical bounds of durations, rates, counts, sizes
  and periods, one table (:data:`~bench.config.bounds.BOUNDS`);
* :mod:`~bench.config.files` -- user files read as regular files of bounded size.

A base layer: it imports only :mod:`bench.errors` and :mod:`bench.units`. Errors are
:class:`~bench.errors.ConfigError` naming the file, the key, the value and the bound.
"""

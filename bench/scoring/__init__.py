"""Scoring: metrics of a DUT's navigation output, computed from a recording only.

Scoring reads one MCAP recording (:func:`~bench.scoring.data.load_run`) and nothing
else: no links, sensors, plant or clock. The truth is interpolated to the DUT's times of
validity (:mod:`~bench.scoring.align`), windows are resolved against the run
(:mod:`~bench.scoring.windows`) and the metric families compute their values:
accuracy, fault detection and isolation, frame-switch smoothness, consistency and
output quality and integrity (:mod:`~bench.scoring.epochs`; catalogue in
:mod:`~bench.scoring.metrics`). See ``docs/scoring.md``.

The same functions make the Foxglove views of a recording (:mod:`~bench.scoring.views`,
written into it by :mod:`~bench.scoring.viewwrite`): derived for display, never read back
by scoring.
"""

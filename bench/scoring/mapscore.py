"""The ``map.*`` metrics of a recording: the DUT's track against the case's road network.

The network is the case's ``[scoring.map] network`` (a GeoJSON file, see
:mod:`bench.scoring.roadmap`). A recording carries it as the attachment ``map/<file>``
(written by the runner with the case), so ``bench score`` judges a recording against the
very network its run was judged against; a recording without that attachment falls back
to the file named in the case, resolved next to the case file.

Epochs are those the accuracy metrics use (:func:`bench.scoring.accuracy.select`: the
DUT's valid epochs inside the truth and the window). DUT and truth positions (the truth
interpolated to the DUT's times of validity, :func:`bench.scoring.align.interpolate_truth`)
are put into the network's local plane from their latitude and longitude
(:meth:`RoadNetwork.to_enu`), and :func:`bench.scoring.mapmetrics.map_metrics` measures:

* ``map.on_road`` -- fraction of epochs within ``tolerance`` of the true road segment;
* ``map.lateral.<rms|mean|p95|max>`` -- distance of the DUT to the true road segment, m;
* ``map.distractor_max`` -- longest episode nearer a distractor than the true road and
  within ``tolerance`` of it, s.

A valid epoch with a non-finite position is the DUT's failure
(:class:`~bench.scoring.data.DutDataError`, FAIL); a network the bench cannot find or read
is the bench's (:class:`~bench.scoring.data.NoDataError`, ERROR).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path, PurePath
from typing import TYPE_CHECKING, Any

import numpy as np

from bench.errors import ConfigError
from bench.scoring.accuracy import select
from bench.scoring.align import NavErrors, interpolate_truth
from bench.scoring.data import DutDataError, NoDataError, RunData
from bench.scoring.windows import Window

if TYPE_CHECKING:  # the geometry (shapely, scipy) is imported when a map metric is asked for
    from bench.scoring.roadmap import RoadNetwork

__all__ = ["MapSettings", "MAP_METRICS", "ATTACHMENT_PREFIX", "load_network", "map_window"]

#: Attachment names of road networks in a recording: ``map/<file name>``.
ATTACHMENT_PREFIX = "map/"

#: metric (after ``map.``) -> (dimension, display unit, description)
MAP_METRICS: dict[str, tuple[str, str, str]] = {
    "on_road": ("dimensionless", "%", "fraction of epochs within the tolerance of the true road segment"),
    "lateral.rms": ("length", "m", "RMS distance of the DUT to the true road segment"),
    "lateral.mean": ("length", "m", "mean distance of the DUT to the true road segment"),
    "lateral.p95": ("length", "m", "95 % distance of the DUT to the true road segment"),
    "lateral.max": ("length", "m", "largest distance of the DUT to the true road segment"),
    "distractor_max": ("time", "s", "longest episode on a distractor road (nearer it than the true road)"),
}


@dataclass(frozen=True)
class MapSettings:
    """``[scoring.map]`` of a case: the network as written, the file it resolves to (None
    for a case read from a recording), and the lateral tolerance, m."""

    network: str
    path: Path | None = None
    tolerance: float = 5.0

    @property
    def attachment(self) -> str:
        """The network's attachment name in a recording."""
        return ATTACHMENT_PREFIX + PurePath(self.network).name


def load_network(run: RunData, settings: MapSettings) -> RoadNetwork:
    """The case's road network: the recording's attachment, else the case's file."""
    from bench.scoring.roadmap import RoadNetwork

    data = run.attachments.get(settings.attachment)
    try:
        if data is not None:
            return RoadNetwork.from_geojson_text(data, file=f"{run.path}:{settings.attachment}")
        if settings.path is None:
            raise NoDataError(
                f"the recording carries no road network ({settings.attachment}) and the case's "
                f"network {settings.network!r} cannot be resolved without the case file (give --case)"
            )
        return RoadNetwork.from_geojson(settings.path)
    except ConfigError as exc:
        raise NoDataError(f"road network: {exc}") from None


def map_window(
    net: RoadNetwork, run: RunData, errors: NavErrors, window: Window, tolerance: float
) -> tuple[dict[str, float], dict[str, Any]]:
    """Every map metric over ``window`` and the details they share."""
    from bench.scoring.mapmetrics import map_metrics

    idx = select(errors, window)
    nav = run.require_nav()[errors.index[idx]]
    bad = ~(np.isfinite(nav["lat"]) & np.isfinite(nav["lon"]))
    if np.any(bad):
        first = float(errors.t_ns[idx][bad][0]) * 1e-9
        raise DutDataError(
            f"the DUT flagged {int(np.sum(bad))} epochs with a non-finite position valid "
            f"(first at {first:g} s) in window {window.text()}"
        )
    t_ns = errors.t_ns[idx]
    truth = interpolate_truth(run.require_truth(), t_ns)
    dut_en = net.to_enu(nav["lat"], nav["lon"])
    truth_en = net.to_enu(truth.lat, truth.lon)
    values = map_metrics(net, t_ns * 1e-9, dut_en, truth_en, tolerance)
    details = {"epochs": len(idx), "window": window.text(), "tolerance_m": tolerance}
    return values, details

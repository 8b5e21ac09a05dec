"""TouchSensorMap fails closed: tampered, empty, truncated or foreign files, dead or inverted channels
and non-finite readings are refused."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from tests.helpers import linear_sensor_map


@pytest.mark.parametrize(
    ("edit", "match"),
    [
        (lambda c: c.force_knots.fill_(float("nan")), "must be finite"),
        (lambda c: c.force_knots.zero_(), "spans 0 N"),
        (lambda c: c.force_knots.copy_(c.force_knots.flip(-1)), "must not decrease"),
        (lambda c: c.raw_knots.fill_(1.0), "strictly increasing"),
        (lambda c: c.raw_zero.fill_(float("inf")), "raw_zero must be finite"),
        (lambda c: c.fitted.fill_(False), "never fitted"),
    ],
)
def test_a_tampered_sensor_map_file_is_refused_on_load(tmp_path, edit, match):
    from gentlerl.transforms import TouchSensorMap

    sensor_map, _ = linear_sensor_map()
    edit(sensor_map)
    path = tmp_path / "cal.pt"
    sensor_map.save(path)
    with pytest.raises(ValueError, match=match):
        TouchSensorMap.load(path)


@pytest.mark.parametrize(
    "content", [b"", b"not a torch file", None], ids=["empty", "garbage", "truncated"]
)
def test_empty_truncated_or_foreign_sensor_map_files_are_refused(tmp_path, content):
    from gentlerl.transforms import TouchSensorMap

    path = tmp_path / "cal.pt"
    if content is None:
        linear_sensor_map()[0].save(path)
        content = path.read_bytes()[:200]
    path.write_bytes(content)
    with pytest.raises(ValueError, match="is not a TouchSensorMap file"):
        TouchSensorMap.load(path)
    torch.save({"shape": (5, 1), "n_knots": 10**9, "state": {}}, path)
    with pytest.raises(ValueError, match="not a hand's sensor map"):
        TouchSensorMap.load(path)


def test_fit_refuses_dead_inverted_and_unbounded_channels():
    from gentlerl.transforms import TouchSensorMap

    _, force = linear_sensor_map()
    with pytest.raises(ValueError, match="dead channel"):
        TouchSensorMap(n_knots=8).fit(np.full_like(force, 1000.0), force)
    with pytest.raises(ValueError, match="inverted"):
        TouchSensorMap(n_knots=8).fit(3000 - 100 * force, force)
    for span in (float("nan"), -1.0, 0.0, "1"):
        with pytest.raises(ValueError, match="min_span"):
            TouchSensorMap(n_knots=8).fit(1000 + 100 * force, force, min_span=span)


def test_forward_map_refuses_non_finite_raw_readings():
    sensor_map, _ = linear_sensor_map()
    for value in (-np.inf, np.inf, np.nan):
        with pytest.raises(ValueError, match="must be finite"):
            sensor_map.forward_map(np.full((5, 1), value))

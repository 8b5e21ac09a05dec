"""TouchSensorMap: isotonic fit of a known sensor curve, inverse, tare, state, bad input."""

import numpy as np
import pytest
import torch
from tensordict import TensorDict

from gentlerl.transforms import TouchSensorMap
from gentlerl.transforms.sensor_map import isotonic_regression


def _sensor(force: np.ndarray) -> np.ndarray:
    """A saturating sensor, different per fingertip: raw = b + g log(1 + f / 2)."""
    b = np.array([2000.0, 2100.0, 1900.0, 2050.0, 1950.0])[:, None]
    g = np.array([400.0, 350.0, 450.0, 380.0, 420.0])[:, None]
    return b + g * np.log1p(force / 2.0)


@pytest.fixture(scope="module")
def fitted():
    rng = np.random.RandomState(0)
    force = np.concatenate([np.zeros((200, 5, 1)), rng.uniform(0, 10, size=(400, 5, 1))])
    raw = _sensor(force) + rng.normal(0, 2.0, size=force.shape)
    sensor_map = TouchSensorMap(n_knots=32)
    return sensor_map, sensor_map.fit(raw, force)


def test_isotonic_regression_pools_adjacent_violators():
    # [3, 2] violates the order: both become their mean 2.5.
    np.testing.assert_allclose(isotonic_regression([1.0, 3.0, 2.0, 4.0]), [1, 2.5, 2.5, 4])
    np.testing.assert_allclose(isotonic_regression([3.0, 2.0, 1.0]), [2, 2, 2])


def test_fit_recovers_the_sensor_curve(fitted):
    sensor_map, errors = fitted
    # Noise of 2 counts is ~0.01-0.2 N depending on the slope: the fit error stays that small.
    assert errors["rmse_pressed_N"] < 0.15 and errors["max_abs_error_N"] < 0.6
    force = np.array([0.0, 1.0, 5.0, 9.0])[:, None, None] * np.ones((1, 5, 1))
    got = sensor_map.forward_map(_sensor(force)).numpy()
    np.testing.assert_allclose(got, force, atol=0.15)


def test_map_is_monotone_and_extrapolates_upwards(fitted):
    sensor_map, _ = fitted
    raw = torch.linspace(1800, 3500, 400, dtype=torch.float64)[:, None, None].expand(-1, 5, 1)
    force = sensor_map.forward_map(raw)
    assert (force.diff(dim=0) >= 0).all() and (force >= 0).all()
    # Past the fitted range (10 N) the last segment's slope continues: more force, never less.
    assert (force[-1] > 10.5).all()


def test_inverse_round_trip(fitted):
    sensor_map, _ = fitted
    force = torch.tensor([0.5, 2.0, 4.0, 8.0], dtype=torch.float64)[:, None, None].expand(-1, 5, 1)
    back = sensor_map.forward_map(sensor_map.inverse(force))
    torch.testing.assert_close(back, force, atol=1e-4, rtol=0)


def test_tare_cancels_drift(fitted):
    sensor_map, _ = fitted
    force = np.full((1, 5, 1), 4.0)
    drift = 40.0  # counts: ~0.4 N at 4 N if left in
    offset = sensor_map.tare(_sensor(np.zeros((1, 5, 1))) + drift)
    drifted = sensor_map.forward_map(_sensor(force) + drift, offset).numpy()
    np.testing.assert_allclose(drifted, force, atol=0.15)
    assert (sensor_map.forward_map(_sensor(force) + drift).numpy() - 4.0 > 0.3).all()


def test_state_dict_and_file_round_trip(fitted, tmp_path):
    sensor_map, _ = fitted
    raw = torch.from_numpy(_sensor(np.full((3, 5, 1), 3.0)))
    copy = TouchSensorMap(n_knots=32)
    copy.load_state_dict(sensor_map.state_dict())
    torch.testing.assert_close(copy.forward_map(raw), sensor_map.forward_map(raw))
    sensor_map.save(tmp_path / "touch_sensor_map.pt")
    assert [p.name for p in tmp_path.iterdir()] == ["touch_sensor_map.pt"]  # no temp file left
    loaded = TouchSensorMap.load(tmp_path / "touch_sensor_map.pt")
    torch.testing.assert_close(loaded.forward_map(raw), sensor_map.forward_map(raw))
    with pytest.raises(RuntimeError, match="size mismatch"):
        TouchSensorMap(n_channels=3, n_knots=32).load_state_dict(sensor_map.state_dict())


def test_as_a_transform(fitted):
    sensor_map, _ = fitted
    raw = torch.from_numpy(_sensor(np.full((4, 5, 1), 5.0))).float()
    out = sensor_map(TensorDict({"tactile": raw}, [4]))
    assert out["tactile_force"].dtype == torch.float32
    torch.testing.assert_close(out["tactile_force"], torch.full((4, 5, 1), 5.0), atol=0.15, rtol=0)


def test_channels_it_was_not_fitted_on_raise(fitted):
    sensor_map, _ = fitted
    with pytest.raises(ValueError, match=r"fitted on 5 sites x 1 channels; raw has shape \(5, 3\)"):
        sensor_map.forward_map(torch.zeros(5, 3))
    with pytest.raises(ValueError, match="not fitted"):
        TouchSensorMap().forward_map(torch.zeros(5, 1))


def test_fit_rejects_an_unpressed_fingertip_and_bad_shapes():
    rng = np.random.RandomState(1)
    force = rng.uniform(0, 10, size=(100, 5, 1))
    force[:, 3] = 0.0  # the little finger never pressed
    with pytest.raises(ValueError, match="fingertip 3 channel 0: the reference force spans 0.00 N"):
        TouchSensorMap(n_knots=8).fit(_sensor(force), force)
    with pytest.raises(ValueError, match=r"shaped \[N, 5, 1\]"):
        TouchSensorMap(n_knots=8).fit(np.zeros((100, 5, 3)), np.zeros((100, 5, 3)))
    with pytest.raises(ValueError, match="at least 16 samples"):
        TouchSensorMap(n_knots=8).fit(np.zeros((10, 5, 1)), np.zeros((10, 5, 1)))
    with pytest.raises(ValueError, match="must be finite"):
        bad = _sensor(force)
        bad[0, 0, 0] = np.nan
        TouchSensorMap(n_knots=8).fit(bad, force)


def test_the_earlier_class_name_warns_and_is_the_new_one_and_other_names_still_fail():
    with pytest.warns(DeprecationWarning, match=r"^gentlerl.transforms.TouchCalibration is deprec"):
        from gentlerl.transforms import TouchCalibration
    assert TouchCalibration is TouchSensorMap
    with pytest.raises(AttributeError, match="has no attribute 'Nope'"):
        import gentlerl.transforms

        gentlerl.transforms.Nope  # noqa: B018

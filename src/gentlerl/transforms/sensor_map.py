"""``TouchSensorMap``: raw tactile channels (sensor units) -> the simulated ``touch`` range (N).

The paper's real hand reads the pressure channel of each BioTac and normalises it to the
simulated touch sensors' range, so that the task thresholds (5 N touch, 3 N impact) and the
algorithm run unchanged (Huang et al. 2019, "Tactile sensing"). Here the normalisation is a
monotone piecewise-linear map per fingertip and channel, fitted by isotonic regression on paired
samples (raw reading, reference force in N, e.g. from the force/torque sensor under the block).
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
import torch
from torchrl.data import Composite, Unbounded
from torchrl.envs.transforms import Transform

from gentlerl import keys
from gentlerl.files import open_checked

# Forces at or below this (N) count as "nothing touches" when the zero level is fitted.
ZERO_FORCE = 0.05
# Samples with at least this reference force (N) make the "pressed" fit error.
PRESSED_FORCE = 0.5
# A file asking for more knots than this (all channels together) is refused before allocating.
_MAX_KNOTS = 1_000_000
#: The largest sensor map file read (a hand's map is a few hundred KB).
MAX_SENSOR_MAP_BYTES = 64 << 20


def isotonic_regression(y: np.ndarray) -> np.ndarray:
    """The non-decreasing sequence closest to ``y`` in least squares (pool adjacent violators)."""
    means, weights, sizes = [], [], []
    for value in np.asarray(y, dtype=np.float64):
        means.append(value)
        weights.append(1.0)
        sizes.append(1)
        while len(means) > 1 and means[-2] > means[-1]:
            w = weights[-2] + weights[-1]
            means[-2] = (means[-2] * weights[-2] + means[-1] * weights[-1]) / w
            weights[-2] = w
            sizes[-2] += sizes[-1]
            del means[-1], weights[-1], sizes[-1]
    return np.repeat(means, sizes)


def fit_errors(error: np.ndarray, force: np.ndarray) -> dict[str, float]:
    """RMSE over all samples, over pressed ones (reference >= 0.5 N) and the largest error (N)."""
    pressed = error[force >= PRESSED_FORCE]
    return {
        "rmse_N": float(np.sqrt((error**2).mean())),
        "rmse_pressed_N": float(np.sqrt((pressed**2).mean())) if pressed.size else float("nan"),
        "max_abs_error_N": float(np.abs(error).max()),
    }


def _interp(x: torch.Tensor, xp: torch.Tensor, fp: torch.Tensor) -> torch.Tensor:
    """Piecewise-linear ``fp(xp)`` at ``x`` ``[N, S, C]``; knots ``[S, C, K]`` strictly increasing.

    Flat below the first knot, extrapolated with the last segment's slope above the last one (a
    saturating sensor read past its fitted range then reports more force, never less).
    """
    xs = x.permute(1, 2, 0).contiguous()  # [S, C, N]
    idx = torch.searchsorted(xp, xs).clamp(1, xp.shape[-1] - 1)
    x0, x1 = xp.gather(-1, idx - 1), xp.gather(-1, idx)
    y0, y1 = fp.gather(-1, idx - 1), fp.gather(-1, idx)
    t = ((xs - x0) / (x1 - x0)).clamp(min=0.0)
    return (y0 + t * (y1 - y0)).permute(2, 0, 1)


def _check_channel(s: int, c: int, x: np.ndarray, y: np.ndarray) -> None:
    """Refuse a dead channel (constant raw) or an inverted one (more force, lower reading)."""
    if float(x.max() - x.min()) <= 0.0:
        raise ValueError(f"fingertip {s} channel {c}: the raw reading is constant (dead channel)")
    if float(np.corrcoef(x, y)[0, 1]) <= 0.0:
        raise ValueError(
            f"fingertip {s} channel {c}: the raw reading falls as the reference force rises "
            "(inverted or miswired sensor)"
        )


class TouchSensorMap(Transform):
    """Maps raw tactile channels ``[..., n_sites, n_channels]`` to forces in N, channel by channel.

    Fit it once from paired samples (:meth:`fit`), save it with the run (``state_dict`` or
    :meth:`save` / :meth:`load`), then hand it to :class:`~gentlerl.envs.DriverHandEnv` (which
    maps every reading) or use it as a TorchRL transform on recorded data (reads
    ``in_keys``, writes ``out_keys``). :meth:`inverse` maps forces back to raw units for plots.

    Args:
        n_sites: fingertips (5: ff, mf, rf, lf, th).
        n_channels: raw channels per fingertip (1: a BioTac's pressure channel).
        n_knots: knots of each piecewise-linear map.
    """

    def __init__(
        self,
        n_sites: int = 5,
        n_channels: int = 1,
        n_knots: int = 32,
        *,
        in_keys: list[str] | None = None,
        out_keys: list[str] | None = None,
    ) -> None:
        for name, value, low in (("n_sites", n_sites, 1), ("n_channels", n_channels, 1)):
            if not (isinstance(value, int) and value >= low):
                raise ValueError(f"{name} must be an integer >= {low}, got {value!r}")
        if not (isinstance(n_knots, int) and n_knots >= 2):
            raise ValueError(f"n_knots must be an integer >= 2, got {n_knots!r}")
        super().__init__(
            in_keys=in_keys or [keys.TACTILE], out_keys=out_keys or [keys.TACTILE_FORCE]
        )
        self.shape = (n_sites, n_channels)
        self.register_buffer("raw_knots", torch.arange(n_knots).expand(*self.shape, -1).double())
        self.register_buffer("force_knots", torch.zeros(*self.shape, n_knots, dtype=torch.float64))
        self.register_buffer("raw_zero", torch.zeros(self.shape, dtype=torch.float64))
        self.register_buffer("fit_rmse", torch.full(self.shape, float("nan"), dtype=torch.float64))
        self.register_buffer("fitted", torch.zeros((), dtype=torch.bool))

    def _check(self, value: torch.Tensor | np.ndarray, name: str) -> torch.Tensor:
        value = torch.as_tensor(value, dtype=torch.float64)
        if value.ndim < 2 or tuple(value.shape[-2:]) != self.shape:
            raise ValueError(
                f"TouchSensorMap is fitted on {self.shape[0]} sites x {self.shape[1]} channels; "
                f"{name} has shape {tuple(value.shape)}, expected [..., {self.shape[0]}, "
                f"{self.shape[1]}]"
            )
        if not bool(self.fitted):
            raise ValueError("TouchSensorMap is not fitted: call fit(raw, force) or load it")
        return value

    @torch.no_grad()
    def fit(
        self,
        raw: np.ndarray | torch.Tensor,
        force: np.ndarray | torch.Tensor,
        min_span: float = 1.0,
    ) -> dict[str, float]:
        """Fit every channel's monotone map from paired samples.

        Args:
            raw: ``[N, n_sites, n_channels]`` raw readings.
            force: ``[N, n_sites, n_channels]`` reference forces (N) at the same instants.
            min_span: each channel's reference force must span at least this (N): a fingertip
                that was never pressed while fitting cannot be mapped.

        Returns:
            ``rmse_N`` (over every sample and channel), ``rmse_pressed_N`` (over samples with a
            reference force >= 0.5 N) and ``max_abs_error_N`` of the fitted map.
        """
        raw = np.asarray(raw, dtype=np.float64)
        force = np.asarray(force, dtype=np.float64)
        if raw.shape != force.shape or raw.ndim != 3 or raw.shape[1:] != self.shape:
            raise ValueError(
                f"fit needs raw and force shaped [N, {self.shape[0]}, {self.shape[1]}], got "
                f"{raw.shape} and {force.shape}"
            )
        if not (np.isfinite(raw).all() and np.isfinite(force).all()):
            raise ValueError("fit: raw and force must be finite")
        if not (isinstance(min_span, int | float) and min_span >= PRESSED_FORCE):
            raise ValueError(
                f"fit: min_span must be a number >= {PRESSED_FORCE} N, got {min_span!r}"
            )
        k = self.raw_knots.shape[-1]
        if raw.shape[0] < 2 * k:
            raise ValueError(f"fit needs at least {2 * k} samples (2 per knot), got {raw.shape[0]}")
        for s, c in np.ndindex(self.shape):
            x, y = raw[:, s, c], force[:, s, c]
            span = float(y.max() - y.min())
            if span < min_span:
                raise ValueError(
                    f"fingertip {s} channel {c}: the reference force spans "
                    f"{span:.2f} N, needs >= {min_span} N; press that fingertip while fitting"
                )
            _check_channel(s, c, x, y)
            order = np.argsort(x, kind="stable")
            x, y_fit = x[order], isotonic_regression(y[order])
            # Strictly increasing knots (a flat stretch maps to one raw value in the inverse).
            raw_knots = np.linspace(x[0], x[-1], k)
            force_knots = np.interp(raw_knots, x, y_fit) + np.arange(k) * 1e-6
            self.raw_knots[s, c] = torch.from_numpy(raw_knots)
            self.force_knots[s, c] = torch.from_numpy(force_knots)
            resting = x[y_fit <= ZERO_FORCE]
            self.raw_zero[s, c] = float(np.median(resting)) if resting.size else x[0]
        self.fitted.fill_(True)
        self.validate()
        error = self.forward_map(raw).numpy() - force
        self.fit_rmse.copy_(torch.from_numpy(np.sqrt((error**2).mean(0))))
        return fit_errors(error, force)

    @torch.no_grad()
    def forward_map(
        self, raw: torch.Tensor | np.ndarray, offset: torch.Tensor | np.ndarray | None = None
    ) -> torch.Tensor:
        """Forces (N, >= 0) of ``raw`` ``[..., n_sites, n_channels]``, float64.

        ``offset`` (same trailing shape, from :meth:`tare`) is subtracted first: it removes a
        sensor's baseline drift since the fit.
        """
        raw = self._check(raw, "raw")
        if not bool(torch.isfinite(raw).all()):
            raise ValueError("forward_map: raw readings must be finite (a sensor fault?)")
        if offset is not None:
            raw = raw - torch.as_tensor(offset, dtype=torch.float64)
        flat = raw.reshape(-1, *self.shape)
        return _interp(flat, self.raw_knots, self.force_knots).clamp(min=0.0).reshape(raw.shape)

    @torch.no_grad()
    def inverse(self, force: torch.Tensor | np.ndarray) -> torch.Tensor:
        """Raw readings that the fitted map sends to ``force`` (N) ``[..., n_sites, n_channels]``."""
        force = self._check(force, "force")
        flat = force.reshape(-1, *self.shape)
        return _interp(flat, self.force_knots, self.raw_knots).reshape(force.shape)

    def tare(self, raw_at_rest: torch.Tensor | np.ndarray) -> torch.Tensor:
        """The offset to pass to :meth:`forward_map`: ``raw_at_rest - raw_zero``.

        ``raw_at_rest``: readings ``[..., n_sites, n_channels]`` (averaged over leading dims)
        while nothing touches the fingertips, e.g. at the start of an episode.
        """
        raw = self._check(raw_at_rest, "raw_at_rest")
        return raw.reshape(-1, *self.shape).mean(0) - self.raw_zero

    # -- TorchRL transform -------------------------------------------------------------------
    def _apply_transform(self, raw: torch.Tensor) -> torch.Tensor:
        return self.forward_map(raw).to(torch.float32)

    def transform_observation_spec(self, observation_spec: Composite) -> Composite:
        for in_key, out_key in zip(self.in_keys, self.out_keys, strict=True):
            spec = observation_spec[in_key]
            observation_spec[out_key] = Unbounded(spec.shape, device=spec.device)
        return observation_spec

    # -- files ---------------------------------------------------------------------------------
    def save(self, path: str | Path) -> None:
        """Write sizes and fitted state to ``path`` atomically (temp file + rename)."""
        path = Path(path)
        tmp = path.with_name(path.name + ".tmp")
        n_knots = self.raw_knots.shape[-1]
        torch.save({"shape": self.shape, "n_knots": n_knots, "state": self.state_dict()}, tmp)
        os.replace(tmp, path)

    @classmethod
    def load(cls, path: str | Path) -> TouchSensorMap:
        """A sensor map written by :meth:`save` (also one of a ``TouchCalibration``, its earlier name:
        the file holds no class name)."""
        try:
            with open_checked(path, MAX_SENSOR_MAP_BYTES, binary=True) as f:
                blob = torch.load(f, weights_only=True)
            sizes = (*blob["shape"], blob["n_knots"])
            if len(sizes) != 3 or math.prod(sizes) > _MAX_KNOTS:
                raise ValueError(f"sites x channels x knots {sizes} is not a hand's sensor map")
            sensor_map = cls(*blob["shape"], n_knots=blob["n_knots"])
            sensor_map.load_state_dict(blob["state"])
        except FileNotFoundError:
            raise
        except Exception as err:  # noqa: BLE001 - truncated, empty, foreign: one clear error
            raise ValueError(
                f"{path} is not a TouchSensorMap file written by save() ({err})"
            ) from None
        if not bool(sensor_map.fitted):
            raise ValueError(f"{path}: the sensor map it holds was never fitted")
        try:
            sensor_map.validate()
        except ValueError as err:
            raise ValueError(f"{path}: {err}") from None
        return sensor_map

    def validate(self) -> None:
        """Refuse a map that cannot be trusted by a safety check: non-finite knots, raw knots not
        strictly increasing, forces decreasing, or a channel whose forces span < 0.5 N (dead,
        inverted or never pressed)."""
        raw, force = self.raw_knots, self.force_knots
        for s, c in np.ndindex(self.shape):
            where = f"fingertip {s} channel {c}"
            if not bool(torch.isfinite(raw[s, c]).all() & torch.isfinite(force[s, c]).all()):
                raise ValueError(f"{where}: sensor map knots must be finite")
            if not bool((raw[s, c].diff() > 0).all()):
                raise ValueError(f"{where}: raw knots must be strictly increasing")
            if not bool((force[s, c].diff() >= 0).all()):
                raise ValueError(f"{where}: force knots must not decrease (inverted sensor?)")
            span = float(force[s, c, -1] - force[s, c, 0])
            if span < PRESSED_FORCE:
                raise ValueError(
                    f"{where}: the map spans {span:.3g} N, needs >= {PRESSED_FORCE} N (a dead or "
                    "inverted sensor, or a fingertip never pressed while fitting)"
                )
        if not bool(torch.isfinite(self.raw_zero).all()):
            raise ValueError("sensor map raw_zero must be finite")

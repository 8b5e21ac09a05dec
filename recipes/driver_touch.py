"""The real-robot path on the simulated hand: fit the tactile sensor map, then learn ``touch``.

``python recipes/driver_touch.py --seed 0 --run-dir runs/driver_touch``

1. A scripted session presses each fingertip of a :class:`~gentlerl.envs.SimulatedDriver` (MuJoCo
   hand, BioTac-like raw sensors) and fits a :class:`~gentlerl.transforms.TouchSensorMap`; a
   second session measures its held-out error. The sensor map is saved in the run directory.
2. ``touch`` is trained with ``scale=real`` (the paper's real-robot preset) through
   :class:`~gentlerl.envs.DriverHandEnv` with a :class:`~gentlerl.envs.ForceWatchdog`, and (with
   ``--env both``, the default) with the same config on the plain simulated env, one after the
   other. ``results.json`` holds both runs' success and impacts, the fit error and the watchdog
   counts. On a real hand, replace the driver and the pressing session (docs/REAL_ROBOT.md).
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path
from typing import Any

import numpy as np

from gentlerl.envs import DriverHandEnv, ForceWatchdog, SimulatedDriver
from gentlerl.envs.hand import DEFAULT_REGIME, REGIMES
from gentlerl.envs.sim_driver import pressing_session
from gentlerl.training import make_config, train
from gentlerl.transforms import TouchSensorMap
from gentlerl.transforms.sensor_map import fit_errors

SENSOR_MAP_FILE = "touch_sensor_map.pt"


def fit_sensor_map(seed: int, run_dir: Path, hand: str) -> tuple[TouchSensorMap, dict[str, Any]]:
    """Fit on one scripted session, measure on another (other press rates), save the fit."""
    driver = SimulatedDriver(seed=seed, regime=hand)
    raw, force = pressing_session(driver, rates=(0.01, 0.02, 0.04))
    sensor_map = TouchSensorMap()
    fit = sensor_map.fit(raw, force)
    raw, force = pressing_session(driver, rates=(0.015, 0.03))
    held_out = fit_errors(sensor_map.forward_map(raw).numpy() - force, force)
    sensor_map.save(run_dir / SENSOR_MAP_FILE)
    per_tip = sensor_map.fit_rmse[:, 0].tolist()
    return sensor_map, {"fit": fit, "held_out": held_out, "fit_rmse_per_fingertip_N": per_tip}


def _episode_column(run_dir: Path, name: str) -> np.ndarray:
    path = run_dir / "logs" / "scalars" / "episode" / f"{name}.csv"
    if not path.is_file():
        return np.zeros(0)
    return np.loadtxt(path, delimiter=",", ndmin=2)[:, 1]


def summarize(run_dir: Path, final: dict[str, float]) -> dict[str, Any]:
    """Final evaluation plus the training episodes' success and per-episode max impact (N)."""
    impact, success = _episode_column(run_dir, "max_impact"), _episode_column(run_dir, "success")
    last = max(len(success) // 5, 1)
    return {
        "eval_final": final,
        "train_episodes": len(success),
        "train_success_rate": float(success.mean()) if len(success) else float("nan"),
        "train_success_rate_last_20pct": float(success[-last:].mean()) if len(success) else 0.0,
        "train_max_impact_median_N": float(np.median(impact)) if len(impact) else float("nan"),
        "train_max_impact_p95_N": float(np.percentile(impact, 95)) if len(impact) else float("nan"),
    }


def run(env: str, args: argparse.Namespace, sensor_map: TouchSensorMap | None) -> dict[str, Any]:
    """Train one run (``env`` is ``driver`` or ``sim``) and summarise it."""
    run_dir = Path(args.run_dir) / env
    collector = {"total_frames": args.total_frames} if args.total_frames else {}
    cfg = make_config(
        "real",
        task="touch",
        seed=args.seed,
        run_dir=str(run_dir),
        logging={"wandb_mode": "disabled", "progress": args.progress},
        collector=collector,
        env={"kwargs": {"regime": args.hand}},
    )
    watchdogs: list[ForceWatchdog] = []
    factory = None
    if env == "driver":

        def factory() -> DriverHandEnv:
            watchdogs.append(ForceWatchdog(args.fingertip_limit, args.block_limit))
            driver = SimulatedDriver(seed=args.seed, regime=args.hand)
            return DriverHandEnv(
                driver,
                "touch",
                sensor_map=sensor_map,
                watchdog=watchdogs[-1],
                action_scale=REGIMES[args.hand]["action_scale"],
            )

    result = summarize(run_dir, train(cfg, factory))
    if watchdogs:
        # One watchdog per env the trainer built (a probe, the collector's, the evaluation one).
        counts = [w.counts() for w in watchdogs]
        result["watchdog_per_env"] = counts
        result["watchdog_total"] = {k: sum(c[k] for c in counts) for k in counts[0]}
    return result


def main(argv: list[str] | None = None) -> dict[str, Any]:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--run-dir", default="runs/driver_touch")
    parser.add_argument("--env", choices=("driver", "sim", "both"), default="both")
    parser.add_argument("--total-frames", type=int, default=None, help="default: scale=real's")
    parser.add_argument("--fingertip-limit", type=float, default=10.0, help="watchdog, N")
    parser.add_argument("--block-limit", type=float, default=15.0, help="watchdog, N")
    parser.add_argument(
        "--hand",
        choices=sorted(REGIMES),
        default=DEFAULT_REGIME,
        help="the simulated hand's physics regime (gentlerl.envs.hand.REGIMES), both runs",
    )
    parser.add_argument("--progress", action="store_true", help="show a progress bar")
    args = parser.parse_args(argv)
    run_dir = Path(args.run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)
    results: dict[str, Any] = {"seed": args.seed, "scale": "real"}
    sensor_map = None
    if args.env in ("driver", "both"):
        sensor_map, results["sensor_map"] = fit_sensor_map(args.seed, run_dir, args.hand)
    for env in ("driver", "sim") if args.env == "both" else (args.env,):
        results[env] = run(env, args, sensor_map)
    tmp = run_dir / "results.json.tmp"
    tmp.write_text(json.dumps(results, indent=2) + "\n")
    os.replace(tmp, run_dir / "results.json")
    print(json.dumps(results, indent=2))
    return results


if __name__ == "__main__":
    main()

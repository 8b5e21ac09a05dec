"""The Ray backend of `gentlerl sweep`: each grid point is one Ray task running the recipe on some
node.

The task calls :func:`gentlerl.apps.grid.run_point` on the node that runs it, so resuming is the
local runner's: ``DONE`` runs are skipped before submitting, a run with a checkpoint continues
from it (also when Ray retries a task whose node died). Run directories are written under
``--out`` by the nodes themselves: on a multi-node cluster ``--out`` must be a filesystem that
every node mounts at the same path (NFS, ...), where :mod:`gentlerl.analysis.runs` then reads them.
"""

from __future__ import annotations

import socket
from collections.abc import Sequence

from gentlerl.apps.grid import GridRun, pending, run_point
from gentlerl.distributed.cluster import ClusterError, connect


def _run_on_node(run: GridRun, extra: Sequence[str]) -> int:
    """Body of the Ray task: one grid point on this node (its run folder must be shared)."""
    if not run.run_dir.parent.is_dir():
        raise ClusterError(
            f"{run.run_dir.parent} does not exist on node {socket.gethostname()}: --out must be "
            "on a filesystem shared by every node at the same path"
        )
    return run_point(run, extra)


def run_grid_on_ray(
    runs: Sequence[GridRun],
    extra: Sequence[str] = (),
    address: str | None = None,
    cpus_per_run: float = 1.0,
    num_cpus: int | None = None,
) -> dict[str, int]:
    """Run the grid's unfinished points as Ray tasks; counts ``done``/``skipped``/``failed``.

    ``address`` None starts a local Ray with ``num_cpus`` CPUs; otherwise see
    :func:`gentlerl.distributed.connect`. Each task reserves ``cpus_per_run`` CPUs, so Ray runs
    as many at a time as the cluster's CPUs allow. Nothing is written before Ray is reachable.
    """
    if cpus_per_run <= 0:
        raise ValueError(f"cpus_per_run={cpus_per_run} must be > 0")
    todo = pending(runs)
    counts = {"skipped": len(runs) - len(todo), "done": 0, "failed": 0, "planned": 0}
    if not todo:
        return counts
    with connect(address, num_cpus=num_cpus) as ray:
        for folder in {run.run_dir.parent for run in todo}:
            folder.mkdir(parents=True, exist_ok=True)
        task = ray.remote(_run_on_node).options(num_cpus=cpus_per_run)
        refs = {task.remote(run, list(extra)): run for run in todo}
        try:
            while refs:
                ready, _ = ray.wait(list(refs), num_returns=1)
                run = refs.pop(ready[0])
                code = _result(ray, ready[0], run)
                counts["done" if code == 0 else "failed"] += 1
                print(
                    f"[{sum(counts.values())}/{len(runs)}] exit {code}: {run.run_dir}", flush=True
                )
        finally:
            for ref in refs:  # interrupted: stop the runs still going (they resume next time)
                ray.cancel(ref)
    return counts


def _result(ray: object, ref: object, run: GridRun) -> int:
    """The task's exit code; a task that raised prints its error (and counts as failed)."""
    try:
        return ray.get(ref)
    except Exception as err:  # noqa: BLE001 - any task failure is one failed run, reported
        print(f"{run.run_dir}: {err}", flush=True)
        return -1

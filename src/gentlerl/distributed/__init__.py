"""Running gentlerl on Ray: joining or starting a cluster, remote collectors (sweeps as Ray tasks:
:mod:`gentlerl.apps.grid_ray`).

Ray is an optional extra (``pip install -e '.[ray]'``); nothing here imports it at module level.
"""

from gentlerl.distributed.cluster import RAY_EXTRA, ClusterError, connect, import_ray

__all__ = ["RAY_EXTRA", "ClusterError", "connect", "import_ray"]

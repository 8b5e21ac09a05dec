"""Start a local Ray or join a cluster, with clear errors instead of hangs.

``ray.init`` on an address that does not answer retries for minutes; a plain TCP connection
with a timeout tells within seconds whether anything listens there.
"""

from __future__ import annotations

import ipaddress
import re
import socket
from collections.abc import Iterator
from contextlib import contextmanager
from types import ModuleType
from typing import Any

#: The one line printed when Ray is missing.
RAY_EXTRA = "ray is not installed; install gentlerl's ray extra: pip install -e '.[ray]'"
#: Seconds the TCP probe of a cluster address waits.
CONNECT_TIMEOUT_S = 10.0
#: Ray's ports when an address names none: the client server (ray://) and the GCS.
_DEFAULT_PORTS = {"ray://": 10001, "": 6379}
_EXPECTED = "'auto', 'host:port' or 'ray://host:port'"
#: A DNS host name: dot-separated labels of letters, digits and inner hyphens.
_HOST = re.compile(r"(?!-)[A-Za-z0-9-]{1,63}(?<!-)(\.(?!-)[A-Za-z0-9-]{1,63}(?<!-))*")


class ClusterError(RuntimeError):
    """Ray is missing or the cluster cannot be reached; the message says which and what to do."""


def import_ray() -> ModuleType:
    """``import ray``, or :class:`ClusterError` naming the extra to install."""
    try:
        import ray
    except ImportError as err:
        raise ClusterError(RAY_EXTRA) from err
    return ray


def parse_address(address: str) -> tuple[str, int]:
    """``ray://host:port`` or ``host:port`` -> (host, port) (a missing port is Ray's default);
    the host a name, an IPv4 address or a bracketed IPv6 one (``[::1]:6379``), the port in
    ``[1, 65535]``. Anything else is a ``ValueError`` saying what is wrong with ``address``."""
    scheme = "ray://" if address.startswith("ray://") else ""
    hostport = address[len(scheme) :]
    if "://" in hostport or "/" in hostport:
        raise ValueError(f"{address!r} is not {_EXPECTED} (no other scheme, no path)")
    if hostport.startswith("["):  # [IPv6]:port
        host, _, rest = hostport[1:].partition("]")
        if rest and not rest.startswith(":"):
            raise ValueError(f"{address!r} is not {_EXPECTED}")
        port = rest[1:]
        valid_host = _is_ip(host, ipaddress.IPv6Address)
    else:
        host, sep, port = hostport.rpartition(":")
        host, port = (host, port) if sep else (hostport, "")
        numeric = re.fullmatch(r"[0-9.]+", host) is not None
        valid_host = _is_ip(host, ipaddress.IPv4Address) if numeric else bool(_HOST.fullmatch(host))
    if not valid_host:
        alone = "; a port alone is not an address" if host.isdigit() else ""
        raise ValueError(
            f"{address!r}: {host!r} is not a host name or an IP address ({_EXPECTED}{alone})"
        )
    if not port:
        return host, _DEFAULT_PORTS[scheme]
    if not re.fullmatch(r"[0-9]{1,5}", port) or not 1 <= int(port) <= 65535:
        raise ValueError(f"{address!r}: port {port!r} is not a number in [1, 65535]")
    return host, int(port)


def _is_ip(text: str, kind: type) -> bool:
    try:
        kind(text)
    except ValueError:
        return False
    return True


def check_reachable(address: str, timeout: float = CONNECT_TIMEOUT_S) -> None:
    """Raise :class:`ClusterError` unless something accepts TCP connections at ``address``."""
    host, port = parse_address(address)
    try:
        socket.create_connection((host, port), timeout=timeout).close()
    except OSError as err:
        raise ClusterError(
            f"cannot reach the Ray cluster at {address!r} ({host}:{port}: {err}); start one with "
            "`ray start --head` and pass its address"
        ) from err


def preflight(address: str | None) -> ModuleType:
    """Ray, after checking that ``address`` answers (unless Ray already runs in this process)."""
    ray = import_ray()
    if not ray.is_initialized() and address not in (None, "auto"):
        check_reachable(address)
    return ray


def join_cluster(address: str | None) -> None:
    """Before a run writes anything: ``preflight``, then, for a cluster ``address`` (not None),
    ``ray.init`` on it now, so an address that answers TCP but holds no Ray (or ``"auto"`` with
    none started) fails before the run directory is touched. The collector reuses this
    connection; a local Ray (``None``) is left for the collector to start and stop."""
    ray = preflight(address)
    if address is None or ray.is_initialized():
        return
    try:
        ray.init(**ray_init_config(address))
    except ConnectionError as err:
        raise no_cluster(address, err) from err


def no_cluster(address: str | None, err: Exception) -> ClusterError:
    """The error for ``ray.init`` finding no cluster (``address="auto"`` with none running)."""
    return ClusterError(
        f"no Ray cluster found for address={address!r} ({err}); start one with `ray start --head`"
    )


def ray_init_config(address: str | None, num_cpus: float | None = None) -> dict[str, Any]:
    """``ray.init`` arguments: a new local Ray with ``num_cpus`` CPUs, or join ``address``.

    Worker output stays in Ray's logs (``/tmp/ray/session_latest/logs``); errors reach the
    caller as exceptions carrying the worker's traceback.
    """
    common = {"include_dashboard": False, "log_to_driver": False}
    if address is None:
        # "local": a new Ray even when a `ray start` cluster runs here (that one needs "auto").
        return {"address": "local", "num_cpus": num_cpus, **common}
    return {"address": address, **common}


@contextmanager
def connect(
    address: str | None = None, num_cpus: int | None = None, **init_kwargs: Any
) -> Iterator[ModuleType]:
    """Ray, initialised for the ``with`` block: joined at ``address`` or started locally.

    ``address`` None starts a local Ray with ``num_cpus`` CPUs (all of them if None); ``"auto"``
    joins the cluster started on this machine by ``ray start``; ``host:port`` or
    ``ray://host:port`` joins a remote one (checked within :data:`CONNECT_TIMEOUT_S`). A Ray
    already initialised in this process is reused and left running. A Ray this call started or
    joined is shut down (disconnected) on exit, so a local one leaves no processes behind.
    """
    ray = preflight(address)
    if ray.is_initialized():
        yield ray
        return
    try:
        ray.init(**{**ray_init_config(address, num_cpus), **init_kwargs})
    except ConnectionError as err:
        raise no_cluster(address, err) from err
    try:
        yield ray
    finally:
        ray.shutdown()

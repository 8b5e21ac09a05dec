"""Ray addresses: parsed, probed and refused in one line; a Ray run without a cluster writes nothing."""

from __future__ import annotations

import re

import pytest


def test_a_ray_run_without_a_cluster_writes_nothing(tmp_path, monkeypatch):
    pytest.importorskip("ray")
    from gentlerl.distributed import ClusterError
    from gentlerl.training.config import make_config
    from gentlerl.training.loop import train

    monkeypatch.delenv("RAY_ADDRESS", raising=False)
    cfg = make_config(
        run_dir=str(tmp_path / "run"), collector={"kind": "ray", "ray_address": "auto"}
    )
    with pytest.raises(ClusterError, match="no Ray cluster found"):
        train(cfg)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("address", "match"),
    [
        ("127.0.0.1:99999", r"port '99999' is not a number in \[1, 65535\]"),
        ("127.0.0.1:²", r"port '²' is not a number in \[1, 65535\]"),
        ("http://127.0.0.1:1", "no other scheme"),
        ("6379", "'6379' is not a host name or an IP address.*a port alone is not an address"),
        ("999.1.1.1:2", "'999.1.1.1' is not a host name or an IP address"),
    ],
)
def test_ray_addresses_that_are_not_addresses_are_refused_by_the_config(address, match):
    from gentlerl.training.config import make_config

    with pytest.raises(ValueError, match=f"collector.ray_address='{re.escape(address)}'.*{match}"):
        make_config(collector={"kind": "ray", "ray_address": address})


def test_a_bracketed_ipv6_ray_address_is_parsed_and_probed():
    from gentlerl.distributed.cluster import ClusterError, check_reachable, parse_address

    assert parse_address("[::1]:1") == ("::1", 1)
    assert parse_address("ray://head.example") == ("head.example", 10001)
    with pytest.raises(ClusterError, match=r"cannot reach the Ray cluster at '\[::1\]:1'"):
        check_reachable("[::1]:1", timeout=2.0)


def test_a_ray_address_without_the_ray_collector_is_refused():
    from gentlerl.training.config import make_config

    with pytest.raises(ValueError, match="collector.ray_address='127.0.0.1:6379' applies to "):
        make_config(collector={"ray_address": "127.0.0.1:6379"})

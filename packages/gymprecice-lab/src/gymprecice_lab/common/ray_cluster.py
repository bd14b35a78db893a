"""A Ray cluster a command will use, checked before it writes anything.

``--ray auto|ADDRESS`` sends work to a cluster (``train``'s envs, ``benchmark``'s seeds,
evaluations and sweep, ``tune``'s workers). A cluster that is missing, does not answer,
or has no node with the CPUs one piece of the work needs would otherwise show up minutes
later, or never (Ray queues a task no node can hold for ever), so each command checks it
first and refuses in one line.
"""

from __future__ import annotations

from collections.abc import Sequence

from gymprecice_lab.common.command_runs import CommandFailed

__all__ = ["check_ray", "largest_node_cpus", "too_large"]


def largest_node_cpus() -> float:
    """CPUs of the alive node with the most (Ray must be initialised)."""
    import ray

    return max(
        (float(n.get("Resources", {}).get("CPU", 0)) for n in ray.nodes() if n.get("Alive")),
        default=0.0,
    )


def too_large(needs: Sequence[tuple[str, float]], cpus: float) -> str | None:
    """Why one of ``needs`` (what, CPUs on one node) cannot run on a cluster whose largest
    node has ``cpus`` CPUs; ``None`` when every one fits."""
    for what, wanted in needs:
        if wanted > cpus:
            return (
                f"{what} needs {wanted:g} CPUs on one node, but the cluster's largest node "
                f"has {cpus:g}; add a larger node, or lower --workers"
            )
    return None


def check_ray(address: str, needs: Sequence[tuple[str, float]], command: str = "benchmark") -> None:
    """Refuse ``--ray`` before anything trains when Ray is missing, no cluster answers, or
    no node has the CPUs one of ``needs`` (what, CPUs on one node) asks for: one line
    ``gymprecice COMMAND: ...`` and exit status 2 (:class:`CommandFailed`)."""
    try:
        import ray
    except ImportError:
        raise CommandFailed(
            command,
            "--ray needs Ray on this machine and every node: pip install "
            "'gymprecice-core[ray]' (see docs/cluster.md)",
        ) from None
    host, _, port = address.rpartition(":")
    try:
        if host and port.isdigit():  # a head's address: ray.init would retry it for minutes
            import socket

            socket.create_connection((host, int(port)), timeout=5).close()
        ray.init(address=address, log_to_driver=False)
    except (OSError, RuntimeError, ValueError) as exc:  # ConnectionError is an OSError
        raise CommandFailed(
            command,
            f"--ray {address}: no Ray cluster answers there "
            f"({getattr(exc, 'strerror', None) or exc}); start one (ray start --head, see "
            "docs/cluster.md) or pass its head's address",
        ) from None
    else:
        reason = too_large(needs, largest_node_cpus())
        if reason:
            raise CommandFailed(command, f"--ray {address}: {reason}")
    finally:
        if ray.is_initialized():
            ray.shutdown()

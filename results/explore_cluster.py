"""The Dask side of a design study: a local cluster started and stopped as a whole, or a running scheduler.

Every worker runs with one BLAS thread (:data:`WORKER_ENV`), so a study's numbers do not depend on
the cluster's layout. A remote scheduler is asked for its identity under one deadline before a
client connects (:func:`connect`); a local cluster starts and stops with the terminal's signals
held (:func:`signals_held_for_dask`), so Ctrl-C ends a study with one line.
"""

from __future__ import annotations

import contextlib
import logging
import re
import signal
import threading
from typing import Any

from rpud_common import ParameterError

log = logging.getLogger(__name__)

__all__ = ["WORKER_ENV", "WORKER_LOG_LEVEL", "SCHEDULER_TIMEOUT_S", "check_scheduler_address", "connect",
           "signals_held_for_dask", "local_cluster", "close_cluster"]

WORKER_ENV = {"OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1",
              "NUMBA_NUM_THREADS": "1", "MKL_CBWR": "COMPATIBLE"}
"""Environment of every worker process: one thread each, so numbers do not depend on the layout."""

WORKER_LOG_LEVEL = logging.CRITICAL
"""Log level of the worker processes, whose lines reach the terminal directly. A task's error
comes back to this process as its future's exception and a lost worker is logged by the
scheduler here; what workers log besides is the noise of a cluster shutting down (heartbeats
to a scheduler that already closed, with tracebacks)."""

SCHEDULER_TIMEOUT_S = 10.0
"""Bound of the whole connection to ``--scheduler``: TCP connect, handshake and first answer, s."""

_HOST = re.compile(r"[A-Za-z0-9]([A-Za-z0-9.-]{0,252})?\Z|\[[0-9A-Fa-f:.]{2,45}\]\Z")


def check_scheduler_address(address: Any) -> str:
    """``tcp://host:port`` (or ``host:port``): the one protocol a Client needs no setup for.

    ``tls://`` needs certificates (a ``Security`` object) and ``ucx://`` a UCX build, neither of
    which this command takes; ``inproc://`` only reaches a scheduler in the same process.
    """
    where = "--scheduler"
    if not isinstance(address, str) or not address.strip() or len(address) > 300 or not address.isprintable():
        raise ParameterError(where, address, "give the address of a running Dask scheduler, tcp://host:port")
    text = address.strip()
    scheme, sep, loc = text.partition("://")
    if not sep:
        scheme, loc = "tcp", text
    if scheme != "tcp":
        raise ParameterError(where, address, f"the {scheme!r} protocol is not supported here: give tcp://host:port")
    host, colon, port = loc.rpartition(":")
    if not colon or not _HOST.match(host) or not port.isdigit() or not 1 <= int(port) <= 65535:
        raise ParameterError(where, address, "give tcp://host:port, a host name or IP address and a port 1-65535")
    return f"tcp://{loc}"


def _probe(address: str, timeout_s: float) -> Any:
    """The scheduler's identity, asked with one deadline over connect, handshake and answer.

    Dask's own connect timeout ends with the TCP connection: a peer that accepts it and never
    answers the handshake would hold the Client forever.
    """
    import asyncio

    from distributed.comm import connect

    async def ask():
        comm = await connect(address, timeout=timeout_s)
        try:
            await comm.write({"op": "identity", "reply": True})
            return await comm.read()
        finally:
            comm.abort()

    return asyncio.run(asyncio.wait_for(ask(), timeout_s))


def connect(address: str, timeout_s: float | None = None):
    """A client of the scheduler at ``address`` with at least one worker, or a ParameterError."""
    from dask.distributed import Client

    timeout_s = SCHEDULER_TIMEOUT_S if timeout_s is None else timeout_s
    address = check_scheduler_address(address)
    why = f"no Dask scheduler answered there within {timeout_s:g} s"
    try:
        info = _probe(address, timeout_s)
    # whatever a peer sends back (garbage, a closed stream) means it is no usable scheduler
    except Exception as exc:  # noqa: BLE001
        raise ParameterError("--scheduler", address, f"{why} ({type(exc).__name__}); give the tcp://host:port "
                                                     "of a running scheduler") from None
    if not isinstance(info, dict) or info.get("type") != "Scheduler":
        raise ParameterError("--scheduler", address, "answers, but not as a Dask scheduler")
    if not info.get("workers"):
        raise ParameterError("--scheduler", address, "the scheduler has no workers: start some "
                                                     f"(dask worker {address}) first")
    try:
        return Client(address, timeout=timeout_s)
    except (ValueError, OSError, TimeoutError) as exc:
        raise ParameterError("--scheduler", address, f"{why} ({type(exc).__name__})") from None


# ------------------------------------------------------------------------------- driver


@contextlib.contextmanager
def signals_held_for_dask(insist: bool = True):
    """Start or stop a local cluster as a whole, and start its workers deaf to SIGINT.

    SIGINT/SIGTERM received meanwhile are recorded and re-delivered to the previous handlers
    when the block ends: raised inside Dask's start-up or shut-down they would leave a half
    started cluster, which Dask's exit hook then fails to close with a traceback. With
    ``insist``, a second signal is delivered at once, so a start-up that hangs can still be
    stopped (by a second SIGTERM: a SIGINT held by the mask below counts once).

    SIGINT is also blocked in the threads Dask starts meanwhile, and through them in the
    worker processes (threads and processes inherit the signal mask): a terminal's Ctrl-C
    reaches the whole process group, and only this process should answer it, by stopping the
    cluster and reporting one line, not every worker with a traceback.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    from multiprocessing import resource_tracker

    # multiprocessing starts its resource tracker on the first spawn and then *unblocks* SIGINT
    # in the spawning thread (rather than restoring its mask): start it before the block
    resource_tracker.ensure_running()
    got: list[int] = []
    previous: dict[int, Any] = {}

    def restore() -> None:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        previous.clear()

    def hold(signum, frame):
        got.append(signum)
        if insist and len(got) > 1:
            handler = previous.get(signum)
            restore()
            _deliver(signum, handler)

    for sig in (signal.SIGINT, signal.SIGTERM):
        if signal.getsignal(sig) not in (signal.SIG_IGN, None):
            previous[sig] = signal.signal(sig, hold)
    mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)     # a held SIGINT arrives here, in hold()
        handlers = dict(previous)
        restore()
        if got and handlers:
            _deliver(got[-1], handlers.get(got[-1]))


def _deliver(signum: int, handler) -> None:
    """Run a signal's handler as the signal would have (a default action through the kernel)."""
    if callable(handler):
        handler(signum, None)
    else:
        signal.raise_signal(signum)


def local_cluster(n: int):
    from dask.distributed import Client, LocalCluster

    cluster = client = None
    try:
        with signals_held_for_dask():
            # the scheduler's HTTP server on a free local port: two studies at once do not compete for 8787
            cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None,
                                   env=WORKER_ENV, silence_logs=WORKER_LOG_LEVEL,
                                   scheduler_kwargs={"dashboard_address": "127.0.0.1:0"})
            client = Client(cluster)
    except BaseException:
        close_cluster(client, cluster)
        raise
    return cluster, client


def close_cluster(client, cluster) -> None:
    with signals_held_for_dask(insist=False):
        if client is not None:
            client.close()
        if cluster is not None:
            cluster.close()


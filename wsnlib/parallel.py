"""Independent jobs in parallel: local processes (joblib's loky) or a Dask cluster.

A sweep (e.g. the tuning of :func:`wsnlib.studies.loss_tolerance.evaluate`) is a list of
independent jobs, each one call of a module-level function on picklable arguments.
:func:`run_jobs` runs them and returns their results **in the jobs' order**, so what a sweep
computes never depends on where, on how many processes or in which order its jobs ran:

* ``n_jobs=1``: one after the other in this process (no pickling; easiest to debug);
* ``n_jobs=N`` or ``-1`` (one per core): local worker processes (joblib's default backend,
  loky), which joblib starts with their inner thread pools (BLAS, numba's ``prange``) cut
  to cores / N, so N processes do not oversubscribe the machine;
* ``scheduler="tcp://host:8786"`` (or a ``distributed.Client``): the workers of a running Dask
  cluster (joblib's ``dask`` backend); large arguments such as a recording are scattered to
  the workers once, not once per job.  Start one with ``dask scheduler`` and ``dask worker
  tcp://host:8786`` on each machine, each with this project's environment (``environment.lock``)
  and the data folders the jobs read.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable

import joblib

__all__ = ["CONNECT_TIMEOUT_S", "connect", "local_workers", "run_jobs"]

#: How long to wait for a Dask scheduler to answer (s).
CONNECT_TIMEOUT_S = 10


def _check_n_jobs(n_jobs) -> int:
    if isinstance(n_jobs, bool) or not isinstance(n_jobs, int) or not (n_jobs >= 1 or n_jobs == -1):
        raise ValueError(f"n_jobs must be a positive integer or -1 (one process per core), got {n_jobs!r}")
    return n_jobs


def local_workers(n_jobs: int) -> int:
    """How many local processes :func:`run_jobs` uses for ``n_jobs`` (-1: one per core, as joblib counts
    them: the cores this process may use)."""
    n_jobs = _check_n_jobs(n_jobs)
    return joblib.cpu_count() if n_jobs == -1 else n_jobs


def connect(address: str):
    """A ``distributed.Client`` of the Dask scheduler at ``address`` (``"tcp://host:8786"``).

    Raises
    ------
    ValueError
        ``address`` is not a scheduler address, or no scheduler answers there within
        :data:`CONNECT_TIMEOUT_S`.
    """
    from distributed import Client
    from distributed.comm.addressing import parse_address, parse_host_port

    try:  # checked before a Client exists: a half-made one hangs at exit
        parse_host_port(parse_address(address)[1])
    except (TypeError, ValueError) as exc:
        raise ValueError(f"scheduler must be a Dask scheduler address such as 'tcp://host:8786' or a "
                         f"distributed.Client, got {address!r}") from exc
    try:
        return Client(address, set_as_default=False, timeout=f"{CONNECT_TIMEOUT_S}s")
    except OSError as exc:
        raise ValueError(f"no Dask scheduler answers at {address!r}: {exc}") from exc


def _client(scheduler):
    """``(client, ours)``: a ``distributed.Client`` for ``scheduler`` and whether we opened it."""
    from distributed import Client

    if isinstance(scheduler, Client):
        return scheduler, False
    return connect(scheduler), True


def run_jobs(function: Callable, jobs: Iterable[tuple], *, n_jobs: int = -1, scheduler=None,
             in_process_first: int = 0, progress: bool = False, desc: str = "jobs") -> list:
    """``[function(*job) for job in jobs]``, run in parallel, results in the jobs' order.

    Parameters
    ----------
    function : callable
        A module-level function (it is pickled to the workers).
    jobs : iterable of tuple
        The positional arguments of each call.
    n_jobs : int
        Local worker processes: ``-1`` (default) one per core, ``1`` none (in this process).
        Ignored with ``scheduler`` (the cluster's workers run the jobs).
    scheduler : str or distributed.Client, optional
        Address of a Dask scheduler (``"tcp://host:8786"``) or a client connected to one.
    in_process_first : int
        Run this many jobs in this process before handing the others out, e.g. one per
        method, so that numba compiles each kernel once and writes it to its on-disk cache,
        where the local workers then load it instead of each compiling it again.
    progress : bool
        Show a tqdm progress bar over the finished jobs.
    desc : str
        The progress bar's label.

    Returns
    -------
    list
        One result per job, in order.

    Raises
    ------
    ValueError
        A bad ``n_jobs``, a ``scheduler`` that is neither an address nor a client, or an address
        where no scheduler answers.
    """
    jobs = [tuple(job) for job in jobs]
    n_jobs = _check_n_jobs(n_jobs)
    if isinstance(in_process_first, bool) or not isinstance(in_process_first, int) or in_process_first < 0:
        raise ValueError(f"in_process_first must be a non-negative integer, got {in_process_first!r}")
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=len(jobs), desc=desc)
    local = scheduler is None and n_jobs == 1
    results = []
    for job in jobs if local else jobs[:in_process_first]:
        results.append(function(*job))
        if bar is not None:
            bar.update()
    rest = jobs[len(results):]
    if rest:
        client, ours = (None, False) if scheduler is None else _client(scheduler)
        # max_nbytes=None: arrays are pickled, never memory-mapped read-only (numba would compile
        # its kernels again for read-only arrays).
        config = ({"backend": "loky", "max_nbytes": None} if client is None
                  else {"backend": "dask", "client": client})
        try:
            with joblib.parallel_config(**config):
                for result in joblib.Parallel(n_jobs=n_jobs if client is None else -1, return_as="generator")(
                        joblib.delayed(function)(*job) for job in rest):
                    results.append(result)
                    if bar is not None:
                        bar.update()
        finally:
            if ours:
                client.close()
    if bar is not None:
        bar.close()
    return results

# SPDX-License-Identifier: Apache-2.0
# SPDX-FileCopyrightText: 2026 ds3d authors
"""Where the tasks of ds3d-bench run: in this process (--jobs 1), a local process pool, or a Dask
distributed cluster (--scheduler tcp://HOST:PORT). Each yields (index, result) as tasks finish."""
import concurrent.futures as cf
import multiprocessing


class ExecutorError(RuntimeError):
    """The cluster or pool could not be used (names the scheduler address and the reason)."""


def _failed(item, exc):
    return {"__error__": f"{type(exc).__name__}: {exc}", "item": item}


def run_local(fn, items, jobs):
    """fn over items in `jobs` processes (spawned, so no thread state is forked); jobs 1 runs here."""
    if jobs <= 1 or len(items) <= 1:
        for i, item in enumerate(items):
            try:
                yield i, fn(item)
            except Exception as e:  # noqa: BLE001
                yield i, _failed(item, e)
        return
    ctx = multiprocessing.get_context("spawn")
    with cf.ProcessPoolExecutor(max_workers=min(jobs, len(items)), mp_context=ctx) as pool:
        futs = {pool.submit(fn, item): i for i, item in enumerate(items)}
        for fut in cf.as_completed(futs):
            i = futs[fut]
            try:
                yield i, fut.result()
            except Exception as e:  # noqa: BLE001  (a worker died: that task only)
                yield i, _failed(items[i], e)


class DaskRunner:
    """A connection to a Dask scheduler; run() maps fn over items on its workers (one task per
    item, no retries: a task that kills its worker is reported and the others go on)."""

    def __init__(self, address, timeout=30):
        try:
            from distributed import Client
        except ImportError as e:
            raise ExecutorError("ds3d-bench: --scheduler needs Dask distributed "
                                "(apt-get install python3-distributed)") from e
        try:
            self.client = Client(address, timeout=timeout)
        except Exception as e:  # noqa: BLE001
            raise ExecutorError(f"ds3d-bench: --scheduler {address}: cannot connect ({e})") from e

    def workers(self):
        return len(self.client.scheduler_info().get("workers", {}))

    def run(self, fn, items):
        from distributed import as_completed

        if not items:
            return
        futs = self.client.map(fn, items, pure=False, retries=0)
        index = {f.key: i for i, f in enumerate(futs)}
        for fut in as_completed(futs):
            i = index[fut.key]
            try:
                yield i, fut.result()
            except Exception as e:  # noqa: BLE001
                yield i, _failed(items[i], e)
            fut.release()

    def close(self):
        self.client.close()

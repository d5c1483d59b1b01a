"""Where a comparison's runs run, and :func:`sweep`, which hands them out.

Three executors, one interface (:class:`Executor`: ``submit(fn, job)``
returns a ``concurrent.futures.Future``; ``slots`` runs at once;
``machine()`` is the record's machine line):

- :class:`InProcess`: one run after another in this process (the
  default);
- :class:`Processes`: N worker processes on this machine (``--jobs N``),
  e.g. one per core with one torch thread each, or several runs sharing
  one GPU;
- :class:`RayTasks`: Ray tasks with their own CPUs and GPUs on a Ray
  cluster, or on a local Ray this machine starts (``--executor ray``;
  Ray is the serving extra's engine, ``requirements/serve.txt``).

One comparison plans its runs once (:func:`cbnet_lab.plan.plan_jobs`) and
each run writes only its own folder (:mod:`cbnet_lab.run_files`), so no
run is locked: :func:`sweep` starts each run once, a test-time variant
after the run whose weights it tests. A sweep that is killed goes on where
it stopped when it is started again: finished runs are read back from
their ``result.json``, a run cut short resumes from its last checkpoint.
One sweep per work dir: two sweeps of the same runs at once would train
them twice, into the same folders.
"""
import concurrent.futures as cf
import math
import multiprocessing
import os
import os.path as osp
import sys
import time
from typing import Callable, Dict, List, Optional, Sequence, Tuple

from mmengine.device import get_device

from .plan import Job
from .report import machine_line
from .run import execute
from .run_files import read_result


class Executor:
    """Where runs run: ``submit(fn, job)`` starts ``fn(job)`` and returns a
    ``concurrent.futures.Future`` of its result; ``slots`` runs at once;
    a context manager (``close`` on the way out)."""

    slots = 1

    def submit(self, fn: Callable, job: Job) -> cf.Future:
        raise NotImplementedError

    def machine(self) -> str:
        """The record's machine line: this machine (a GPU when MMEngine's
        Runner sees one: it trains there)."""
        return machine_line(device=get_device())

    def close(self) -> None:
        """Release what it holds (nothing here)."""

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class InProcess(Executor):
    """Each run in this process, one after another (the default)."""

    def submit(self, fn: Callable, job: Job) -> cf.Future:
        """Run ``fn(job)`` now; its result or error in a done future."""
        future = cf.Future()
        try:
            future.set_result(fn(job))
        except Exception as err:  # handed back as a worker's error is
            future.set_exception(err)
        return future


def _die_with_parent() -> None:
    """Ask Linux to end this worker when the process that started it ends
    (a sweep killed mid-run leaves no run training on its own)."""
    try:
        import ctypes
        import signal
        ctypes.CDLL(None).prctl(1, signal.SIGTERM)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass


def _start_worker(threads: Optional[int]) -> None:
    """A worker's set-up: it ends with the sweep; ``threads`` torch
    threads (``--threads``), as the sweep's own process has."""
    _die_with_parent()
    if threads:
        import torch
        torch.set_num_threads(threads)


class Processes(Executor):
    """``jobs`` worker processes on this machine, a run each at a time.

    Workers are spawned (a fresh interpreter each, importing what this
    one imports), so a run sees no state of the sweep's process.

    Args:
        jobs (int): Runs at once.
        threads (int, optional): Torch threads of each worker.
    """

    def __init__(self, jobs: int, threads: Optional[int] = None):
        self.slots = jobs
        self.pool = cf.ProcessPoolExecutor(
            jobs, mp_context=multiprocessing.get_context('spawn'),
            initializer=_start_worker, initargs=(threads, ))

    def submit(self, fn: Callable, job: Job) -> cf.Future:
        return self.pool.submit(fn, job)

    def close(self) -> None:
        self.pool.shutdown(wait=True, cancel_futures=True)


def _ray_task(fn: Callable, job: Job, threads: Optional[int]) -> dict:
    """A run as a Ray task: ``fn(job)`` with ``threads`` torch threads
    (Ray sets ``OMP_NUM_THREADS`` to the task's CPUs otherwise)."""
    _start_worker(threads)
    return fn(job)


def _task_machine() -> str:
    """The machine line where a task runs (a GPU when it was given one)."""
    return machine_line(device=get_device())


def _code_paths() -> List[str]:
    """The folders this process imports its code from, outside the Python
    installation (a source tree, the projects' packages), for a local Ray's
    workers to import the same code."""
    install = tuple({sys.prefix, sys.base_prefix, sys.exec_prefix})
    return [p for p in sys.path if p and osp.isdir(p)
            and not osp.realpath(p).startswith(install)]


class RayTasks(Executor):
    """Each run a Ray task with ``cpus`` CPUs and ``gpus`` GPUs.

    Args:
        address (str, optional): The Ray cluster (``ray.init``'s address,
            e.g. ``auto`` or ``HOST:6379``); None starts a local Ray on
            this machine with ``jobs x cpus`` CPUs (all its cores without
            ``jobs``). A cluster's nodes must see the work dir, the data
            and the code at the same paths (a shared folder).
        jobs (int, optional): Runs in flight at most (None: as many as
            the cluster's resources take; Ray queues the rest).
        cpus (float): CPUs of each run.
        gpus (float): GPUs of each run (a fraction shares one GPU; 0 trains
            on the CPU: Ray hides the GPUs from a task that asks for none).
        threads (int, optional): Torch threads of each run.
    """

    def __init__(self, address: Optional[str] = None,
                 jobs: Optional[int] = None, cpus: float = 1,
                 gpus: float = 0, threads: Optional[int] = None):
        # what Ray's import and start set in this process's environment
        # (RAY_*, PYTHONBREAKPOINT) stays after its shutdown: put back by
        # close()
        self.environ = dict(os.environ)
        try:
            import ray
        except ImportError as err:
            raise RuntimeError(
                '--executor ray needs Ray: pip install -r '
                'requirements/serve.txt (the serving extra)') from err
        self.ray, self.threads = ray, threads
        self.started = not ray.is_initialized()
        if self.started:
            local = {} if address else dict(
                num_cpus=None if jobs is None else int(math.ceil(jobs * cpus)),
                include_dashboard=False,
                runtime_env=dict(env_vars=dict(
                    PYTHONPATH=os.pathsep.join(_code_paths()))))
            ray.init(address=address, **local)
        options = dict(num_cpus=cpus, num_gpus=gpus)
        self.task = ray.remote(_ray_task).options(**options)
        self.probe = ray.remote(_task_machine).options(**options)
        self.slots = jobs or sys.maxsize
        self.resources = f'{cpus:g} CPU, {gpus:g} GPU'

    def submit(self, fn: Callable, job: Job) -> cf.Future:
        return self.task.remote(fn, job, self.threads).future()

    def machine(self) -> str:
        """The machine line of a task with a run's resources."""
        line = self.ray.get(self.probe.remote())
        return f'Ray tasks of {self.resources} each on {line}'

    def close(self) -> None:
        if self.started:
            self.ray.shutdown()
            for key in set(os.environ) - set(self.environ):
                del os.environ[key]
            os.environ.update(self.environ)


def make_executor(kind: str = 'local', jobs: Optional[int] = None,
                  address: Optional[str] = None, cpus: float = 1,
                  gpus: float = 0, threads: Optional[int] = None):
    """The executor of ``compare_recipes.py --executor KIND --jobs N``:
    ``local`` runs in this process (N = 1, the default) or in N worker
    processes; ``ray`` as Ray tasks (:class:`RayTasks`)."""
    if kind == 'ray':
        return RayTasks(address, jobs, cpus, gpus, threads)
    if kind != 'local':
        raise ValueError(f"unknown executor {kind!r}: 'local' or 'ray'")
    if jobs is not None and jobs > 1:
        return Processes(jobs, threads)
    return InProcess()


def sweep(jobs: Sequence[Job], executor: Executor,
          log: Callable[[str], None] = print,
          train: bool = True) -> Tuple[List[dict], List[list]]:
    """Every run of ``jobs``: finished ones read back, the others handed to
    ``executor``, at most its ``slots`` at once, each test-time variant
    once the run whose weights it tests has finished.

    A run that fails stops the sweep: no run starts after it, the runs
    already running finish (their results are kept), then its error is
    raised.

    Args:
        jobs (Sequence[Job]): The comparison's runs, in order.
        executor: Where the runs run (:func:`make_executor`).
        log (callable): Progress printer.
        train (bool): False runs nothing: the runs not finished are left
            out (listed in the second return value).

    Returns:
        tuple: the runs' results in the order of ``jobs`` (each a
        :func:`cbnet_lab.run.run_recipe` record) and the runs left out, as
        ``[recipe, seed]``.
    """
    results: Dict[int, dict] = {}
    pending, missing = [], []
    for job in jobs:
        if osp.isfile(job.result):
            log(job.say('already done'))
            results[job.index] = read_result(job.result, job.budget,
                                             job.cfg_options)
        elif train:
            pending.append(job)
        else:
            missing.append([job.name, job.seed])
            log(job.say('not finished, left out (nothing is trained)'))
    # the time of the runs that train, for the estimate of what is left
    left, spent, fresh = sum(job.trains for job in pending), 0.0, 0
    running: Dict[cf.Future, Tuple[Job, float]] = {}
    failure = None
    while (pending and failure is None) or running:
        busy = {(j.name, j.seed) for j in pending} | {
            (j.name, j.seed) for j, _ in running.values()}
        for job in [j for j in pending if j.after not in busy]:
            if failure is not None or len(running) >= executor.slots:
                break
            pending.remove(job)
            eta = ''
            if fresh:  # the mean run so far, as many at once as can be
                at_once = max(1, min(executor.slots, left))
                minutes = math.ceil(spent / fresh * left / at_once / 60)
                eta = f', about {minutes} min left'
            log(job.say(job.doing + eta))
            running[executor.submit(execute, job)] = (job,
                                                      time.perf_counter())
        if not running:
            break
        done, _ = cf.wait(running, return_when=cf.FIRST_COMPLETED)
        for future in done:
            job, start = running.pop(future)
            try:
                results[job.index] = future.result()
            except Exception as err:  # noqa: B902  (any run's error)
                failure = failure or err
                if running:
                    log(job.say(f'failed ({type(err).__name__}): no run '
                                f'starts after it, the {len(running)} '
                                'running finish first'))
                continue
            if job.trains:
                spent += time.perf_counter() - start
                fresh += 1
                left -= 1
    if failure is not None:
        raise failure
    if pending:
        raise RuntimeError(
            'runs left waiting for runs that are not in the comparison: '
            f'{[(j.name, j.seed) for j in pending]}')
    return [results[k] for k in sorted(results)], missing

"""How long a call takes and how much memory it needs: wall-clock times of
repeated (or alternated) calls, their median and spread, and the peak
memory of a block (CUDA's allocator, or the resident set on the CPU).

What the lab's benchmarks (:mod:`cbnet_lab.benchmark` and the modules
over it) and the projects' timing command lines measure with; nothing
here builds a model.
"""
import os
import statistics
import threading
import time
from typing import Callable, Dict, List, Optional, Sequence

import torch


def synchronize(device: str) -> None:
    """Wait for queued CUDA work (no-op on CPU)."""
    if str(device).startswith('cuda'):
        torch.cuda.synchronize(device)


def time_calls(fn: Callable[[], object], repeats: int, warmup: int = 1,
               device: str = 'cpu') -> List[float]:
    """Wall-clock seconds of ``repeats`` calls of ``fn`` after ``warmup``.

    Args:
        fn (callable): The measured work.
        repeats (int): Timed calls.
        warmup (int): Untimed calls first.
        device (str): Synchronised around each call when CUDA.

    Returns:
        list[float]: One duration per timed call, seconds.
    """
    for _ in range(warmup):
        fn()
    times = []
    for _ in range(repeats):
        synchronize(device)
        start = time.perf_counter()
        fn()
        synchronize(device)
        times.append(time.perf_counter() - start)
    return times


def time_alternately(calls: Dict[str, Callable[[], object]], repeats: int,
                     warmup: int = 1, device: str = 'cpu',
                     self_timed: bool = False,
                     on_round: Optional[Callable[[int, dict], None]] = None
                     ) -> Dict[str, list]:
    """Measure several calls in alternation (``a, b, ..., a, b, ...``), so
    that load changes on a shared machine hit them alike.

    Args:
        calls (dict[str, callable]): The measured work, by name.
        repeats (int): Rounds with one measured call of each.
        warmup (int): Unmeasured rounds first (kernels, allocator).
        device (str): Synchronised around each timed call when CUDA.
        self_timed (bool): The calls time themselves: what each returns
            is recorded (e.g. a forward's and a whole step's seconds)
            instead of its wall time (:func:`time_calls`).
        on_round (callable, optional): ``on_round(i, measured)`` after
            round ``i`` (from 0): a run cut short keeps what it measured.

    Returns:
        dict[str, list]: Per name, one duration (seconds) or return value
        per round.
    """
    measured = {name: [] for name in calls}
    for _ in range(warmup):
        for fn in calls.values():
            fn()
    for i in range(repeats):
        for name, fn in calls.items():
            measured[name].append(
                fn() if self_timed else time_calls(fn, 1, 0, device)[0])
        if on_round is not None:
            on_round(i, measured)
    return measured


def summarize(times: Sequence[float]) -> Dict[str, float]:
    """Median and spread of durations.

    Args:
        times (Sequence[float]): Durations, seconds.

    Returns:
        dict: ``median``, ``min``, ``max``, ``iqr`` (interquartile
        range; 0 with fewer than 2 values) and ``p95`` (95th percentile,
        linear between the sorted values as ``numpy.percentile``; with
        fewer than 20 values it leans on the slowest ones), seconds.
    """
    if not times:
        raise ValueError('no durations to summarise')
    iqr, p95 = 0.0, times[0]
    if len(times) > 1:
        q = statistics.quantiles(times, n=4, method='inclusive')
        iqr = q[2] - q[0]
        p95 = statistics.quantiles(times, n=20, method='inclusive')[18]
    return dict(
        median=statistics.median(times),
        min=min(times),
        max=max(times),
        iqr=iqr,
        p95=p95)


def _status_mib(field: str) -> float:
    """A ``kB`` field of ``/proc/self/status``, in MiB."""
    with open('/proc/self/status') as f:
        for line in f:
            if line.startswith(field + ':'):
                return int(line.split()[1]) / 1024
    raise KeyError(f'{field} not in /proc/self/status')


def _reset_hwm() -> None:
    """Reset the kernel's resident-set high-water mark to the current RSS."""
    with open('/proc/self/clear_refs', 'w') as f:
        f.write('5')


#: glibc ``mallopt`` parameters
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3
#: the ceiling of glibc's dynamic mmap threshold on 64-bit (and twice it
#: for the trim threshold): where a long-running PyTorch process settles
STEADY_MMAP_THRESHOLD = 32 * 2**20
#: while a peak is measured, every allocation above this is ``mmap``-ed
MEASURE_MMAP_THRESHOLD = 64 * 2**10
_LIBC = None


def _glibc():
    """glibc through ctypes, or ``None`` (musl, macOS, Windows)."""
    global _LIBC
    if _LIBC is None:
        import ctypes
        try:
            lib = ctypes.CDLL(None)
            lib.mallopt, lib.malloc_trim  # noqa: B018 (glibc only)
            _LIBC = lib
        except (OSError, AttributeError):
            _LIBC = False
    return _LIBC or None


def set_malloc_thresholds(mmap_threshold: int = STEADY_MMAP_THRESHOLD
                          ) -> bool:
    """Fix glibc's mmap threshold (and the trim threshold at twice it).

    By default glibc raises its mmap threshold as large blocks are freed,
    up to :data:`STEADY_MMAP_THRESHOLD`, after which freed tensor memory is
    reused from the heap without page faults. :class:`PeakMemory` lowers
    the threshold for the measured block (so freed tensors leave the
    resident set) and restores this steady value afterwards; timing code
    calls this once at start so that every timed call, before or after a
    memory measurement, sees the same allocator.

    Returns:
        bool: False where the C library is not glibc (nothing changed).
    """
    libc = _glibc()
    if libc is None:
        return False
    libc.mallopt(_M_MMAP_THRESHOLD, int(mmap_threshold))
    libc.mallopt(_M_TRIM_THRESHOLD, 2 * int(mmap_threshold))
    return True


_HWM_RESETS: Optional[bool] = None


def hwm_reset_works() -> bool:
    """Whether this kernel resets and then raises ``VmHWM`` as documented.

    Probed once per process: reset, map and touch 64 MiB of fresh pages,
    unmap them, and check that the high-water mark rose by most of that.
    Some kernels and sandboxes accept the reset but do not keep the mark
    (it reads as the current RSS), which would report every peak as ~0.
    """
    global _HWM_RESETS
    if _HWM_RESETS is None:
        import mmap
        size = 64 * 2**20
        try:
            _reset_hwm()
            base = _status_mib('VmRSS')
            buf = mmap.mmap(-1, size)
            for off in range(0, size, mmap.PAGESIZE):
                buf[off] = 1
            buf.close()
            _HWM_RESETS = _status_mib('VmHWM') - base > 0.75 * size / 2**20
        except (OSError, KeyError):
            _HWM_RESETS = False
    return _HWM_RESETS


class _RSSSampler(threading.Thread):
    """Polls the resident set (``/proc/self/statm``) and keeps its maximum."""

    def __init__(self, interval: float) -> None:
        super().__init__(daemon=True)
        self.interval = interval
        self.page_mib = os.sysconf('SC_PAGE_SIZE') / 2**20
        self.max_mib = self.rss_mib()
        self.stop = threading.Event()

    def rss_mib(self) -> float:
        with open('/proc/self/statm') as f:
            return int(f.read().split()[1]) * self.page_mib

    def run(self) -> None:
        while not self.stop.wait(self.interval):
            self.max_mib = max(self.max_mib, self.rss_mib())

    def finish(self) -> float:
        self.stop.set()
        self.join()
        return max(self.max_mib, self.rss_mib())


class PeakMemory:
    """Peak memory of the work inside a ``with`` block, MiB.

    CUDA: ``torch.cuda.max_memory_allocated`` above the allocation at
    entry. CPU: the resident set's peak above the resident set at entry,
    read from the kernel's high-water mark (``VmHWM``, reset at entry
    through ``/proc/self/clear_refs``) where :func:`hwm_reset_works`, else
    from a thread that polls the resident set every ``interval`` seconds
    (``method`` says which; polling can miss peaks shorter than the
    interval, so it is a lower bound). On glibc, the block runs with every
    allocation above 64 KiB ``mmap``-ed and the heap trimmed at entry, so
    the resident set follows the live tensors (memory cached by the
    allocator would hide new peaks); the steady thresholds
    (:func:`set_malloc_thresholds`) are restored at exit. This changes the
    cost of allocations inside the block: do not time the same call.
    ``peak`` is ``None`` where neither is available (no ``/proc``).

    Args:
        device (str): ``'cpu'`` or a CUDA device.
        interval (float): Polling period of the fallback, seconds.
    """

    def __init__(self, device: str = 'cpu', interval: float = 0.002) -> None:
        self.device = str(device)
        self.interval = interval
        self.peak: Optional[float] = None
        self.method: Optional[str] = None

    def __enter__(self) -> 'PeakMemory':
        self._sampler = None
        if self.device.startswith('cuda'):
            torch.cuda.synchronize(self.device)
            torch.cuda.reset_peak_memory_stats(self.device)
            self._base = torch.cuda.memory_allocated(self.device)
            self.method = 'cuda'
            return self
        if not os.path.exists('/proc/self/statm'):
            return self
        if set_malloc_thresholds(MEASURE_MMAP_THRESHOLD):
            _glibc().malloc_trim(0)
        if hwm_reset_works():
            _reset_hwm()
            self.method = 'vmhwm'
        else:
            self._sampler = _RSSSampler(self.interval)
            self._sampler.start()
            self.method = 'sampled'
        self._base = _status_mib('VmRSS')
        return self

    def __exit__(self, *exc) -> None:
        if self.method == 'cuda':
            torch.cuda.synchronize(self.device)
            self.peak = (torch.cuda.max_memory_allocated(self.device) -
                         self._base) / 2**20
        elif self.method == 'vmhwm':
            self.peak = _status_mib('VmHWM') - self._base
        elif self.method == 'sampled':
            self.peak = self._sampler.finish() - self._base
        if self.method in ('vmhwm', 'sampled'):
            set_malloc_thresholds(STEADY_MMAP_THRESHOLD)

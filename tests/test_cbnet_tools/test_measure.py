"""Wall time and peak memory of calls (cbnet_tools/measure.py): the
durations' summary against the statistics module, alternated timing, the
CPU peak memory through the kernel's high-water mark and through the
polling fallback."""
import os.path as osp
import time

import numpy as np
import pytest
import torch

from cbnet_tools import measure
from cbnet_tools.measure import PeakMemory, summarize


def test_summarize_matches_statistics():
    s = summarize([4.0, 1.0, 3.0, 2.0, 5.0])
    assert s == dict(median=3.0, min=1.0, max=5.0, iqr=2.0,
                     p95=pytest.approx(4.8))
    times = [0.3, 7.5, 1.0, 2.0, 2.5, 9.0, 0.1, 4.0, 3.3]
    assert summarize(times)['p95'] == pytest.approx(
        np.percentile(times, 95))
    assert summarize([2.0])['iqr'] == 0.0
    assert summarize([2.0])['p95'] == 2.0
    with pytest.raises(ValueError, match='no durations'):
        summarize([])


def test_time_alternately_alternates_after_warm_up_rounds():
    order, rounds = [], []
    calls = {n: (lambda n=n: order.append(n) or len(order)) for n in 'ab'}
    times = measure.time_alternately(
        calls, repeats=3, warmup=2,
        on_round=lambda i, m: rounds.append((i, len(m['a']))))
    assert order == list('ab' * 5)  # 2 warm-up rounds, then 3 timed
    assert [len(v) for v in times.values()] == [3, 3]
    assert all(t >= 0 for v in times.values() for t in v)
    assert rounds == [(0, 1), (1, 2), (2, 3)]
    # calls that time themselves: their return values are kept
    own = measure.time_alternately(calls, 2, 0, self_timed=True)
    assert own == dict(a=[11, 13], b=[12, 14])


def test_peak_memory_sees_a_large_allocation():
    if not osp.exists('/proc/self/statm'):
        pytest.skip('needs Linux /proc')
    with PeakMemory('cpu') as mem:
        x = torch.ones(64, 2**20 // 4 * 4)  # 256 MiB of float32, touched
        del x
    assert mem.method in ('vmhwm', 'sampled')
    assert mem.peak is not None
    if mem.method == 'vmhwm':
        assert 200 < mem.peak < 400
    else:  # polling is a lower bound: a short peak can fall between polls
        assert mem.peak < 400


def test_peak_memory_sampling_fallback(monkeypatch):
    """Where the kernel does not keep VmHWM, a polling thread measures."""
    if not osp.exists('/proc/self/statm'):
        pytest.skip('needs Linux /proc')
    monkeypatch.setattr(measure, '_HWM_RESETS', False)
    with PeakMemory('cpu', interval=0.001) as mem:
        x = torch.ones(64, 2**20 // 4 * 4)  # 256 MiB of float32, touched
        time.sleep(0.05)  # held for 50 polling periods
        del x
    assert mem.method == 'sampled'
    assert 200 < mem.peak < 400
    with PeakMemory('cpu', interval=0.001) as idle:
        pass
    assert idle.method == 'sampled' and abs(idle.peak) < 50


def test_peak_memory_is_not_hidden_by_memory_the_allocator_cached():
    """Memory freed before the block (kept by glibc's heap at the steady
    thresholds) must not absorb the block's allocations."""
    if not osp.exists('/proc/self/statm') or \
            not measure.set_malloc_thresholds():
        pytest.skip('needs Linux /proc and glibc')
    chunks = [torch.ones(2**21) for _ in range(16)]  # 16 x 8 MiB, heap
    del chunks  # freed into the heap (below the 32 MiB mmap threshold)
    with PeakMemory('cpu') as mem:
        chunks = [torch.ones(2**21) for _ in range(16)]
        time.sleep(0.02)  # for the polling fallback
        del chunks
    assert 100 < mem.peak < 200


def test_hwm_probe_is_cached_and_boolean():
    first = measure.hwm_reset_works()
    assert isinstance(first, bool)
    assert measure.hwm_reset_works() is first

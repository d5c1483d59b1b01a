"""Smoke test of tools/analysis_tools/benchmark_backbone.py (MiT-B0 at
64x96, one timed forward) with the query-chunked CSPE variant, on the CPU
and, where there is one, on a GPU."""
import json

import pytest
import torch
from tool_helpers import load_tool


def run_b0(tmp_path, *extra):
    """The tool's JSON record of MiT-B0 ope / cspe / cspe in bands of 8."""
    tool = load_tool('analysis_tools/benchmark_backbone.py')
    out = tmp_path / 'backbone.json'
    tool.main(['--archs', 'b0', '--size', '64', '96', '--runs', '1',
               '--query-chunk', '8', '--out', str(out), *extra])
    return json.loads(out.read_text())


def test_b0_ope_cspe_and_chunked(tmp_path):
    record = run_b0(tmp_path, '--threads', '1')
    results = record['results']
    assert [r['pos'] for r in results] == ['ope', 'cspe', 'cspe, chunk 8']
    for r in results:
        assert r['time_s'] > 0 and r['time_ratio'] > 0
    # the chunked model is the cspe model (same parameters)
    assert results[1]['params_m'] == results[2]['params_m']
    # the device is recorded, CPU by default
    assert all(r['device'] == 'cpu' for r in results)
    assert record['device'] == 'cpu'


@pytest.mark.skipif(not torch.cuda.is_available(), reason='needs CUDA')
def test_cuda_times_and_memory_on_the_gpu(tmp_path):
    results = run_b0(tmp_path, '--device', 'cuda')['results']
    assert all(r['device'].startswith('cuda') and r['peak_mib'] > 0
               for r in results)

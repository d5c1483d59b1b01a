"""Smoke test of tools/analysis_tools/benchmark_kernels.py on the CPU (one
small image size, few channels, 4 RoIs, one repeat)."""
import json

import pytest
from tool_helpers import load_tool


def test_small_run_writes_every_kernel_against_its_stock_op(tmp_path):
    tool = load_tool('analysis_tools/benchmark_kernels.py')
    out = tmp_path / 'kernels.json'
    tool.main(['--size', '192', '384', '--channels', '4', '--rois', '4',
               '--repeats', '1', '--threads', '1', '--out', str(out)])
    result = json.loads(out.read_text())
    assert result['device'] == 'cpu'
    assert result['machine']['threads'] == 1  # report.machine_info
    rows = result['rows']
    deform = [r for r in rows if r['kernel'].startswith('deform')]
    loss = [r for r in rows if r['kernel'] == 'boundary loss']
    # inference and training, gather against mmcv (torchvision where it
    # imports); fused against the autograd form
    assert {r['setting'].split(', ')[-1] for r in deform} == {
        'inference', 'fwd+bwd'}
    assert {'gather', 'mmcv'} <= {r['impl'] for r in deform}
    assert sorted(r['impl'] for r in loss) == ['autograd', 'fused']
    for r in rows:
        assert r['median_ms'] > 0
        stock = 'autograd' if r['kernel'] == 'boundary loss' else 'mmcv'
        if r['impl'] == stock:
            assert r['vs_stock'] == 1.0
    by = {(r['setting'], r['impl']): r for r in deform}
    for (setting, impl), r in by.items():
        assert r['vs_stock'] == pytest.approx(
            r['median_ms'] / by[(setting, 'mmcv')]['median_ms'])


def test_a_size_too_small_for_the_baseline_is_refused(tmp_path):
    tool = load_tool('analysis_tools/benchmark_kernels.py')
    with pytest.raises(SystemExit, match='smaller than 3x3'):
        tool.main(['--size', '64', '128', '--out',
                   str(tmp_path / 'k.json')])
    assert not (tmp_path / 'k.json').exists()

"""Smoke test of tools/analysis_tools/benchmark_rpn.py: its synthetic set,
one training iteration of each head at 64x32, recall and timing."""
import json

import pytest

from tool_helpers import load_tool


# 19 s on 2 cores at load ~3, 51 s at load ~9 (model builds, COCO recall)
@pytest.mark.slow
def test_one_iteration_per_head(tmp_path):
    tool = load_tool('analysis_tools/benchmark_rpn.py')
    out = tmp_path / 'rpn.json'
    tool.main([
        '--data-root', str(tmp_path / 'data'), '--synthetic', '2', '1',
        '--iters', '1', '--warmup', '1', '--batch-size', '1', '--scale',
        '64', '32', '--width', '8', '--time-runs', '1', '--out', str(out)
    ])
    result = json.loads(out.read_text())
    rows = {r['head']: r for r in result['results']}
    assert sorted(rows) == ['CRPN', 'RPNHead']
    for row in rows.values():
        assert 0 <= row['AR@100'] <= row['AR@1000'] <= 1
        assert row['mean_proposals'] > 0
        assert row['head_forward_ms'] > 0 and row['params'] > 0
        assert row['input_hw'] == [32, 64]
    # the Cascade RPN head has two stages: more parameters than RPNHead
    assert rows['CRPN']['params'] > rows['RPNHead']['params']

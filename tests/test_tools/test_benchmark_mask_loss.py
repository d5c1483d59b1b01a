"""Smoke test of tools/analysis_tools/benchmark_mask_loss.py (4 RoIs, one
repeat)."""
import json

from tool_helpers import load_tool


def test_four_rois_one_repeat(tmp_path):
    tool = load_tool('analysis_tools/benchmark_mask_loss.py')
    out = tmp_path / 'mask_loss.json'
    tool.main(['--rois', '4', '--repeats', '1', '--num-classes', '3',
               '--out', str(out)])
    result = json.loads(out.read_text())
    assert [r['rois'] for r in result['rows']] == [4]
    row = result['rows'][0]
    names = ['bce', 'shape', 'bound', 'bound_exact']
    for key in ('time_ms', 'best_time_ms', 'forward_time_ms',
                'peak_mem_mib'):
        assert sorted(row[key]) == sorted(names)
        assert all(v > 0 for v in row[key].values()), (key, row[key])
    assert row['time_ratio_vs_bce']['bce'] == 1.0
    assert row['forward_time_ratio_vs_bce']['bce'] == 1.0
    assert all(row['forward_time_ms'][n] <= row['time_ms'][n]
               for n in names)  # medians of the parts of one step

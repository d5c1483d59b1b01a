"""Smoke test of tools/analysis_tools/benchmark_backbone.py (MiT-B0 at
64x96, one timed forward) with the query-chunked CSPE variant."""
import json

from tool_helpers import load_tool


def test_b0_ope_cspe_and_chunked(tmp_path):
    tool = load_tool('analysis_tools/benchmark_backbone.py')
    out = tmp_path / 'backbone.json'
    tool.main(['--archs', 'b0', '--size', '64', '96', '--runs', '1',
               '--threads', '1', '--query-chunk', '8', '--out', str(out)])
    results = json.loads(out.read_text())['results']
    assert [r['pos'] for r in results] == ['ope', 'cspe', 'cspe, chunk 8']
    for r in results:
        assert r['time_s'] > 0 and r['time_ratio'] > 0
    # the chunked model is the cspe model (same parameters)
    assert results[1]['params_m'] == results[2]['params_m']

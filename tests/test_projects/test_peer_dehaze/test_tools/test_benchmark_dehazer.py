"""projects/peer_dehaze/tools/benchmark_dehazer.py on tiny images."""
import json

import pytest
from tool_helpers import load_tool


@pytest.fixture(scope='module')
def tool():
    return load_tool('projects/peer_dehaze/tools/benchmark_dehazer.py')


def test_times_both_dehazers_per_size(tool, tmp_path):
    out = tmp_path / 'latency.json'
    results = tool.main(['--sizes', '16', '24', '9', '31', '--repeats', '2',
                         '--warmup', '0', '--out', str(out)])
    assert set(results) == {'attention@16x24', 'attention@9x31',
                            'dcp@16x24', 'dcp@9x31'}
    for key, res in results.items():
        assert 0 < res['min'] <= res['median'] <= res['max']
        assert res['params'] == (0 if key.startswith('dcp') else 26499)
    saved = json.loads(out.read_text())
    assert saved['threads'] == 1 and saved['results'] == results
    with pytest.raises(ValueError, match='pairs'):
        tool.main(['--sizes', '16'])

"""tools/dehaze/benchmark_dehazer.py on tiny images."""
import importlib.util
import json
import os.path as osp

import pytest

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__))))
SCRIPT = osp.join(ROOT, 'tools', 'dehaze', 'benchmark_dehazer.py')


@pytest.fixture(scope='module')
def tool():
    spec = importlib.util.spec_from_file_location('benchmark_dehazer',
                                                  SCRIPT)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


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

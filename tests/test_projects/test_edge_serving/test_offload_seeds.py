"""Offload tables of several seeds of the edge model
(cbnet_serving.offload_seeds, projects/edge_serving/tools/offload_seeds.py).

Two "seeds" of the local model over the offload stream (serving_helpers.py,
the ``runs`` fixture of conftest.py): one that sees the clear frames only,
one that sees nothing. Each seed's table comes from offload_curve; the
combined rows are checked against means and stds computed here from those
tables.
"""
import json

import numpy as np
import pytest
from serving_helpers import NONE, write_run
from tool_helpers import load_tool

from cbnet_serving.offload import offload_curve
from cbnet_serving.offload_seeds import combine, row_key, to_markdown


@pytest.fixture
def two_seeds(runs):
    blind = write_run(runs['tmp'] / 'blind', 'local', lambda f: NONE)
    out = []
    for local in (runs['local'], blind):
        out.append(offload_curve(local, runs['server'], runs['ann'],
                                 thresholds=[0.6], confidences=[0.5],
                                 random_seeds=(0, 1),
                                 progress=lambda *_: None))
    return out


def test_combine_is_the_mean_and_std_of_the_seeds(two_seeds):
    table = combine(two_seeds, ['a', 'b'])
    assert table['seeds'] == ['a', 'b'] and table['frames'] == 4
    rows = {r['row']: r for r in table['rows']}
    # random rows are no rows of their own
    assert set(rows) == {'always local', 'haze: transmission < 0.6',
                         'confidence: top score < 0.5', 'always server'}
    for name, r in rows.items():
        per = [next(x for x in res['rows'] if x['policy'] == name)
               for res in two_seeds]
        for k in ('bbox_mAP', 'offload_rate', 'seconds'):
            assert r[k]['mean'] == pytest.approx(np.mean([p[k] for p in per]))
            assert r[k]['std'] == pytest.approx(
                np.std([p[k] for p in per], ddof=1))
        fog = [p['condition_ap']['0.02']['bbox_mAP'] for p in per]
        assert r['condition_ap']['0.02']['mean'] == pytest.approx(
            np.mean(fog))
    haze = rows['haze: transmission < 0.6']
    per = [next(x for x in res['rows'] if x['policy'] == haze['row'])
           for res in two_seeds]
    gains = [p['bbox_mAP'] - p['random']['bbox_mAP'] for p in per]
    assert haze['gain_over_random']['mean'] == pytest.approx(np.mean(gains))
    # the local model that misses the foggy frames: offloading exactly
    # them (100 AP) beats offloading two frames at random
    assert per[0]['bbox_mAP'] == pytest.approx(100) and gains[0] > 0
    assert 'random_bbox_mAP' not in rows['always local']
    md = to_markdown(table)
    assert md.startswith('2 seeds (a, b), 4 frames')
    assert '| always server | 100 +- 0 % | 100.0 +- 0.0 |' in md


def test_rows_are_lined_up_by_decile():
    def result(thr):
        row = dict(policy=f'haze: transmission < {thr}', rule='haze',
                   quantile=0.5, offload_rate=0.5, bbox_mAP=thr * 10,
                   bbox_mAP_50=1.0, seconds=0.1,
                   condition_ap={'fog': dict(bbox_mAP=1.0)})
        extra = dict(row, policy=f'confidence: top score < {thr}',
                     rule='confidence', quantile=None)
        return dict(frames=2, conditions=['fog'], calibrated=False,
                    rows=[row, extra])
    table = combine([result(0.4), result(0.6)])
    haze = table['rows'][0]
    assert haze['row'] == 'haze, decile 0.5'
    assert haze['policies'] == ['haze: transmission < 0.4',
                                'haze: transmission < 0.6']
    assert haze['bbox_mAP']['mean'] == pytest.approx(5.0)
    # fixed thresholds that differ: not the same row, left out and said so
    assert table['partial'] == ['confidence: top score < 0.4',
                                'confidence: top score < 0.6']
    assert 'Rows not in every seed (left out)' in to_markdown(table)
    assert row_key(dict(policy='random 1/2 (mean of 3 seeds)')) is None


def test_results_that_cannot_be_combined(two_seeds):
    with pytest.raises(ValueError, match='at least two seeds'):
        combine(two_seeds[:1])
    other = dict(two_seeds[1], frames=5)
    with pytest.raises(ValueError, match='frames 5 differs'):
        combine([two_seeds[0], other])
    other = dict(two_seeds[1], calibrated=True)
    with pytest.raises(ValueError, match='calibrated'):
        combine([two_seeds[0], other])
    old = dict(two_seeds[1], rows=[
        {k: v for k, v in r.items() if k != 'rule'}
        for r in two_seeds[1]['rows']])
    with pytest.raises(ValueError, match='score it again'):
        combine([two_seeds[0], old])


def test_offload_seeds_cli(two_seeds, tmp_path, capsys):
    paths = []
    for i, res in enumerate(two_seeds):
        paths.append(str(tmp_path / f'{i}.json'))
        json.dump(res, open(paths[-1], 'w'))
    tool = load_tool('projects/edge_serving/tools/offload_seeds.py')
    with pytest.raises(SystemExit):
        tool.main(paths + ['--names', 'x', '--out-dir', str(tmp_path)])
    assert '1 names for 2 records' in capsys.readouterr().err
    tool.main(paths + ['--out-dir', str(tmp_path / 'o')])
    out = capsys.readouterr().out
    assert (tmp_path / 'o' / 'offload_seeds.md').read_text() in out
    saved = json.load(open(tmp_path / 'o' / 'offload_seeds.json'))
    assert saved['records'] == paths and len(saved['rows']) == 4

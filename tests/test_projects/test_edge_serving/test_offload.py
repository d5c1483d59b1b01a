"""Offload rate vs AP (cbnet_serving.offload,
projects/edge_serving/tools/offload_eval.py).

Two fake route.py runs over a stream of clear and foggy frames of two
annotated images (``runs``, conftest.py; the stream is
serving_helpers.py's): the server predicts the ground truth everywhere,
the local model only on clear frames. AP is checked against pycocotools'
COCOeval called directly (an independent reference), and against what it
must be: perfect when every foggy frame is offloaded.
"""
import copy
import json

import numpy as np
import pytest
from serving_helpers import (CLASSES, FRAMES, cocoeval_ap, img_of, truth,
                             write_run)
from tool_helpers import load_tool

from cbnet_serving.offload import (check_runs, offload_curve, policy_offloads,
                                   read_run, score, stream_annotations,
                                   to_markdown)


def test_stream_annotations_one_image_per_frame(runs):
    gt = stream_annotations(runs['ann'], FRAMES)
    assert [i['id'] for i in gt['images']] == [1, 2, 3, 4]
    assert [i['file_name'] for i in gt['images']] == FRAMES
    # image 1 has two objects, image 2 one; each frame has its own copies
    assert [a['image_id'] for a in gt['annotations']] == [1, 1, 2, 2, 3, 4]
    assert [a['id'] for a in gt['annotations']] == [1, 2, 3, 4, 5, 6]
    with pytest.raises(ValueError, match='no .or no single. image'):
        stream_annotations(runs['ann'], FRAMES + ['x/s9_leftImg8bit.png'])


def test_score_matches_cocoeval(runs):
    gt = stream_annotations(runs['ann'], FRAMES)
    local = read_run(runs['local'])['records']
    preds = [local[f]['prediction'] for f in FRAMES]
    # drop one object and lower a score, so AP is neither 0 nor 100
    preds[0] = dict(truth(1), labels=truth(1)['labels'][:1],
                    scores=[0.3], bboxes=truth(1)['bboxes'][:1],
                    masks=truth(1)['masks'][:1])
    got = score(gt, preds, CLASSES)
    for key, iou in (('bbox_mAP', 'bbox'), ('segm_mAP', 'segm')):
        ref = cocoeval_ap(gt, preds, iou)
        assert 0 < ref < 100
        assert got[key] == pytest.approx(ref, abs=0.1)
    perfect = [truth(img_of(f)) for f in FRAMES]
    assert score(gt, perfect, CLASSES)['segm_mAP'] == pytest.approx(100)


def test_offload_curve_haze_rule_recovers_foggy_frames(runs):
    res = offload_curve(runs['local'], runs['server'], runs['ann'],
                        thresholds=[0.3, 0.6],
                        policy=dict(transmission_thr=0.0,
                                    min_confidence=0.5),
                        random_seeds=(0, 1), progress=lambda *_: None)
    rows = {r['policy']: r for r in res['rows']}
    gt = stream_annotations(runs['ann'], FRAMES)
    local = read_run(runs['local'])['records']
    ref_local = cocoeval_ap(gt, [local[f]['prediction'] for f in FRAMES],
                            'segm')
    assert rows['always local']['segm_mAP'] == pytest.approx(ref_local,
                                                             abs=0.1)
    assert rows['always local']['offload_rate'] == 0
    assert rows['always server']['segm_mAP'] == pytest.approx(100)
    # transmission 0.4 < 0.6: the two foggy frames go to the server
    haze = rows['haze: transmission < 0.6']
    assert haze['offload_rate'] == 0.5
    assert haze['offloaded'] == {'clear': 0.0, '0.02': 1.0}
    assert haze['segm_mAP'] == pytest.approx(100)
    assert haze['seconds'] == pytest.approx((0.5 + 2.0) / 2)
    assert rows['haze: transmission < 0.3']['offload_rate'] == 0
    # the confidence rule alone (top score 0.2 < 0.5 on foggy frames)
    shipped = [r for r in res['rows'] if r['policy'].startswith('shipped')]
    assert shipped[0]['segm_mAP'] == pytest.approx(100)
    # random offloading of 2 of 4 frames: a control, mean of two seeds
    rand = [r for r in res['rows'] if r['policy'].startswith('random 2/4')]
    assert len(rand) == 1
    assert set(rand[0]['std']) == {'bbox_mAP', 'segm_mAP'}
    assert ref_local <= rand[0]['segm_mAP'] <= 100
    assert res['by_condition']['0.02']['local']['segm_mAP'] == 0
    assert res['by_condition']['0.02']['server']['segm_mAP'] == \
        pytest.approx(100)
    table = to_markdown(res)
    assert '| haze: transmission < 0.6 | 50% | 0% | 100% |' in table
    assert '| 0.02 | 0.400 |' in table


def test_live_auto_run_and_server_classes_in_another_order(runs):
    # the server labels index ITS classes (reversed order): remapped by name
    rev = CLASSES[::-1]
    server = write_run(runs['tmp'] / 'server_rev', 'server',
                       lambda f: truth(img_of(f), rev), classes=rev)
    auto = write_run(
        runs['tmp'] / 'auto', 'auto',
        lambda f: truth(img_of(f), rev) if 'foggy' in f
        else truth(img_of(f)), classes=rev)
    # the auto run: foggy frames answered by the server, clear ones local
    lines = [json.loads(x) for x in open(runs['tmp'] / 'auto' /
                                         'results.jsonl')]
    with open(runs['tmp'] / 'auto' / 'results.jsonl', 'w') as f:
        for r in lines:
            r['where'] = 'server' if 'foggy' in r['frame'] else 'local'
            f.write(json.dumps(r) + '\n')
    res = offload_curve(runs['local'], server, runs['ann'],
                        thresholds=[0.6], auto_dir=auto, random_seeds=(0, ),
                        progress=lambda *_: None)
    rows = {r['policy']: r for r in res['rows']}
    assert rows['always server']['segm_mAP'] == pytest.approx(100)
    live = rows['live auto run (route.py --mode auto)']
    assert live['offload_rate'] == 0.5 and live['fallbacks'] == 0
    assert live['segm_mAP'] == pytest.approx(100)


def test_runs_that_cannot_be_compared(runs):
    local, server = read_run(runs['local']), read_run(runs['server'])
    assert check_runs(local, server) == sorted(FRAMES)
    other = copy.deepcopy(server)
    other['records'].pop(FRAMES[0])
    with pytest.raises(ValueError, match='different frames'):
        check_runs(local, other)
    other = copy.deepcopy(server)
    other['records'][FRAMES[1]]['where'] = 'local-fallback'
    with pytest.raises(ValueError, match='not answered by the server'):
        check_runs(local, other)
    other = copy.deepcopy(server)
    other['records'][FRAMES[1]]['transmission'] = 0.1
    with pytest.raises(ValueError, match='different local models'):
        check_runs(local, other)


def test_read_run_errors(runs, tmp_path):
    with pytest.raises(FileNotFoundError, match='route.py'):
        read_run(str(tmp_path / 'nowhere'))
    bad = tmp_path / 'bad'
    bad.mkdir()
    (bad / 'results.jsonl').write_text('{"frame": "a"')
    with pytest.raises(ValueError, match='not JSON'):
        read_run(str(bad))
    (bad / 'results.jsonl').write_text('')
    with pytest.raises(ValueError, match='no frames'):
        read_run(str(bad))
    # no run.json (an old run): the classes must be given
    (tmp_path / 'local' / 'run.json').unlink()
    with pytest.raises(ValueError, match='classes='):
        offload_curve(runs['local'], runs['server'], runs['ann'],
                      thresholds=[0.6], progress=lambda *_: None)


def test_policy_offloads_uses_the_routers_rule(runs):
    recs = read_run(runs['local'])['records']
    frames = sorted(recs)
    got = policy_offloads(recs, frames, 0.6, 0.0)
    assert got.tolist() == ['foggy' in f for f in frames]
    assert policy_offloads(recs, frames, 0.0, 0.0).sum() == 0
    assert policy_offloads(recs, frames, 0.0, 0.95).all()


def test_offload_eval_cli(runs, capsys):
    tool = load_tool('projects/edge_serving/tools/offload_eval.py')
    tool.main([runs['local'], runs['server'], '--ann', runs['ann'],
               '--thresholds', '0.6', '--out-dir', str(runs['tmp'] / 'o')])
    out = capsys.readouterr().out
    assert '| always server | 100% |' in out
    res = json.load(open(runs['tmp'] / 'o' / 'offload.json'))
    assert res['frames'] == 4
    # edge_router.py's thresholds (0.6, 0.3) make the "shipped" row
    assert any(r['policy'].startswith('shipped: transmission < 0.6 or '
                                      'top score < 0.3') for r in res['rows'])
    assert (runs['tmp'] / 'o' / 'offload.md').read_text() in out


def test_confidence_rule_and_random_control_per_row(runs):
    res = offload_curve(runs['local'], runs['server'], runs['ann'],
                        thresholds=[0.6], confidences=[0.5, 0.1],
                        random_seeds=(0, 1), progress=lambda *_: None)
    rows = {r['policy']: r for r in res['rows']}
    # the local top score is 0.2 on the foggy frames, 0.9 on clear ones
    conf = rows['confidence: top score < 0.5']
    assert conf['rule'] == 'confidence' and 'quantile' not in conf
    assert conf['offloaded'] == {'clear': 0.0, '0.02': 1.0}
    assert conf['segm_mAP'] == pytest.approx(100)
    assert rows['confidence: top score < 0.1']['offload_rate'] == 0
    # a row offloading 2 of 4 frames carries random offloading of 2
    rand = rows['random 2/4 (mean of 2 seeds)']
    assert conf['random'] == {k: v for k, v in rand.items()
                              if k.startswith(('bbox_', 'segm_'))}
    assert rows['haze: transmission < 0.6']['random'] == conf['random']
    # nothing or everything offloaded: no control
    assert 'random' not in rows['always local']
    assert 'random' not in rows['always server']
    assert 'random' not in rows['confidence: top score < 0.1']
    assert [r['rule'] for r in res['rows']] == [
        'local', 'haze', 'confidence', 'confidence', 'server', 'random']
    table = to_markdown(res)
    assert table.splitlines()[0].endswith('| box AP, random at that rate |')
    assert f"| {rand['bbox_mAP']:.1f} |" in table


def test_default_levels_are_deciles(runs):
    res = offload_curve(runs['local'], runs['server'], runs['ann'],
                        random_seeds=(0, ), progress=lambda *_: None)
    haze = [r for r in res['rows'] if r['rule'] == 'haze']
    conf = [r for r in res['rows'] if r['rule'] == 'confidence']
    t = [0.4, 0.4, 0.9, 0.9]
    want = {}
    for q in np.round(np.linspace(0.1, 0.9, 9), 1):
        want.setdefault(round(float(np.quantile(t, q)), 4), float(q))
    assert [(r['policy'], r['quantile']) for r in haze] == [
        (f'haze: transmission < {thr:g}', q)
        for thr, q in sorted(want.items())]
    # the top scores (0.2 / 0.9) split the same way as the transmission
    assert [r['quantile'] for r in conf] == [r['quantile'] for r in haze]
    assert [r['offload_rate'] for r in conf] == \
        [r['offload_rate'] for r in haze]

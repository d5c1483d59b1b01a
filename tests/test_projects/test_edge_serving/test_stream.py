"""A stream of real-format frames by condition (cbnet_serving.stream,
projects/edge_serving/tools/make_stream.py) scored with
``offload_curve(..., conditions='folder')``.

A tiny VOC fog folder (DAWN's layout and names) and a tiny COCO file
become ``frames/fog`` and ``frames/clear`` with one annotation file; two
fake route.py runs over those frames (the server answers every frame with
its ground truth, the edge model only the clear ones) must give AP 100 when
the fog frames are offloaded, and pycocotools (called directly) is the
reference for the pooled stream.
"""
import json
import os
import os.path as osp

import pytest
from serving_helpers import cocoeval_ap, tiny_coco
from tool_helpers import load_tool

from cbnet_mmdet.datasets.voc_fog import CITYSCAPES_CLASSES
from cbnet_serving.offload import (condition_order, frame_condition,
                                   offload_curve, stream_annotations)
from cbnet_serving.stream import build_stream, list_images, voc_frames
from cbnet_tools.synthetic.voc_folder import tiny_fog_folder


@pytest.fixture
def stream(tmp_path):
    fog = str(tmp_path / 'fog')
    tiny_fog_folder(fog, num_images=10)
    ann, imgs = tiny_coco(str(tmp_path / 'coco'))
    tool = load_tool('projects/edge_serving/tools/make_stream.py')
    out = tool.main([str(tmp_path / 'stream'), '--voc', f'fog={fog}',
                     '--coco', f'clear={ann}:{imgs}'])
    return dict(out=out, fog=fog, tmp=tmp_path)


def test_build_stream_layout_and_annotations(stream):
    out = stream['out']
    gt = json.load(open(out['ann_file']))
    fog_val = voc_frames(stream['fog'])
    assert out['counts'] == {'fog': len(fog_val), 'clear': 3}
    assert out['dropped'] == 1  # the dog
    names = [img['file_name'] for img in gt['images']]
    assert names[-3:] == [f'clear/{i:012d}.jpg' for i in (1, 2, 3)]
    assert all(n.startswith('fog/') for n in names[:-3])
    for n in names:  # every frame is a link to its photo
        assert osp.islink(osp.join(out['frames'], n))
    assert [i['id'] for i in gt['images']] == list(range(1, len(names) + 1))
    assert [c['name'] for c in gt['categories']] == \
        list(CITYSCAPES_CLASSES)
    # the VOC boxes arrive as COCO x, y, w, h, the COCO ones unchanged
    fog_boxes = [o['bbox'] for _, _, _, objs in fog_val for o in objs]
    got = [a['bbox'] for a in gt['annotations']
           if a['image_id'] <= len(fog_val)]
    assert got == fog_boxes
    clear = [a for a in gt['annotations'] if a['image_id'] > len(fog_val)]
    assert [(a['category_id'], a['bbox']) for a in clear] == [
        (3, [5, 5, 30, 20]), (1, [40, 10, 10, 30]), (3, [2, 2, 20, 10])]


def test_build_stream_refuses_bad_input(stream, tmp_path):
    with pytest.raises(FileExistsError, match='not empty'):
        build_stream(str(tmp_path / 'stream'), voc=[('fog', stream['fog'])])
    with pytest.raises(ValueError, match='two frames would be'):
        build_stream(str(tmp_path / 's2'), voc=[('fog', stream['fog']),
                                                ('fog', stream['fog'])])
    with pytest.raises(ValueError, match='a folder name is expected'):
        build_stream(str(tmp_path / 's3'), voc=[('a/b', stream['fog'])])
    with pytest.raises(ValueError, match='at least one'):
        build_stream(str(tmp_path / 's4'))
    bad = tmp_path / 'bad.json'
    bad.write_text(json.dumps(dict(images=[])))
    with pytest.raises(ValueError, match="no 'annotations'"):
        build_stream(str(tmp_path / 's5'), coco=[('c', str(bad), '.')])
    tool = load_tool('projects/edge_serving/tools/make_stream.py')
    with pytest.raises(SystemExit):
        tool.parse_args([str(tmp_path / 's6'), '--coco', 'clear=x.json'])
    with pytest.raises(SystemExit):
        tool.parse_args([str(tmp_path / 's6')])


def test_list_images_recursive_sorted_images_only(tmp_path):
    """The one listing route.py and load_test.py read a folder with: every
    image under it at any depth, in sorted path order, whatever the case of
    its extension; other files and folders named like images left out."""
    for rel in ('fog/b.jpg', 'fog/a.PNG', 'clear/z/c.jpeg', 'clear/d.bmp',
                'notes.txt', 'fog/e.jpg.json'):
        osp.dirname(rel) and os.makedirs(tmp_path / osp.dirname(rel),
                                         exist_ok=True)
        (tmp_path / rel).write_bytes(b'x')
    os.makedirs(tmp_path / 'dir.png')
    got = [osp.relpath(f, tmp_path) for f in list_images(str(tmp_path))]
    assert got == ['clear/d.bmp', 'clear/z/c.jpeg', 'fog/a.PNG', 'fog/b.jpg']
    empty = tmp_path / 'empty'
    os.makedirs(empty / 'sub')
    (empty / 'sub' / 'x.txt').write_bytes(b'x')
    with pytest.raises(FileNotFoundError, match='no images'):
        list_images(str(empty))


def test_frame_conditions():
    assert frame_condition('fog/a.jpg', 'folder') == 'fog'
    assert frame_condition('x/s1_leftImg8bit_foggy_beta_0.01.png') == '0.01'
    with pytest.raises(ValueError, match='in no folder'):
        frame_condition('a.jpg', 'folder')
    with pytest.raises(ValueError, match='one of'):
        frame_condition('fog/a.jpg', 'nope')
    assert condition_order(['fog', '0.02', 'clear', '0.005', 'haze']) == \
        ['clear', '0.005', '0.02', 'fog', 'haze']


def write_run(folder, mode, frames, preds, transmission):
    folder.mkdir()
    with open(folder / 'results.jsonl', 'w') as f:
        for frame in frames:
            f.write(json.dumps(dict(
                frame=frame, where='local' if mode == 'local' else 'server',
                reason='', transmission=transmission(frame),
                local_top_score=0.9, seconds=1.0,
                prediction=preds[frame])) + '\n')
    classes = dict(classes=list(CITYSCAPES_CLASSES))
    json.dump(dict(local=classes, server=None if mode == 'local' else
                   classes), open(folder / 'run.json', 'w'))
    return str(folder)


def truth(gt):
    """Per frame path, a prediction equal to its ground truth."""
    out = {}
    for img in gt['images']:
        objs = [a for a in gt['annotations'] if a['image_id'] == img['id']
                and not a['iscrowd']]
        out[img['file_name']] = dict(
            labels=[a['category_id'] - 1 for a in objs],
            scores=[0.9] * len(objs),
            bboxes=[[x, y, x + w, y + h] for x, y, w, h in
                    (a['bbox'] for a in objs)])
    return out


def test_offload_curve_on_a_folder_stream(stream):
    out = stream['out']
    gt = json.load(open(out['ann_file']))
    frames = sorted(img['file_name'] for img in gt['images'])
    right = truth(gt)
    none = dict(labels=[], scores=[], bboxes=[])
    edge = {f: right[f] if f.startswith('clear/') else none for f in frames}
    tmp = stream['tmp']
    local = write_run(tmp / 'local', 'local', frames, edge,
                      lambda f: 0.4 if f.startswith('fog/') else 0.9)
    server = write_run(tmp / 'server', 'server', frames, right,
                       lambda f: 0.4 if f.startswith('fog/') else 0.9)
    # read as Foggy Cityscapes names, every real frame is 'clear'
    assert offload_curve(local, server, out['ann_file'], thresholds=[0.6],
                         random_seeds=(0, ), metrics=('bbox', ),
                         progress=lambda *_: None)['conditions'] == ['clear']
    res = offload_curve(local, server, out['ann_file'], thresholds=[0.6],
                        random_seeds=(0, ), metrics=('bbox', ),
                        conditions='folder', progress=lambda *_: None)
    assert res['conditions'] == ['clear', 'fog']
    rows = {r['policy']: r for r in res['rows']}
    stream_gt = stream_annotations(out['ann_file'], frames, 'folder')
    ref = cocoeval_ap(stream_gt, [dict(edge[f], masks=[None] *
                                       len(edge[f]['labels']))
                                  for f in frames], 'bbox')
    assert 0 < ref < 100
    assert rows['always local']['bbox_mAP'] == pytest.approx(ref, abs=0.1)
    haze = rows['haze: transmission < 0.6']
    assert haze['offloaded'] == {'clear': 0.0, 'fog': 1.0}
    assert haze['bbox_mAP'] == pytest.approx(100)
    assert rows['always local']['condition_ap']['fog']['bbox_mAP'] == 0
    assert rows['always local']['condition_ap']['clear']['bbox_mAP'] == \
        pytest.approx(100)
    tool = load_tool('projects/edge_serving/tools/offload_eval.py')
    tool.main([local, server, '--ann', out['ann_file'], '--conditions',
               'folder', '--boxes-only', '--thresholds', '0.6',
               '--out-dir', str(tmp / 'table')])
    md = (tmp / 'table' / 'offload.md').read_text()
    assert 'box AP clear | box AP fog' in md
    assert json.load(open(tmp / 'table' / 'offload.json'))[
        'condition_rule'] == 'folder'

"""cbnet_tools.quick_eval on configs alone: the files written, the cut
without a COCO file, malformed input. (Scores against a set of exactly
those images: tests/test_lab/test_num_images_tools.py.)"""
import json
import os.path as osp

import pytest
from mmengine.config import Config

from cbnet_tools.synthetic.voc_folder import tiny_fog_folder
from cbnet_tools.quick_eval import (_dataset_length, check_subset_scoring,
                                    first_images_cfg, subset_coco)


def coco(num_images, first_id=1):
    images = [dict(id=first_id + i, file_name=f'{i}.png', height=8,
                   width=8) for i in range(num_images)]
    anns = [dict(id=100 + i * 2 + j, image_id=img['id'], category_id=1,
                 bbox=[0, 0, 2, 2], area=4, iscrowd=0)
            for i, img in enumerate(images) for j in range(2)]
    return dict(info={'x': 1}, images=images, annotations=anns,
                categories=[dict(id=1, name='car')])


def write(path, data):
    with open(path, 'w') as f:
        json.dump(data, f)
    return str(path)


def make_config(root, ann='val.json', evaluators=None):
    return Config(dict(
        test_dataloader=dict(dataset=dict(
            type='CocoDataset', data_root=str(root) + '/', ann_file=ann)),
        val_evaluator=evaluators, test_evaluator=evaluators))


def test_cut_files_and_evaluators(tmp_path):
    write(tmp_path / 'val.json', coco(4))
    other = write(tmp_path / 'other.json', coco(6))  # a superset
    cfg = make_config(tmp_path, evaluators=[
        dict(type='CocoMetric', ann_file=str(tmp_path / 'val.json')),
        dict(type='CBNetInstanceMIoUMetric', ann_file=other),
        dict(type='DumpDetResults', out_file_path='x.pkl')])
    out = first_images_cfg(cfg, 2, str(tmp_path / 'cut'))
    ds = out.test_dataloader.dataset
    assert osp.isabs(ds.ann_file) and ds.get('indices') is None
    with open(ds.ann_file) as f:
        cut = json.load(f)
    assert [i['id'] for i in cut['images']] == [1, 2]
    assert sorted(a['image_id'] for a in cut['annotations']) == [1, 1, 2, 2]
    assert cut['info'] == {'x': 1} and cut['categories'][0]['name'] == 'car'
    coco_m, miou, dump = out.test_evaluator
    assert coco_m.ann_file == ds.ann_file  # the same file: written once
    with open(miou.ann_file) as f:
        assert [i['id'] for i in json.load(f)['images']] == [1, 2]
    assert 'ann_file' not in dump
    # the input config is unchanged
    assert cfg.test_dataloader.dataset.ann_file == 'val.json'
    assert cfg.test_evaluator[1].ann_file == other
    check_subset_scoring(out)  # no indices: nothing to refuse


def test_a_set_without_coco_file_is_cut_with_indices(tmp_path):
    tiny_fog_folder(str(tmp_path / 'fog'), num_images=10)
    cfg = Config(dict(
        test_dataloader=dict(dataset=dict(
            type='CBNetVOCFogDataset', data_root=str(tmp_path / 'fog'),
            ann_file='', split='val', test_mode=True)),
        test_evaluator=dict(type='CocoMetric', metric='bbox')))
    # the seeded val split of the 10 photos
    held = _dataset_length(cfg.test_dataloader.dataset, 'mmdet')
    assert 1 < held < 10
    out = first_images_cfg(cfg, held - 1, str(tmp_path))
    assert out.test_dataloader.dataset.indices == held - 1
    # more than the split holds: refused, as for a COCO file
    with pytest.raises(ValueError, match=f'num_images={held + 1} but the '
                       r'test set \(CBNetVOCFogDataset at .*\) holds '
                       f'{held} images'):
        first_images_cfg(cfg, held + 1, str(tmp_path))
    check_subset_scoring(out)  # the metric builds GT from the samples
    cfg.test_evaluator.ann_file = 'whole.json'
    with pytest.raises(ValueError, match='no COCO ann_file'):
        first_images_cfg(cfg, 3, str(tmp_path))


def test_indices_against_a_whole_file_is_refused(tmp_path):
    cfg = make_config(tmp_path, evaluators=dict(type='CocoMetric',
                                                ann_file='all.json'))
    cfg.test_dataloader.dataset.indices = 5
    with pytest.raises(ValueError, match='indices=5 .* every image of '
                       'all.json.*--num-images'):
        check_subset_scoring(cfg)
    with pytest.raises(ValueError, match='not both'):
        first_images_cfg(cfg, 2, str(tmp_path))


@pytest.mark.parametrize('num', [0, -1, True, 1.5, '2'])
def test_bad_num_images(tmp_path, num):
    write(tmp_path / 'val.json', coco(2))
    with pytest.raises(ValueError, match='positive integer'):
        first_images_cfg(make_config(tmp_path), num, str(tmp_path))


def test_malformed_sets(tmp_path):
    write(tmp_path / 'val.json', coco(2))
    with pytest.raises(ValueError, match='holds 2 images'):
        first_images_cfg(make_config(tmp_path), 3, str(tmp_path))
    with pytest.raises(FileNotFoundError, match='missing.json'):
        first_images_cfg(make_config(tmp_path, 'missing.json'), 1,
                         str(tmp_path))
    write(tmp_path / 'list.json', [1, 2])
    with pytest.raises(ValueError, match='not a COCO annotation file'):
        first_images_cfg(make_config(tmp_path, 'list.json'), 1,
                         str(tmp_path))
    # an evaluator's file without the tested images
    other = write(tmp_path / 'other.json', coco(2, first_id=50))
    with pytest.raises(KeyError, match=r'other.json has no image with id '
                       r'\[1\]'):
        first_images_cfg(make_config(tmp_path, evaluators=[dict(
            type='CocoMetric', ann_file=other)]), 1, str(tmp_path))
    wrapped = Config(dict(test_dataloader=dict(dataset=dict(
        type='ConcatDataset', datasets=[]))))
    with pytest.raises(ValueError, match='wrapper ConcatDataset'):
        first_images_cfg(wrapped, 1, str(tmp_path))


def test_subset_coco_keeps_order_of_the_file():
    data = coco(3)
    cut = subset_coco(data, [3, 1], 'f.json')
    assert [i['id'] for i in cut['images']] == [1, 3]
    assert len(cut['annotations']) == 4

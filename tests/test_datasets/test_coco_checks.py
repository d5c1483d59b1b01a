"""Value checks of the annotation file (cbnet_mmdet/datasets/coco_checks.py)
through the datasets: wrong content is one clear error naming the file, the
entry and the fix; what is dropped is logged per reason; labels go by
category name."""
import copy
import json
import re

import numpy as np
import pytest
from mmdet.registry import DATASETS
from mmengine.logging import MMLogger
from mmengine.registry import init_default_scope
from pycocotools import mask as mask_utils

import cbnet_mmdet  # noqa: F401

init_default_scope('mmdet')
CLASSES = ('person', 'rider', 'car', 'truck', 'bus', 'train', 'motorcycle',
           'bicycle')
#: Cityscapes label ids of CLASSES (the converter's category ids).
CAT_IDS = (24, 25, 26, 27, 28, 31, 32, 33)
H, W = 40, 60


def square(x, y, side):
    return [x, y, x + side, y, x + side, y + side, x, y + side]


def rle_of_rect(x, y, w, h):
    mask = np.zeros((H, W), np.uint8)
    mask[y:y + h, x:x + w] = 1
    rle = mask_utils.encode(np.asfortranarray(mask))
    rle['counts'] = rle['counts'].decode()
    return rle


def base_coco() -> dict:
    """Two images; a person (polygon) and a car (RLE) in the first, a
    bicycle (polygon) and a crowd region in the second."""
    images = [
        dict(id=1, file_name='a/a_000000_000019_leftImg8bit.png', height=H,
             width=W),
        dict(id=2, file_name='b/b_000000_000019_leftImg8bit.png', height=H,
             width=W),
    ]
    anns = [
        dict(id=1, image_id=1, category_id=24, iscrowd=0, area=100.0,
             bbox=[10.0, 10.0, 10.0, 10.0],
             segmentation=[square(10.0, 10.0, 10.0)]),
        dict(id=2, image_id=1, category_id=26, iscrowd=0, area=100,
             bbox=[30.0, 5.0, 10.0, 10.0],
             segmentation=rle_of_rect(30, 5, 10, 10)),
        dict(id=3, image_id=2, category_id=33, iscrowd=0, area=64.0,
             bbox=[5.0, 20.0, 8.0, 8.0], segmentation=[square(5., 20., 8.)]),
        dict(id=4, image_id=2, category_id=24, iscrowd=1, area=16,
             bbox=[40.0, 30.0, 4.0, 4.0],
             segmentation=rle_of_rect(40, 30, 4, 4)),
    ]
    cats = [dict(id=i, name=n) for i, n in zip(CAT_IDS, CLASSES)]
    return dict(images=images, annotations=anns, categories=cats)


def write(tmp_path, coco, name='train.json') -> str:
    path = tmp_path / name
    path.write_text(json.dumps(coco))  # NaN written as the token NaN
    return str(path)


def build(ann_file, kind='CBNetCityscapesDataset', **kwargs):
    kwargs.setdefault('filter_cfg', None)
    extra = dict(beta=0.02) if kind != 'CBNetCityscapesDataset' else {}
    return DATASETS.build(
        dict(type=kind, ann_file=ann_file,
             data_prefix=dict(img='leftImg8bit/train/'),
             check_files=False, pipeline=[], **extra, **kwargs))


def instances(ds):
    """(image file, box, class name, crowd) of every loaded instance."""
    out = []
    for i in range(len(ds)):
        info = ds.get_data_info(i)
        for inst in info['instances']:
            out.append((info['img_path'].split('/')[-1][0], inst['bbox'],
                        CLASSES[inst['bbox_label']], inst['ignore_flag']))
    return sorted(out)


EXPECTED = sorted([
    ('a', [10.0, 10.0, 20.0, 20.0], 'person', 0),
    ('a', [30.0, 5.0, 40.0, 15.0], 'car', 0),
    ('b', [5.0, 20.0, 13.0, 28.0], 'bicycle', 0),
    ('b', [40.0, 30.0, 44.0, 34.0], 'person', 1),
])


@pytest.fixture
def log_file(tmp_path):
    """A fresh current MMLogger writing to a file; returns a reader."""
    path = tmp_path / 'log.txt'
    MMLogger.get_instance(f'coco_checks_{tmp_path.name}', log_file=str(path),
                          log_level='INFO')
    return lambda: path.read_text()


def test_clean_file_loads_every_instance(tmp_path, log_file):
    ds = build(write(tmp_path, base_coco()))
    assert instances(ds) == EXPECTED
    log = log_file()
    assert re.search(r'CBNetCityscapesDataset \S+train.json: 2 images, 3 '
                     r'instances, 1 crowd regions; dropped annotations: '
                     r'none; left out by filter_cfg: 0 images', log), log


@pytest.mark.parametrize('kind', ['CBNetCityscapesDataset',
                                  'CBNetFoggyCityscapesDataset',
                                  'CBNetPairedFoggyDataset'])
@pytest.mark.parametrize('edit', ['drop_rider', 'reverse', 'drop_person'])
def test_labels_follow_category_names(tmp_path, kind, edit, log_file):
    coco = base_coco()
    cats = coco['categories']
    expected = EXPECTED
    if edit == 'drop_rider':  # an unused class missing: nothing shifts
        coco['categories'] = [c for c in cats if c['name'] != 'rider']
    elif edit == 'reverse':  # another order: same labels
        coco['categories'] = cats[::-1]
    else:  # a used class missing: its annotations dropped and logged
        coco['categories'] = [c for c in cats if c['name'] != 'person']
        expected = [e for e in EXPECTED if e[2] != 'person']
    ds = build(write(tmp_path, coco), kind)
    assert instances(ds) == expected
    if edit != 'reverse':
        missing = 'rider' if edit == 'drop_rider' else 'person'
        assert f"is named ['{missing}']: no instances" in log_file()
    if edit == 'drop_person':
        assert ds.load_report['drops'] == {'unknown_category': 2}


def mutate(coco, path, value):
    """Set ``coco[path[0]][path[1]][path[2]] = value``."""
    coco[path[0]][path[1]][path[2]] = value
    return coco


NAN = float('nan')
#: (what to change, new value, text the error must hold)
ERRORS = [
    (('images', 1, 'id'), 1, 'image 1 (\'b/b_000000_000019_leftImg8bit.png\')'
     ": id 1 is also the id of 'a/a_000000_000019_leftImg8bit.png'; image "
     'ids must be unique'),
    (('images', 0, 'id'), '1', "id must be an integer, got '1' (str)"),
    (('images', 1, 'file_name'), 'a/a_000000_000019_leftImg8bit.png',
     'file_name is listed twice'),
    (('images', 0, 'height'), 0, 'height must be a positive integer'),
    (('annotations', 0, 'image_id'), '1',
     "annotation 1 (image_id '1'): image_id must be an integer, got '1' "
     '(str)'),
    (('annotations', 0, 'image_id'), 1.0, 'image_id must be an integer'),
    (('annotations', 1, 'id'), 1, 'id must be an integer unique'),
    (('annotations', 0, 'category_id'), 'person',
     'category_id must be an integer'),
    (('annotations', 0, 'iscrowd'), '0',
     "iscrowd must be the integer 0 or 1, got '0' (str); write 0"),
    (('annotations', 0, 'iscrowd'), 2, 'iscrowd must be the integer 0 or 1'),
    (('annotations', 0, 'area'), None, 'area must be a finite number'),
    (('annotations', 0, 'segmentation'), [[10., 10., 1e30, 10., 20., 20.]],
     'polygon points outside the 60x40 image'),
    (('annotations', 0, 'segmentation'), [[10., 10., NAN, 10., 20., 20.]],
     'polygon coordinates must be finite numbers, got nan'),
    (('annotations', 0, 'segmentation'), [[10., 10., '20', 10., 20., 20.]],
     "polygon coordinates must be finite numbers, got '20'"),
    (('annotations', 1, 'segmentation'), dict(size=[H, W], counts='0<'),
     'RLE counts sum to 12 pixels, not height x width = 2400'),
    (('annotations', 1, 'segmentation'), dict(size=[H, W], counts=[5, 2400]),
     'RLE counts sum to 2405 pixels'),
    (('annotations', 1, 'segmentation'), dict(size=[H, W], counts=[5, -5]),
     'undecodable RLE counts'),
    (('annotations', 0, 'bbox'), [30.0, 10.0, 10.0, 10.0],
     'bbox [30.0, 10.0, 10.0, 10.0] disagrees with its mask, which spans '
     'x1, y1, x2, y2 = [10.0, 10.0, 20.0, 20.0]'),
    (('annotations', 1, 'bbox'), [30.0, 5.0, 20.0, 10.0],
     'disagrees with its mask, which spans x1, y1, x2, y2 = [30.0, 5.0, '
     '40.0, 15.0]'),
    (('categories', 1, 'name'), 'person', "category name 'person' is listed "
     'twice'),
    (('categories', 1, 'id'), 24, 'category id 24 is listed twice'),
]


@pytest.mark.parametrize('path,value,problem', ERRORS,
                         ids=[f'{p[0]}.{p[2]}={v!r}'[:40]
                              for p, v, _ in ERRORS])
def test_wrong_content_is_one_clear_error(tmp_path, path, value, problem):
    ann_file = write(tmp_path, mutate(base_coco(), path, value))
    with pytest.raises(ValueError) as err:
        build(ann_file)
    assert str(err.value).startswith(f'annotation file {ann_file}: ')
    assert problem in str(err.value)


@pytest.mark.parametrize('content,problem', [
    ([1, 2], 'top level: must be a JSON object with "images", '
     '"annotations" and "categories", got a list (convert the dataset with '
     'tools/dataset_converters/cityscapes.py)'),
    (dict(images=[], annotations={}, categories=[]),
     '"annotations": must be a list, got dict'),
])
def test_top_level_errors(tmp_path, content, problem):
    ann_file = write(tmp_path, content)
    with pytest.raises(ValueError) as err:
        build(ann_file)
    assert str(err.value) == f'annotation file {ann_file}: {problem}'


def drop_cases(coco):
    """One annotation per drop reason, ids 11.. (image 1 unless said)."""
    extra = [
        dict(category_id=999),  # unknown category
        dict(bbox=[100.0, 100.0, 5.0, 5.0],
             segmentation=[square(100., 100., 5.)]),  # outside the image
        dict(bbox=[10.0, 10.0, 0.5, 10.0],
             segmentation=[[10., 10., 10.5, 10., 10.5, 20.]]),  # < 1 px
        dict(area=0),
        dict(ignore=True),
        dict(image_id=77),  # no such image
    ]
    template = coco['annotations'][0]
    for i, change in enumerate(extra):
        coco['annotations'].append(dict(copy.deepcopy(template), id=11 + i,
                                        **change))
    coco['categories'].append(dict(id=7, name='ego vehicle'))
    coco['annotations'].append(dict(copy.deepcopy(template), id=20,
                                    category_id=7))
    return coco


def test_drops_are_logged_per_reason_and_strict_raises(tmp_path, log_file):
    ann_file = write(tmp_path, drop_cases(base_coco()))
    ds = build(ann_file)
    assert instances(ds) == EXPECTED  # nothing else lost, labels kept
    drops = dict(unknown_category=1, outside_image=1, below_1px=1,
                 zero_area=1, ignore=1, unknown_image=1, other_class=1)
    assert ds.load_report['drops'] == drops
    assert ds.load_report['annotations'] == 4 + 7
    log = log_file()
    assert (f'dropped 7 of 11 annotations of {ann_file}: 1 box width or '
            'height < 1 px (ids 13), 1 marked "ignore": true (ids 15), 1 '
            'category is not one of the dataset classes (ids 20), 1 box '
            'fully outside its image (ids 12), 1 category_id not in '
            '"categories" (ids 11), 1 image_id not in "images" (ids 16), 1 '
            'area <= 0 (ids 14)') in log
    assert ('dropped annotations: below_1px 1, ignore 1, other_class 1, '
            'outside_image 1, unknown_category 1, unknown_image 1, '
            'zero_area 1;') in log
    with pytest.raises(ValueError) as err:
        build(ann_file, strict=True)
    assert str(err.value).startswith(
        f'annotation file {ann_file}: strict mode: 7 annotation(s) would be '
        'dropped: 1 box width or height < 1 px (ids 13)')


def test_filter_cfg_counts_in_the_summary(tmp_path, log_file):
    coco = base_coco()
    coco['annotations'][2]['iscrowd'] = 1  # image b: only crowd regions
    ds = build(write(tmp_path, coco),
               filter_cfg=dict(filter_empty_gt=True, min_size=0))
    assert len(ds) == 1
    assert ds.load_report['filtered_images'] == 1
    assert ds.load_report['filtered_instances'] == 2
    assert ('1 images, 2 instances, 0 crowd regions; dropped annotations: '
            'none; left out by filter_cfg: 1 images (2 instances)'
            ) in log_file()


def reference_runs(mask: np.ndarray) -> list:
    """Run lengths of a mask in COCO's order (column-major, zeros first),
    computed with NumPy."""
    flat = mask.flatten(order='F')
    change = np.flatnonzero(np.diff(flat)) + 1
    edges = np.concatenate([[0], change, [flat.size]])
    runs = np.diff(edges).tolist()
    return ([0] + runs) if flat[0] else runs


@pytest.mark.parametrize('seed', range(4))
def test_rle_string_counts_match_numpy_runs(seed):
    from cbnet_mmdet.datasets.coco_checks import rle_string_counts
    rng = np.random.default_rng(seed)
    mask = (rng.random((37, 53)) < [0.02, 0.5, 0.98][seed % 3]).astype(
        np.uint8)
    if seed == 3:
        mask[:] = 1
    counts = mask_utils.encode(np.asfortranarray(mask))['counts'].decode()
    runs = rle_string_counts(counts)
    assert runs == reference_runs(mask)
    assert sum(runs) == mask.size


def test_rle_string_counts_rejects_garbage():
    from cbnet_mmdet.datasets.coco_checks import rle_string_counts
    for bad in ('!!!!', '0\x7f', 'P'):  # bad char, bad char, cut number
        with pytest.raises(ValueError):
            rle_string_counts(bad)
    assert rle_string_counts('') == []


def test_not_utf8_is_a_clear_error_and_nothing_kept(tmp_path):
    path = tmp_path / 'latin1.json'
    path.write_bytes(b'{"images": [], "x": "\xe9"}')
    with pytest.raises(ValueError, match=f'annotation file {path} is not '
                       'valid JSON'):
        build(str(path))
    ds = build(write(tmp_path, base_coco()))
    assert 'COCOAPI' not in vars(ds)  # the checked dict is not kept

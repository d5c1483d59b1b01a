"""CBNetVOCFogDataset: VOC real-fog folders as the 8 Cityscapes classes,
the seeded split, and clear errors on broken annotations."""
import os.path as osp
import xml.etree.ElementTree as ET
from collections import Counter

import pytest
from mmengine.registry import init_default_scope

from cbnet_mmdet.datasets import CBNetVOCFogDataset
from cbnet_tools.synthetic.voc_folder import voc_xml, write_voc_folder
from cbnet_mmdet.datasets.voc_fog import CITYSCAPES_CLASSES, seeded_split

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__))))
#: The DAWN fog copy next to the checkout (CI has it; skipped elsewhere).
DAWN = osp.join(ROOT, '..', 'shared', 'data', 'dawn_fog')


@pytest.fixture(autouse=True)
def _scope():
    init_default_scope('mmdet')


def build(root, **kwargs):
    kwargs.setdefault('ann_file', '')
    if kwargs['ann_file'] == '':
        kwargs.setdefault('split', 'train')
    return CBNetVOCFogDataset(data_root=str(root), pipeline=[], **kwargs)


def voc_fields(path):
    """(class name, box floats, difficult) of every object, read with
    ElementTree independently of the dataset."""
    out = []
    for obj in ET.parse(path).getroot().iter('object'):
        box = [float(obj.find(f'bndbox/{k}').text)
               for k in ('xmin', 'ymin', 'xmax', 'ymax')]
        out.append((obj.find('name').text, box,
                    int(obj.find('difficult').text)))
    return out


def test_names_are_mapped_onto_cityscapes_labels(tmp_path):
    write_voc_folder(str(tmp_path), {
        'a': [('car', (10, 20, 60, 50)), ('motorbike', (1, 2, 30, 40), 1)],
        'b': [('person', (0, 0, 160, 96)), ('bus', (5.5, 6, 70.25, 80))],
        'c': [],
    })
    ds = build(tmp_path, split='train', val_fraction=0.34)
    # 3 images: round(0.34 * 3) = 1 val, 2 train
    assert len(ds) + len(build(tmp_path, split='val',
                               val_fraction=0.34)) == 3
    everything = {}
    for split in ('train', 'val'):
        d = build(tmp_path, split=split, val_fraction=0.34, test_mode=True)
        for i in range(len(d)):
            info = d.get_data_info(i)
            everything[info['img_id']] = info
    assert sorted(everything) == ['a', 'b', 'c']
    renamed = {'motorbike': 'motorcycle'}
    for img_id, info in everything.items():
        assert info['width'] == 160 and info['height'] == 96
        assert info['img_path'] == osp.join(str(tmp_path), 'JPEGImages',
                                            f'{img_id}.jpg')
        expected = voc_fields(tmp_path / 'Annotations' / f'{img_id}.xml')
        got = info['instances']
        assert len(got) == len(expected)
        for inst, (name, box, difficult) in zip(got, expected):
            name = renamed.get(name, name)
            assert CITYSCAPES_CLASSES[inst['bbox_label']] == name
            assert inst['bbox'] == box  # as written, no minus-one
            assert inst['ignore_flag'] == difficult
    assert ds.metainfo['classes'] == CITYSCAPES_CLASSES


def test_unknown_names_are_listed_or_ignored(tmp_path):
    write_voc_folder(str(tmp_path), {
        'a': [('car', (1, 1, 9, 9)), ('van', (1, 1, 9, 9)),
              ('van', (2, 2, 9, 9))],
        'b': [('tricycle', (1, 1, 9, 9))],
    })
    (tmp_path / 'all.txt').write_text('a\nb\n')
    with pytest.raises(ValueError) as err:
        build(tmp_path, ann_file='all.txt')
    msg = str(err.value)
    # both names, with their counts over all images and a file each
    assert "'tricycle' (1x" in msg and "'van' (2x" in msg
    assert 'b.xml' in msg and 'a.xml' in msg
    assert 'name_map' in msg and 'ignore_names' in msg
    ds = build(tmp_path, split='val', val_fraction=0.5,
               ignore_names=['van', 'tricycle'], test_mode=True)
    ds_other = build(tmp_path, split='train', val_fraction=0.5,
                     ignore_names=['van', 'tricycle'], test_mode=True)
    counts = Counter(CITYSCAPES_CLASSES[i['bbox_label']]
                     for d in (ds, ds_other) for k in range(len(d))
                     for i in d.get_data_info(k)['instances'])
    assert counts == {'car': 1}
    # mapped instead: van -> car (the default motorbike map is replaced)
    mapped = [build(tmp_path, split=s, val_fraction=0.5, test_mode=True,
                    name_map={'van': 'car', 'tricycle': 'bicycle'})
              for s in ('train', 'val')]
    counts = Counter(CITYSCAPES_CLASSES[i['bbox_label']]
                     for d in mapped for k in range(len(d))
                     for i in d.get_data_info(k)['instances'])
    assert counts == {'car': 3, 'bicycle': 1}
    with pytest.raises(ValueError, match=r"\['lorry'\]"):
        build(tmp_path, name_map={'van': 'lorry'})


def test_seeded_split_is_a_partition_fixed_by_seed():
    ids = [f'img{k:02d}' for k in range(20)]
    val = seeded_split(ids[::-1], 'val', 0.3, seed=0)  # order-free
    train = seeded_split(ids, 'train', 0.3, seed=0)
    assert len(val) == 6 and len(train) == 14
    assert sorted(val + train) == ids
    assert val == seeded_split(ids, 'val', 0.3, seed=0)
    assert val != seeded_split(ids, 'val', 0.3, seed=1)
    assert len(seeded_split(ids, 'val', 0.25, seed=0)) == 5
    with pytest.raises(ValueError, match='split must be one of'):
        seeded_split(ids, 'test')
    with pytest.raises(ValueError, match='val_fraction'):
        seeded_split(ids, 'val', 1.0)


def test_image_set_file(tmp_path):
    write_voc_folder(str(tmp_path), {
        'a': [('car', (1, 1, 9, 9))],
        'b': [('bus', (1, 1, 9, 9))],
        'c': [('bicycle', (1, 1, 9, 9))],
    })
    (tmp_path / 'ImageSets').mkdir()
    (tmp_path / 'ImageSets' / 'test.txt').write_text('c\na\n\n')
    ds = build(tmp_path, ann_file='ImageSets/test.txt', test_mode=True)
    assert [ds.get_data_info(i)['img_id'] for i in range(len(ds))] == \
        ['c', 'a']
    with pytest.raises(ValueError, match='not both'):
        build(tmp_path, ann_file='ImageSets/test.txt', split='val')
    with pytest.raises(FileNotFoundError, match='image-set file not found'):
        build(tmp_path, ann_file='ImageSets/nope.txt')
    with pytest.raises(ValueError, match="needs split='train'"):
        build(tmp_path, ann_file='', split=None)


def write_one(tmp_path, text, img=True):
    write_voc_folder(str(tmp_path), {'ok': [('car', (1, 1, 9, 9))]})
    path = tmp_path / 'Annotations' / 'bad.xml'
    path.write_text(text)
    if img:
        (tmp_path / 'JPEGImages' / 'bad.jpg').write_bytes(
            (tmp_path / 'JPEGImages' / 'ok.jpg').read_bytes())
    (tmp_path / 'ImageSets').mkdir(exist_ok=True)
    (tmp_path / 'ImageSets' / 'all.txt').write_text('ok\nbad\n')
    return 'bad.xml'


@pytest.mark.parametrize('text,match', [
    ('', 'empty file'),
    ('<annotation><object>', 'malformed XML'),
    ('not xml at all', 'malformed XML'),
    (voc_xml('bad.jpg', None, [('car', (1, 1, 9, 9))]),
     r'<size><width> must be a positive integer, got None'),
    (voc_xml('bad.jpg', (0, 96), []), 'positive integer'),
    (voc_xml('bad.jpg', (160, 96), [('car', (1, 1, 161, 9))]),
     r'object 0 box \[1.0, 1.0, 161.0, 9.0\].*not inside its 160x96'),
    (voc_xml('bad.jpg', (160, 96), [('car', (5, 1, 5, 9))]),
     'has no area'),
    (voc_xml('bad.jpg', (160, 96), [('car', (-1, 1, 9, 9))]),
     'clip_to_image=True'),
    (voc_xml('bad.jpg', (160, 96), [('car', (1, 'x', 9, 9))]),
     'object 0 needs <bndbox> with numeric'),
    (voc_xml('bad.jpg', (160, 96), [('', (1, 1, 9, 9))]),
     'object 0 has no <name>'),
])
def test_broken_annotations_are_clear_errors(tmp_path, text, match):
    name = write_one(tmp_path, text)
    with pytest.raises(ValueError, match=match) as err:
        build(tmp_path, ann_file='ImageSets/all.txt', test_mode=True)
    assert name in str(err.value)


def test_clip_to_image_clips_and_counts(tmp_path):
    write_one(tmp_path, voc_xml('bad.jpg', (160, 96),
                                [('car', (-3, 1, 170, 9)),
                                 ('car', (1, 1, 9, 9))]))
    ds = build(tmp_path, ann_file='ImageSets/all.txt', test_mode=True,
               clip_to_image=True)
    boxes = [i['bbox'] for i in ds.get_data_info(1)['instances']]
    assert boxes == [[0.0, 1.0, 160.0, 9.0], [1.0, 1.0, 9.0, 9.0]]
    assert ds._stats == {'boxes clipped to their image': 1}
    # a box wholly outside cannot be clipped into one
    write_one(tmp_path, voc_xml('bad.jpg', (160, 96),
                                [('car', (170, 1, 180, 9))]))
    with pytest.raises(ValueError, match='not inside'):
        build(tmp_path, ann_file='ImageSets/all.txt', clip_to_image=True)


def test_missing_files_and_folders(tmp_path):
    write_one(tmp_path, voc_xml('bad.jpg', (160, 96), []), img=False)
    with pytest.raises(FileNotFoundError, match=r"1 image\(s\).*bad.jpg"):
        build(tmp_path, ann_file='ImageSets/all.txt')
    build(tmp_path, ann_file='ImageSets/all.txt', check_files=False)
    with pytest.raises(FileNotFoundError, match="img_suffix='.png'"):
        build(tmp_path, ann_file='ImageSets/all.txt', img_suffix='.png')
    (tmp_path / 'ImageSets' / 'all.txt').write_text('ok\ngone\n')
    with pytest.raises(FileNotFoundError, match='gone.xml'):
        build(tmp_path, ann_file='ImageSets/all.txt')
    with pytest.raises(FileNotFoundError, match='annotation folder not'):
        build(tmp_path / 'nowhere')
    (tmp_path / 'empty' / 'Annotations').mkdir(parents=True)
    with pytest.raises(ValueError, match='no .xml annotation'):
        build(tmp_path / 'empty')


def test_no_training_image_left_is_an_error(tmp_path):
    write_voc_folder(str(tmp_path), {'a': [], 'b': []})
    with pytest.raises(ValueError, match='no training image left'):
        build(tmp_path, split='train', val_fraction=0.5,
              filter_cfg=dict(filter_empty_gt=True))


def test_images_left_out_by_the_filter_are_counted(tmp_path):
    import logging

    from mmengine.logging import MMLogger
    write_voc_folder(str(tmp_path), {
        'a': [('car', (1, 1, 20, 20))], 'b': [], 'c': [],
        'd': [('person', (2, 2, 30, 40))]})
    records = []
    handler = logging.Handler()
    handler.emit = records.append
    logger = MMLogger.get_current_instance()
    logger.addHandler(handler)
    try:
        ds = build(tmp_path, split='train', val_fraction=0.0001,
                   filter_cfg=dict(filter_empty_gt=True))
    finally:
        logger.removeHandler(handler)
    assert len(ds) == 2
    lines = [r.getMessage() for r in records]
    assert any('(train): 2 images kept, 2 left out by filter_cfg' in line
               for line in lines), lines


@pytest.mark.skipif(not osp.isdir(DAWN), reason='no DAWN copy at '
                    '../shared/data/dawn_fog')
def test_dawn_fog_copy_reads_with_its_documented_counts():
    """docs/robustness.md's counts (218 photos; car 944, person 101,
    truck 74, bus 47, motorcycle 19, bicycle 10) over the two seeded
    subsets."""
    counts, sizes = Counter(), {}
    for split in ('train', 'val'):
        ds = CBNetVOCFogDataset(data_root=DAWN, ann_file='', split=split,
                                test_mode=True, pipeline=[])
        sizes[split] = len(ds)
        counts.update(CITYSCAPES_CLASSES[i['bbox_label']]
                      for k in range(len(ds))
                      for i in ds.get_data_info(k)['instances'])
    assert sizes == dict(train=153, val=65)
    assert counts == dict(car=944, person=101, truck=74, bus=47,
                          motorcycle=19, bicycle=10)


def _pipelines():
    """The shipped real-fog train and test pipelines (their config)."""
    from mmengine.config import Config
    cfg = Config.fromfile(osp.join(ROOT, 'configs', 'realfog', '_base_',
                                   'voc-fog_box.py'))
    return cfg.fog_train_pipeline, cfg.fog_test_pipeline


def _with_orientation(path, value):
    """Rewrite a JPEG with an EXIF orientation tag (pixels unchanged)."""
    from PIL import Image
    with Image.open(path) as img:
        img.load()
        exif = img.getexif()
        exif[0x0112] = value
        img.save(path, exif=exif.tobytes(), quality=95)


@pytest.mark.parametrize('pipeline', ['train', 'test'])
@pytest.mark.parametrize('case', ['half-size xml', 'exif 90', 'exif 180'])
def test_images_that_do_not_fit_their_xml_are_errors(tmp_path, pipeline,
                                                     case):
    """Training and testing apply one rule: an XML whose <size> belongs to
    another copy of the image, and an EXIF-oriented JPEG (90: the decoder
    turns it, the size disagrees; 180: the size agrees and the boxes lie
    on other pixels), are errors naming the file. Before, the test path
    scored all three, and training the 180 one, without a word."""
    write_voc_folder(str(tmp_path), {
        n: [('car', (10, 20, 60, 50))] for n in 'abcd'})
    img = tmp_path / 'JPEGImages' / 'a.jpg'
    if case == 'half-size xml':
        (tmp_path / 'Annotations' / 'a.xml').write_text(
            voc_xml('a.jpg', (80, 48), [('car', (5, 10, 30, 25))]))
    else:
        _with_orientation(img, 6 if case == 'exif 90' else 3)
    train, test = _pipelines()
    (tmp_path / 'ImageSets').mkdir()
    (tmp_path / 'ImageSets' / 'all.txt').write_text('a\nb\nc\nd\n')
    ds = CBNetVOCFogDataset(
        data_root=str(tmp_path), ann_file='ImageSets/all.txt',
        test_mode=pipeline == 'test',
        pipeline=train if pipeline == 'train' else test)
    index = 0  # 'a', the image set's first
    match = {'half-size xml': 'is 96x160 .HxW. but its annotations say '
             '48x80', 'exif 90': 'carries EXIF orientation 6',
             'exif 180': 'carries EXIF orientation 3'}[case]
    with pytest.raises(ValueError, match=match) as err:
        ds[index]
    assert str(img) in str(err.value)
    # the other images of the folder load as before
    other = (index + 1) % len(ds)
    assert ds[other]['data_samples'].ori_shape == (96, 160)


def test_exif_orientation_accepted_where_it_cannot_mislead(tmp_path):
    """A photo without annotations (DetInferencer's data: no height and
    width) keeps the decoder's upright image; `allow_exif_orientation`
    (pixels read as stored) accepts an annotated one."""
    import numpy as np
    from cbnet_mmdet.datasets.transforms import CBNetCheckImage
    write_voc_folder(str(tmp_path), {'a': [('car', (10, 20, 60, 50))]})
    path = str(tmp_path / 'JPEGImages' / 'a.jpg')
    _with_orientation(path, 3)
    img = np.zeros((96, 160, 3), np.uint8)
    CBNetCheckImage().transform(dict(img=img, img_path=path))
    annotated = dict(img=img, img_path=path, height=96, width=160)
    with pytest.raises(ValueError, match='EXIF orientation 3'):
        CBNetCheckImage().transform(dict(annotated))
    CBNetCheckImage(allow_exif_orientation=True).transform(dict(annotated))
    with pytest.raises(ValueError, match='is 96x160 .* annotations say '
                       '48x80'):
        CBNetCheckImage(allow_exif_orientation=True).transform(
            dict(annotated, height=48, width=80))

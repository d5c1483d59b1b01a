"""The class map of COCO detectors onto other label sets
(cbnet_mmdet/utils/class_map.py), against names written out here."""
import pytest

from cbnet_mmdet.datasets.voc_fog import CITYSCAPES_CLASSES
from cbnet_mmdet.utils import class_map as cm

#: The project's 8 classes and their COCO labels (MMDet's order: person 0,
#: bicycle 1, car 2, motorcycle 3, bus 5, train 6, truck 7), typed out.
EXPECTED = {'person': 0, 'rider': 0, 'car': 2, 'truck': 7, 'bus': 5,
            'train': 6, 'motorcycle': 3, 'bicycle': 1}
VOC = ('aeroplane', 'bicycle', 'bird', 'boat', 'bottle', 'bus', 'car', 'cat',
       'chair', 'cow', 'diningtable', 'dog', 'horse', 'motorbike', 'person',
       'pottedplant', 'sheep', 'sofa', 'train', 'tvmonitor')


def test_coco_has_its_80_classes_in_mmdets_order():
    coco = cm.coco_classes()
    assert len(coco) == 80 and coco[:3] == ('person', 'bicycle', 'car')
    assert coco[-1] == 'toothbrush'


def test_the_street_classes_take_cocos_of_the_same_names():
    assert cm.class_sources(CITYSCAPES_CLASSES) == [
        EXPECTED[n] for n in CITYSCAPES_CLASSES]
    targets = cm.label_targets(CITYSCAPES_CLASSES)
    assert len(targets) == 80
    # a person box is scored as person and as rider; a dog as nothing
    assert targets[0] == [CITYSCAPES_CLASSES.index('person'),
                          CITYSCAPES_CLASSES.index('rider')]
    assert targets[cm.coco_classes().index('dog')] == []
    assert 'rider <- person' in cm.describe_map(CITYSCAPES_CLASSES)


def test_every_voc_class_has_a_coco_class():
    sources = cm.class_sources(VOC)
    coco = cm.coco_classes()
    assert None not in sources
    named = dict(zip(VOC, (coco[s] for s in sources)))
    assert named['motorbike'] == 'motorcycle' and named['sofa'] == 'couch'
    assert named['tvmonitor'] == 'tv' and named['cow'] == 'cow'


def test_own_names_win_and_unmapped_classes_are_none():
    # a source that has 'rider' itself uses it, not the alias
    assert cm.class_sources(['rider', 'person'], ['person', 'rider']) == \
        [1, 0]
    assert cm.class_sources(['road sign'], 'coco') == [None]
    assert 'road sign <- (none' in cm.describe_map(['road sign'])


@pytest.mark.parametrize('kwargs,match', [
    (dict(target=['car'], source='voc'), "a sequence of names or 'coco'"),
    (dict(target=[], source='coco'), 'must not be empty'),
    (dict(target=['car', 'car']), r"given twice: \['car'\]"),
    (dict(target=['rider'], source=['car']), "scored as 'person', which"),
    (dict(target=['van'], aliases={'van': 'lorry'}),
     "'van' is to be scored as 'lorry'"),
])
def test_bad_maps_are_clear_errors(kwargs, match):
    with pytest.raises(ValueError, match=match):
        cm.class_sources(**kwargs)

"""tools/dataset_converters/coco_street.py on small COCO dicts: names
matched as COCO spells them whatever their case, malformed files as
errors naming the entry, and never an empty split written silently."""
import json

import pytest
from tool_helpers import load_tool


def coco(names=('person', 'car', 'dog'), num_images=6):
    cats = [dict(id=i, name=n) for i, n in enumerate(names, 1)]
    images = [dict(id=i, file_name=f'{i}.jpg', width=64, height=48)
              for i in range(1, num_images + 1)]
    anns = [dict(id=10 + i, image_id=i, category_id=1 + i % len(names),
                 bbox=[1, 1, 10, 10], area=100, iscrowd=0,
                 segmentation=[[1, 1, 11, 1, 11, 11]])
            for i in range(1, num_images + 1)]
    return dict(images=images, annotations=anns, categories=cats)


@pytest.fixture(scope='module')
def tool():
    return load_tool('dataset_converters/coco_street.py')


def test_capitalised_names_are_cocos(tool):
    lower = tool.convert(coco())
    upper = tool.convert(coco(names=('Person', 'Car ', 'Dog')))
    assert upper['stats'] == lower['stats']
    assert lower['stats']['kept'] == {'person': 2, 'car': 2}
    assert lower['stats']['dropped'] == 2


@pytest.mark.parametrize('edit,match', [
    (lambda c: c['images'].append('x.jpg'), r"images\[6\] is str 'x.jpg'"),
    (lambda c: c['images'][0].pop('file_name'),
     r"images\[0\] \(id 1\) has no \['file_name'\]"),
    (lambda c: c['categories'][1].pop('name'),
     r"categories\[1\] \(id 2\) has no \['name'\]"),
    (lambda c: c['annotations'][2].pop('category_id'),
     r"annotations\[2\] \(id 13\) has no \['category_id'\]"),
    (lambda c: c.update(annotations=None), "no 'annotations' list"),
])
def test_malformed_entries_are_named(tool, edit, match):
    data = coco()
    edit(data)
    with pytest.raises(ValueError, match=match):
        tool.convert(data)


def test_no_street_class_at_all_is_an_error(tool, tmp_path):
    data = coco(names=('Dog', 'Cat'))
    with pytest.raises(ValueError, match=r"no annotation of a street "
                       r"class: the categories are \['Cat', 'Dog'\]"):
        tool.convert(data)
    # the command: an error, nothing written
    (tmp_path / 'coco' / 'annotations').mkdir(parents=True)
    (tmp_path / 'coco' / 'images').mkdir()
    (tmp_path / 'coco' / 'annotations' / 'instances.json').write_text(
        json.dumps(data))
    with pytest.raises(ValueError, match='no annotation of a street'):
        tool.main([str(tmp_path / 'coco'), str(tmp_path / 'out')])
    assert not (tmp_path / 'out' / 'annotations').exists()

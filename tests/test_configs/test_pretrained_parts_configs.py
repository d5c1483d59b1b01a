"""configs/pretrained/parts/: the real-fog box recipes on the pretrained
MobileNetV2 with ONE part swapped. The stock Cascade R-CNN and the revised
CBNet's box path differ in three parts there (neck, RPN, stage IoUs); each
config is one of the two with one of them taken from the other, whole."""
import os.path as osp

import pytest
from config_parts import assert_takes_part, diff, model_of, owner

from cbnet_lab import config_edits as ce
from cbnet_lab import recipe_comparison as rc

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__))))
PRETRAINED = osp.join(ROOT, 'configs', 'pretrained')
PARTS = osp.join(PRETRAINED, 'parts')
#: The two whole recipes at the full trunk lr (the parts set's setting)
STOCK = osp.join(PRETRAINED, 'finetune', 'cascade-rcnn_mobilenet-v2_fpn_'
                 '1xb2-ft-trunk-lr1_dawn-fog.py')
REVISED = osp.join(PRETRAINED, 'finetune', 'cbnet-revised-box_mobilenet-'
                   'v2_nasfpn-crpn_1xb2-ft-trunk-lr1_dawn-fog.py')
#: (config file under configs/pretrained/, the recipe it starts from, the
#: part it swaps)
SWAPS = [
    ('parts/cascade-rcnn_mobilenet-v2_nasfpn_1xb2-ft-trunk-lr1_dawn-fog.py',
     'stock', 'neck'),
    ('parts/cascade-rcnn_mobilenet-v2_fpn-crpn-reg1_1xb2-ft-trunk-lr1_'
     'dawn-fog.py', 'stock', 'rpn'),
    ('parts/cascade-rcnn_mobilenet-v2_fpn-iou579_1xb2-ft-trunk-lr1_'
     'dawn-fog.py', 'stock', 'iou'),
    # shipped as the CBNet recipe for pretrained trunks
    ('cbnet-pt-box_mobilenet-v2_fpn-crpn_1xb2-ft-trunk-lr1_dawn-fog.py',
     'revised', 'neck'),
    ('finetune/cbnet-revised-box_mobilenet-v2_nasfpn-rpn_1xb2-ft-trunk-lr1_'
     'dawn-fog.py', 'revised', 'rpn'),
    ('parts/cbnet-revised-box_mobilenet-v2_nasfpn-crpn-iou567_1xb2-ft-'
     'trunk-lr1_dawn-fog.py', 'revised', 'iou'),
]


@pytest.fixture(scope='module')
def recipes():
    return dict(stock=model_of(STOCK), revised=model_of(REVISED))


def test_neck_rpn_and_ious_are_every_difference(recipes):
    differing = diff(recipes['stock'], recipes['revised'])
    parts = {p for k in differing for p in owner(k)}
    unowned = sorted(k for k in differing if not owner(k))
    assert not unowned, f'differences no part accounts for: {unowned}'
    assert parts == {'neck', 'rpn', 'iou'}


@pytest.mark.parametrize('config,start,part', SWAPS,
                         ids=[s[0] for s in SWAPS])
def test_each_config_swaps_exactly_one_part(recipes, config, start, part):
    base = recipes[start]
    other = recipes['revised' if start == 'stock' else 'stock']
    row = model_of(osp.join(PRETRAINED, config))
    assert_takes_part(base, row, part, other, config)


def test_the_set_lists_both_recipes_and_every_swap_once():
    rows = rc.RECIPE_SETS['realfog_pretrained_parts']
    paths = [osp.normpath(osp.join(ce.configs_root(), p)) for _, p in rows]
    names = [n for n, _ in rows]
    assert len(set(names)) == len(names) == len(set(paths))
    expected = {STOCK, REVISED} | {
        osp.normpath(osp.join(PRETRAINED, c)) for c, _, _ in SWAPS}
    assert set(paths) == expected
    # the two recipes keep their realfog_pretrained_finetune names, so
    # run in the same work dir the sets share those runs
    fog = dict(rc.RECIPE_SETS['realfog_pretrained_finetune'])
    for name, path in rows:
        if name in fog:
            assert fog[name] == path

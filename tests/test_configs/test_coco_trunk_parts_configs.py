"""configs/coco_trunk/parts/: the stock Cascade Mask R-CNN on YOLOX-Nano's
COCO trunk with ONE part of CBNet taken in. The stock recipe and CBNet-PT
differ in three parts there (mask loss, RPN, stage IoUs); each of the
first three configs takes one of them from CBNet-PT, whole; the fourth
takes the paper's one mask head on the last stage (which CBNet-PT does not
keep)."""
import os.path as osp

import pytest
from config_parts import assert_takes_part, diff, model_of, owner

from cbnet_lab import config_edits as ce
from cbnet_lab import recipe_comparison as rc

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__))))
COCO_TRUNK = osp.join(ROOT, 'configs', 'coco_trunk')
STOCK = osp.join(COCO_TRUNK, 'cascade-mask-rcnn_yolox-nano-coco_fpn_'
                 '1xb2-ft_coco-street.py')
CBNET_PT = osp.join(COCO_TRUNK, 'cbnet-pt_yolox-nano-coco_fpn-crpn_'
                    '1xb2-ft_coco-street.py')
#: the paper's RoI head (configs/demo/parts/_base_/parts.py)
PAPER_ROI_HEAD = 'CBNetCascadeRoIHead'
#: (config file under configs/coco_trunk/parts/, the part it takes in)
SWAPS = [
    ('cascade-mask-rcnn_yolox-nano-coco_fpn-boundary-loss_1xb2-ft_'
     'coco-street.py', 'mask loss'),
    ('cascade-mask-rcnn_yolox-nano-coco_fpn-crpn-reg1_1xb2-ft_'
     'coco-street.py', 'rpn'),
    ('cascade-mask-rcnn_yolox-nano-coco_fpn-iou579_1xb2-ft_'
     'coco-street.py', 'iou'),
    ('cascade-mask-rcnn_yolox-nano-coco_fpn-last-stage-mask_1xb2-ft_'
     'coco-street.py', 'mask stage'),
]


@pytest.fixture(scope='module')
def recipes():
    return dict(stock=model_of(STOCK), cbnet_pt=model_of(CBNET_PT))


def test_mask_loss_rpn_and_ious_are_every_difference(recipes):
    differing = diff(recipes['stock'], recipes['cbnet_pt'])
    unowned = sorted(k for k in differing if not owner(k))
    assert not unowned, f'differences no part accounts for: {unowned}'
    assert {p for k in differing for p in owner(k)} == {
        'mask loss', 'rpn', 'iou'}


@pytest.mark.parametrize('config,part', SWAPS, ids=[s[0] for s in SWAPS])
def test_each_config_takes_exactly_one_part(recipes, config, part):
    stock, cbnet_pt = recipes['stock'], recipes['cbnet_pt']
    row = model_of(osp.join(COCO_TRUNK, 'parts', config))
    if part == 'mask stage':  # the paper's, not CBNet-PT's
        assert_takes_part(stock, row, part, label=config)
        assert row['roi_head.type'] == PAPER_ROI_HEAD
        assert cbnet_pt['roi_head.type'] == stock['roi_head.type']
    else:
        assert_takes_part(stock, row, part, cbnet_pt, config)


def test_the_set_lists_both_recipes_and_every_part_once():
    rows = rc.RECIPE_SETS['coco_street_coco_trunk_parts']
    paths = [osp.normpath(osp.join(ce.configs_root(), p)) for _, p in rows]
    names = [n for n, _ in rows]
    assert len(set(names)) == len(names) == len(set(paths))
    assert set(paths) == {STOCK, CBNET_PT} | {
        osp.join(COCO_TRUNK, 'parts', c) for c, _ in SWAPS}
    # the whole recipes keep their coco_street_coco_trunk names, so runs
    # in the same work dir count for both sets
    whole = dict(rc.RECIPE_SETS['coco_street_coco_trunk'])
    shared = [n for n, _ in rows if n in whole]
    assert len(shared) == 2
    for name, path in rows:
        if name in whole:
            assert whole[name] == path

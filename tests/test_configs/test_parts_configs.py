"""configs/demo/parts/: each config is one of the two demo recipes (the
stock Cascade Mask R-CNN on SegFormer's MiT-B0, the demo CBNet) with ONE
part swapped for the other recipe's, and the parts together are every
difference between the two."""
import os.path as osp

import pytest
from config_parts import PART_KEYS, assert_takes_part, diff, model_of, owner

from cbnet_lab import config_edits as ce
from cbnet_lab import recipe_comparison as rc

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__))))
DEMO = osp.join(ROOT, 'configs', 'demo')
PARTS = osp.join(DEMO, 'parts')
STOCK = osp.join(PARTS, 'cascade-mask-rcnn_mit-b0-gelu-ope_fpn_1xb4-demo_'
                 'cityscapes-like.py')
CBNET = osp.join(DEMO, 'cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py')

#: (config file, the recipe it starts from, the part it swaps).
SWAPS = [
    ('../cascade-mask-rcnn_mit-b0_fpn_1xb4-demo_cityscapes-like.py', 'stock',
     'trunk'),
    ('cascade-mask-rcnn_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py', 'stock',
     'neck'),
    ('cascade-mask-rcnn_mit-b0_fpn-crpn_1xb4-demo_cityscapes-like.py',
     'stock', 'rpn'),
    ('cascade-mask-rcnn_mit-b0_fpn-iou579_1xb4-demo_cityscapes-like.py',
     'stock', 'iou'),
    ('cascade-mask-rcnn_mit-b0_fpn-last-stage-mask_1xb4-demo_cityscapes-'
     'like.py', 'stock', 'mask stage'),
    ('cascade-mask-rcnn_mit-b0_fpn-boundary-loss_1xb4-demo_cityscapes-'
     'like.py', 'stock', 'mask loss'),
    ('cascade-mask-rcnn_mit-b0_fpn-sigmoid-cls_1xb4-demo_cityscapes-like.py',
     'stock', 'cls'),
    ('cbnet_mit-b0-gelu-ope_nasfpn_1xb4-demo_cityscapes-like.py', 'cbnet',
     'trunk'),
    ('cbnet_mit-b0_fpn_1xb4-demo_cityscapes-like.py', 'cbnet', 'neck'),
    ('cbnet_mit-b0_nasfpn-rpn_1xb4-demo_cityscapes-like.py', 'cbnet', 'rpn'),
    ('cbnet_mit-b0_nasfpn-iou567_1xb4-demo_cityscapes-like.py', 'cbnet',
     'iou'),
    ('cbnet_mit-b0_nasfpn-mask-per-stage_1xb4-demo_cityscapes-like.py',
     'cbnet', 'mask stage'),
    ('cbnet_mit-b0_nasfpn-bce-mask_1xb4-demo_cityscapes-like.py', 'cbnet',
     'mask loss'),
    ('cbnet_mit-b0_nasfpn-softmax-cls_1xb4-demo_cityscapes-like.py', 'cbnet',
     'cls'),
]


def test_the_parts_are_every_difference_between_the_two_recipes():
    stock, cbnet = model_of(STOCK), model_of(CBNET)
    differing = diff(stock, cbnet)
    assert differing
    unowned = sorted(k for k in differing if not owner(k))
    assert not unowned, f'differences no part accounts for: {unowned}'
    # and every part is a real difference
    assert {p for k in differing for p in owner(k)} == set(PART_KEYS)


@pytest.mark.parametrize('config,start,part', SWAPS,
                         ids=[s[0] for s in SWAPS])
def test_each_config_swaps_exactly_one_part(config, start, part):
    stock, cbnet = model_of(STOCK), model_of(CBNET)
    base, other = (stock, cbnet) if start == 'stock' else (cbnet, stock)
    row = model_of(osp.normpath(osp.join(PARTS, config)))
    # what changed is the other recipe's part, whole
    assert_takes_part(base, row, part, other, config)


def test_the_parts_set_lists_every_swap_once():
    names = [n for n, _ in rc.RECIPE_SETS['parts']]
    paths = {osp.normpath(osp.join(ce.configs_root(), p))
             for _, p in rc.RECIPE_SETS['parts']}
    assert len(names) == len(set(names)) == len(paths)
    for config, _, _ in SWAPS:
        assert osp.normpath(osp.join(PARTS, config)) in paths
    assert STOCK in paths and CBNET in paths


def test_revised_without_crpn_swaps_only_the_rpn():
    """'CBNet revised -CRPN' is the revised recipe with the stock cascade's
    RPN part, whole, and nothing else changed."""
    revised = model_of(osp.join(DEMO, 'cbnet-revised_mit-b0_nasfpn_1xb4-'
                                'demo_cityscapes-like.py'))
    row = model_of(osp.join(PARTS, 'cbnet_mit-b0_nasfpn-mask-per-stage-'
                            'softmax-cls-rpn_1xb4-demo_cityscapes-like.py'))
    stock = model_of(STOCK)
    changed = diff(revised, row)
    assert changed and {p for k in changed for p in owner(k)} == {'rpn'}
    for key in {k for k in set(stock) | set(row) if 'rpn' in owner(k)}:
        assert row.get(key, '<absent>') == stock.get(key, '<absent>'), key


REVISED = [
    (CBNET, osp.join(DEMO, 'cbnet-revised_mit-b0_nasfpn_1xb4-demo_'
                     'cityscapes-like.py')),
    (osp.join(ROOT, 'configs', 'cbnet', 'cbnet_mit-b5_nasfpn-crpn_8xb1-'
              '12e_cityscapes.py'),
     osp.join(ROOT, 'configs', 'cbnet', 'cbnet-revised_mit-b5_nasfpn-crpn_'
              '8xb1-12e_cityscapes.py')),
]


@pytest.mark.parametrize('paper,revised', REVISED,
                         ids=[osp.basename(r) for _, r in REVISED])
def test_the_revised_cbnet_is_the_papers_with_three_changes(paper, revised):
    before, after = model_of(paper), model_of(revised)
    changed = diff(before, after)
    # per-stage mask heads, softmax classification, CRPN regression at 1
    assert {p for k in changed for p in owner(k)} == {
        'mask stage', 'cls', 'rpn'}, sorted(changed)
    assert after['roi_head.type'] == 'CascadeRoIHead'
    for i in range(3):
        assert after[f'roi_head.bbox_head.{i}.loss_cls.type'] == \
            'CrossEntropyLoss'
        assert after[f'roi_head.bbox_head.{i}.loss_cls.use_sigmoid'] is False
    assert {k for k in changed if owner(k) == ['rpn']} == {
        'rpn_head.loss_iou.loss_weight', 'rpn_head.loss_giou.loss_weight'}
    assert after['rpn_head.loss_iou.loss_weight'] == \
        after['rpn_head.loss_giou.loss_weight'] == 1.0
    # everything else is the paper's: trunk, neck, IoUs, boundary-aware loss
    assert after['roi_head.mask_head.loss_mask.type'] == \
        'CBNetBoundaryAwareLoss'

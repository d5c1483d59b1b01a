"""configs/pretrained/finetune/: the two real-fog question recipes (and
the revised one with RPNHead, the parts set's RPN swap) on the pretrained
MobileNetV2 with the trunk at the full lr (lr_mult 1 instead of 0.1).
Each must differ from its recipe in that one number and nothing else,
and the optimiser MMEngine builds from it must give the trunk's
parameters the neck's lr."""
import os.path as osp

import pytest
from mmengine.optim import build_optim_wrapper
from mmengine.registry import init_default_scope

from cbnet_lab import config_edits as ce
from cbnet_lab import recipe_comparison as rc

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__))))
PRETRAINED = osp.join(ROOT, 'configs', 'pretrained')
#: (fine-tuning config, the recipe it changes)
PAIRS = [
    ('finetune/cascade-rcnn_mobilenet-v2_fpn_1xb2-ft-trunk-lr1_dawn-fog.py',
     'cascade-rcnn_mobilenet-v2_fpn_1xb2-ft_dawn-fog.py'),
    ('finetune/cbnet-revised-box_mobilenet-v2_nasfpn-crpn_1xb2-ft-trunk-'
     'lr1_dawn-fog.py',
     'cbnet-revised-box_mobilenet-v2_nasfpn-crpn_1xb2-ft_dawn-fog.py'),
    ('finetune/cbnet-revised-box_mobilenet-v2_nasfpn-rpn_1xb2-ft-trunk-'
     'lr1_dawn-fog.py',
     'cbnet-revised-box_mobilenet-v2_nasfpn-rpn_1xb2-ft_dawn-fog.py'),
]
#: The realfog_pretrained_finetune set's two question rows.
QUESTION = PAIRS[:2]


def flat(d, prefix=''):
    out = {}
    for k, v in d.items():
        key = f'{prefix}{k}'
        if isinstance(v, dict):
            out.update(flat(v, key + '.'))
        else:
            out[key] = v
    return out


@pytest.mark.parametrize('config,recipe', PAIRS, ids=[p[0] for p in PAIRS])
def test_only_the_trunk_lr_changes(config, recipe):
    row = flat(ce.read_config(osp.join(PRETRAINED, config)).to_dict())
    ref = flat(ce.read_config(osp.join(PRETRAINED, recipe)).to_dict())
    changed = {k for k in set(row) | set(ref)
               if row.get(k, '<absent>') != ref.get(k, '<absent>')}
    key = 'optim_wrapper.paramwise_cfg.custom_keys.backbone.lr_mult'
    assert changed == {key}
    assert (ref[key], row[key]) == (0.1, 1.0)


@pytest.mark.parametrize('config,recipe', PAIRS, ids=[p[0] for p in PAIRS])
def test_the_built_optimiser_gives_the_trunk_the_full_lr(config, recipe):
    import cbnet_mmdet  # noqa: F401 (registers the components)
    from mmdet.registry import MODELS
    init_default_scope('mmdet')
    lrs = {}
    for name in (config, recipe):
        cfg = ce.read_config(osp.join(PRETRAINED, name))
        cfg.model.backbone.init_cfg = None
        model = MODELS.build(cfg.model)
        optim = build_optim_wrapper(model, cfg.optim_wrapper)
        trunk = {id(p) for p in model.backbone.parameters()}
        neck = {id(p) for p in model.neck.parameters()}
        groups = optim.optimizer.param_groups
        lrs[name] = (
            {g['lr'] for g in groups if id(g['params'][0]) in trunk},
            {g['lr'] for g in groups if id(g['params'][0]) in neck})
    base = ce.read_config(osp.join(PRETRAINED, recipe)).mnv2_lr
    trunk, neck = lrs[recipe]
    assert len(trunk) == 1 and trunk.pop() == pytest.approx(base * 0.1)
    assert neck == {base}
    assert lrs[config] == ({base}, {base})


def test_the_set_reuses_the_question_rows():
    rows = rc.RECIPE_SETS['realfog_pretrained_finetune']
    fog = dict(rc.RECIPE_SETS['realfog_pretrained'])
    paths = {osp.normpath(osp.join(ce.configs_root(), p)) for _, p in rows}
    assert paths == {osp.normpath(osp.join(PRETRAINED, p))
                     for pair in QUESTION for p in pair}
    # the two recipes under their realfog_pretrained names and files
    assert [n for n, _ in rows if n in fog] == ['Cascade R-CNN',
                                                'CBNet revised']
    for name, path in rows:
        if name in fog:
            assert fog[name] == path
    assert rc.SET_PRESETS['realfog_pretrained_finetune'] == \
        'realfog_pretrained'

"""configs/pretrained/neck/: the revised CBNet's box path on real fog with
its NAS-FPN on GroupNorm instead of BatchNorm; the set that compares it
with the BatchNorm and FPN rows of the parts set."""
import os.path as osp

import torch
from mmdet.registry import MODELS
from mmengine.registry import init_default_scope
from config_parts import diff, model_of

from cbnet_lab import config_edits as ce
from cbnet_lab import recipe_comparison as rc
from cbnet_tools import pretrained as pt

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__))))
PRETRAINED = osp.join(ROOT, 'configs', 'pretrained')
REVISED = osp.join(PRETRAINED, 'finetune', 'cbnet-revised-box_mobilenet-'
                   'v2_nasfpn-crpn_1xb2-ft-trunk-lr1_dawn-fog.py')
GN = osp.join(PRETRAINED, 'neck', 'cbnet-revised-box_mobilenet-v2_nasfpn-'
              'gn-crpn_1xb2-ft-trunk-lr1_dawn-fog.py')


def test_the_neck_norm_is_the_only_difference():
    changed = diff(model_of(REVISED), model_of(GN))
    assert changed == {'neck.norm_cfg.type', 'neck.norm_cfg.num_groups'}
    gn, revised = ce.read_config(GN), ce.read_config(REVISED)
    assert gn.model.neck.norm_cfg == dict(type='GN', num_groups=8,
                                          requires_grad=True)
    assert revised.model.neck.norm_cfg.type == 'BN'
    for key in ('optim_wrapper', 'param_scheduler', 'train_dataloader',
                'test_dataloader', 'test_evaluator'):
        assert gn[key] == revised[key], key


def _neck_features(path, x):
    """The training-mode features of ``x`` and of its first photo alone."""
    torch.manual_seed(0)
    model = MODELS.build(ce.read_config(path).model)
    model.train()  # the trunk's BN stays frozen (norm_eval), the neck's not
    with torch.no_grad():
        return model, model.extract_feat(x), model.extract_feat(x[:1])


def test_builds_without_weights_and_the_neck_ignores_the_batch(
        tmp_path, monkeypatch):
    monkeypatch.setenv(pt.PRETRAINED_DIR_ENV, str(tmp_path / 'empty'))
    init_default_scope('mmdet')
    x = torch.rand(2, 3, 128, 192)
    model, both, one = _neck_features(GN, x)
    norms = {type(m).__name__ for m in model.neck.modules()
             if isinstance(m, (torch.nn.GroupNorm, torch.nn.BatchNorm2d))}
    assert norms == {'GroupNorm'}
    # a photo's features do not depend on the other photo of the batch
    for a, b in zip(both, one):
        torch.testing.assert_close(a[:1], b, rtol=1e-4, atol=1e-4)
    # with BatchNorm (the recipe) in training mode they do
    _, both, one = _neck_features(REVISED, x)
    assert not torch.allclose(both[0][:1], one[0], rtol=1e-3, atol=1e-3)


def test_the_set_reuses_the_parts_rows():
    rows = rc.RECIPE_SETS['realfog_pretrained_neck']
    parts = dict(rc.RECIPE_SETS['realfog_pretrained_parts'])
    reused = [(n, p) for n, p in rows if n in parts]
    assert len(reused) == 2 and all(parts[n] == p for n, p in reused)
    new = [p for n, p in rows if n not in parts]
    assert [osp.normpath(osp.join(ce.configs_root(), p)) for p in new] == [
        GN]
    assert rc.SET_PRESETS['realfog_pretrained_neck'] == 'realfog_pretrained'
    assert rc.SET_COLUMNS['realfog_pretrained_neck'] == \
        rc.SET_COLUMNS['realfog_pretrained_parts']

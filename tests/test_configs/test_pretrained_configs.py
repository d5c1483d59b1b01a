"""configs/pretrained: four recipes on one ImageNet MobileNetV2
at equal widths, data and budget, each on real masks (COCO street) and
box-only on real fog (DAWN), plus YOLOX-Tiny, the dark channel prior in
front of the stock cascade and the light edge detector; every
one builds with no weights file."""
import glob
import os
import os.path as osp

import pytest
import torch
from mmdet.registry import MODELS
from mmengine.registry import init_default_scope

from cbnet_lab import config_edits as ce
from cbnet_lab import recipe_comparison as rc
from cbnet_lab.sets import data_condition
from cbnet_tools import pretrained as pt

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__))))
PRETRAINED = osp.join(ROOT, 'configs', 'pretrained')
DEHAZE = osp.join(ROOT, 'projects', 'peer_dehaze', 'configs', 'pretrained')
SHIPPED = sorted(glob.glob(osp.join(PRETRAINED, '*.py')) +
                 glob.glob(osp.join(DEHAZE, '*.py')))
STREET = dict(rc.resolve_recipes('coco_street'))
FOG = dict(rc.resolve_recipes('realfog_pretrained'))


@pytest.fixture(autouse=True)
def empty_cache(tmp_path, monkeypatch):
    """No weights file anywhere the configs look."""
    monkeypatch.setenv(pt.PRETRAINED_DIR_ENV, str(tmp_path / 'empty'))


#: The CBNet recipe for pretrained trunks: the revised CBNet less the
#: NAS-FPN, measured as a row of the real-fog parts set
PT_RECIPE = osp.join(PRETRAINED, 'cbnet-pt-box_mobilenet-v2_fpn-crpn_1xb2-'
                     'ft-trunk-lr1_dawn-fog.py')


def test_every_config_is_in_a_set():
    parts = dict(rc.resolve_recipes('realfog_pretrained_parts'))
    assert osp.normpath(parts['CBNet revised -NAS-FPN, trunk lr x1']) == \
        PT_RECIPE
    assert sorted(map(osp.normpath, list(STREET.values()) +
                      list(FOG.values()) + [PT_RECIPE])) == SHIPPED
    assert len(STREET) == 5 and len(FOG) == 9


@pytest.mark.parametrize('path', SHIPPED, ids=osp.basename)
def test_builds_and_runs_without_the_weights_file(path):
    cfg = ce.read_config(path)
    assert not osp.exists(pt.pretrained_dir())
    init_default_scope('mmdet')
    model = MODELS.build(cfg.model)  # no file read at build time
    if cfg.model.type != 'YOLOX':
        assert cfg.model.backbone.init_cfg.checkpoint == \
            pt.pretrained_path('mobilenet_v2')
        with pytest.raises(FileNotFoundError,
                           match='fetch_pretrained.py mobilenet_v2'):
            pt.require_pretrained(cfg)
    model.eval()
    with torch.no_grad():
        feats = model.extract_feat(torch.zeros(1, 3, 128, 192))
    assert len(feats) in (3, 5)


def _trunk_and_widths(cfg):
    model = cfg.model
    return (model.backbone, model.neck.out_channels,
            model.neck.in_channels, cfg.optim_wrapper.optimizer.lr,
            cfg.optim_wrapper.paramwise_cfg.custom_keys,
            model.roi_head.bbox_roi_extractor.out_channels,
            [h.fc_out_channels for h in model.roi_head.bbox_head],
            model.train_cfg.rpn_proposal.max_per_img,
            [s.sampler.num for s in model.train_cfg.rcnn])


@pytest.mark.parametrize('recipes', [STREET, FOG], ids=['street', 'fog'])
def test_equal_trunk_widths_optimiser_and_data(recipes):
    cfgs = {n: ce.read_config(p) for n, p in recipes.items()}
    # two-stage recipes (YOLOX and the edge model have no RoI head; the
    # edge model's trunk and data are checked in test_edge_model_*)
    detectors = {n: c for n, c in cfgs.items() if 'roi_head' in c.model}
    first = _trunk_and_widths(next(iter(detectors.values())))
    backbone, width, in_channels, lr, keys = first[:5]
    assert backbone.type == 'MobileNetV2' and backbone.frozen_stages == 1
    assert backbone.norm_eval and backbone.out_indices == (1, 2, 4, 7)
    assert in_channels == [24, 32, 96, 1280] and width == 64
    assert lr == 2e-4 and keys.backbone.lr_mult == 0.1
    for name, cfg in detectors.items():
        assert _trunk_and_widths(cfg) == first, name
        pre = cfg.model.data_preprocessor
        # the ImageNet normalisation the weights were trained with, RGB
        assert pre.mean == [123.675, 116.28, 103.53] and pre.bgr_to_rgb
    # the edge model keeps its own input size (its row says so)
    keeps = {r.name for r in rc.SETS[
        'realfog_pretrained' if recipes is FOG else 'coco_street'].recipes
        if r.keep_img_scale}
    assert keeps == ({'Edge FCOS-lite, 320 px'} if recipes is FOG else set())
    data = {n: (c.train_dataloader, c.test_dataloader, c.test_evaluator,
                data_condition(c.data_root)) for n, c in cfgs.items()
            if n not in keeps}
    assert len({repr(d) for d in data.values()}) == 1


def test_the_heads_of_each_recipe():
    street = {n: ce.read_config(p).model for n, p in STREET.items()}
    stock, paper = street['Cascade Mask R-CNN'], street['CBNet']
    revised, rpn = street['CBNet revised'], street['CBNet revised, RPNHead']
    cbnet_pt = street['CBNet-PT']
    assert stock.neck.type == 'FPN' and stock.rpn_head.type == 'RPNHead'
    assert stock.roi_head.type == 'CascadeRoIHead'
    assert stock.roi_head.mask_head.type == 'FCNMaskHead'
    assert [s.assigner.pos_iou_thr for s in stock.train_cfg.rcnn] == \
        [0.5, 0.6, 0.7]
    for model in (paper, revised, rpn):
        assert model.neck.type == 'CBNetNASFPN'
        assert [s.assigner.pos_iou_thr for s in model.train_cfg.rcnn] == \
            [0.5, 0.7, 0.9]
        assert model.roi_head.mask_head.type == 'CBNetBoundaryMaskHead'
    assert paper.roi_head.type == 'CBNetCascadeRoIHead'
    assert paper.rpn_head.type == 'CBNetCascadeRPNHead'
    assert paper.rpn_head.loss_iou.loss_weight == 10.0
    assert {h.loss_cls.type for h in paper.roi_head.bbox_head} == \
        {'CBNetSigmoidCrossEntropyLoss'}
    for model in (revised, rpn):
        assert model.roi_head.type == 'CascadeRoIHead'  # mask per stage
        assert {h.loss_cls.type for h in model.roi_head.bbox_head} == \
            {'CrossEntropyLoss'}
    assert revised.rpn_head.type == 'CBNetCascadeRPNHead'
    assert revised.rpn_head.loss_iou.loss_weight == 1.0
    assert revised.rpn_head.loss_giou.loss_weight == 1.0
    assert rpn.rpn_head.type == 'RPNHead'
    # CBNet-PT: the revised CBNet with the stock cascade's neck
    assert cbnet_pt.neck == stock.neck
    assert cbnet_pt.data_preprocessor == stock.data_preprocessor
    for key in ('rpn_head', 'roi_head', 'train_cfg', 'test_cfg', 'backbone'):
        assert cbnet_pt[key] == revised[key], key
    # the fog versions are the same heads without masks
    fog = {n: ce.read_config(p) for n, p in FOG.items()}
    pairs = [('Cascade R-CNN', 'Cascade Mask R-CNN'),
             ('CBNet', 'CBNet'), ('CBNet revised', 'CBNet revised'),
             ('CBNet revised, RPNHead', 'CBNet revised, RPNHead'),
             ('CBNet-PT', 'CBNet-PT')]
    for fog_name, street_name in pairs:
        model = fog[fog_name].model
        assert model.roi_head.get('mask_head') is None
        assert model.rpn_head == street[street_name].rpn_head
        assert model.roi_head.bbox_head == \
            street[street_name].roi_head.bbox_head
    dcp = fog['DCP + Cascade R-CNN'].model
    assert dcp.data_preprocessor.type == 'CBNetDehazeDataPreprocessor'
    assert dcp.data_preprocessor.dehaze.type == 'CBNetDarkChannelPrior'
    assert dcp.roi_head == fog['Cascade R-CNN'].model.roi_head
    assert fog['YOLOX-Tiny (scratch)'].model.type == 'YOLOX'


def test_data_of_the_two_sets():
    street = ce.read_config(STREET['CBNet'])
    assert data_condition(street.data_root) == 'coco street'
    assert street.train_dataloader.dataset.type == 'CBNetCityscapesDataset'
    assert street.train_dataloader.dataset.pipeline[0].type == \
        'CBNetLoadImageFromFile'
    assert [e.type for e in street.test_evaluator] == [
        'CocoMetric', 'CBNetInstanceMIoUMetric']
    fog = ce.read_config(FOG['CBNet'])
    assert data_condition(fog.data_root) == 'real fog'
    ds = fog.test_dataloader.dataset
    assert (ds.type, ds.split, ds.val_fraction, ds.split_seed) == (
        'CBNetVOCFogDataset', 'val', 0.3, 0)
    assert fog.train_dataloader.dataset.pipeline[0].type == \
        'CBNetLoadImageFromFile'
    # the presets: 640 px wide at most, batches of 2
    for name in ('coco_street', 'realfog_pretrained'):
        preset = rc.PRESETS[rc.SET_PRESETS[name]]
        assert preset.img_scale == (640, 480) and preset.batch_size == 2


EDGE, EDGE_640 = FOG['Edge FCOS-lite, 320 px'], FOG['Edge FCOS-lite, 640 px']


@pytest.fixture
def fake_trunk(tmp_path, monkeypatch):
    """A seeded MobileNetV2 state dict saved where the configs look."""
    from mmdet.models.backbones import MobileNetV2
    monkeypatch.setenv(pt.PRETRAINED_DIR_ENV, str(tmp_path / 'weights'))
    torch.manual_seed(3)
    state = MobileNetV2().state_dict()
    path = pt.pretrained_path('mobilenet_v2')
    os.makedirs(osp.dirname(path))
    torch.save(dict(state_dict=state), path)
    return state


def test_edge_model_loads_the_trunk_and_fine_tunes_it_as_the_others(
        fake_trunk):
    from mmengine.optim import build_optim_wrapper
    cfg = ce.read_config(EDGE)
    stock = ce.read_config(FOG['Cascade R-CNN'])
    # the same trunk, fine-tuning and data preprocessor as the recipes
    assert cfg.model.backbone == stock.model.backbone
    assert cfg.model.data_preprocessor == stock.model.data_preprocessor
    assert cfg.model.type == 'FCOS' and cfg.model.bbox_head.num_classes == 8
    assert cfg.model.bbox_head.strides == [8, 16, 32]
    init_default_scope('mmdet')
    model = MODELS.build(cfg.model)
    # the converted trunk's keys are exactly the backbone's (strict load)
    model.backbone.load_state_dict(fake_trunk, strict=True)
    model = MODELS.build(cfg.model)
    model.init_weights()  # through the config's Pretrained init
    for key, value in fake_trunk.items():
        torch.testing.assert_close(model.backbone.state_dict()[key], value)
    model.train()
    frozen = [p.requires_grad for p in model.backbone.conv1.parameters()]
    frozen += [p.requires_grad for p in model.backbone.layer1.parameters()]
    assert frozen and not any(frozen)
    assert all(not m.training for m in model.backbone.modules()
               if isinstance(m, torch.nn.BatchNorm2d))
    wrapper = build_optim_wrapper(model, cfg.optim_wrapper)
    lrs = {}
    for group in wrapper.optimizer.param_groups:
        for p in group['params']:
            lrs[id(p)] = group['lr']
    trunk = {lrs[id(p)] for p in model.backbone.layer7.parameters()}
    head = {lrs[id(p)] for p in model.bbox_head.parameters()}
    neck = {lrs[id(p)] for p in model.neck.parameters()}
    assert len(trunk) == 1 and trunk.pop() == pytest.approx(2e-5)
    assert head == neck == {2e-4}


def test_edge_model_trains_and_predicts_on_a_tiny_batch():
    from mmdet.testing import demo_mm_inputs
    cfg = ce.read_config(EDGE)
    init_default_scope('mmdet')
    torch.manual_seed(0)
    model = MODELS.build(cfg.model)
    data = model.data_preprocessor(demo_mm_inputs(
        2, [(3, 90, 160)] * 2, num_items=[3, 2], num_classes=8,
        with_mask=False), True)
    model.train()
    losses = model(**data, mode='loss')
    assert set(losses) == {'loss_cls', 'loss_bbox', 'loss_centerness'}
    loss, _ = model.parse_losses(losses)
    assert torch.isfinite(loss) and loss > 0
    loss.backward()
    assert all(p.grad is None for p in model.backbone.layer1.parameters())
    assert model.backbone.layer2[0].expand_conv.conv.weight.grad is not None
    assert model.bbox_head.conv_cls.weight.grad.abs().sum() > 0
    model.eval()
    data = model.data_preprocessor(demo_mm_inputs(
        1, [(3, 90, 160)], num_items=[1], num_classes=8,
        with_mask=False), False)
    with torch.no_grad():
        out = model(**data, mode='predict')[0].pred_instances
    assert out.bboxes.shape[1] == 4 and len(out) <= 100
    assert len(out) == 0 or int(out.labels.max()) < 8


def test_edge_model_keeps_its_input_size_under_the_preset(tmp_path):
    preset = rc.PRESETS['realfog_pretrained']
    budget = ce.Budget(iters=2, batch_size=2, num_workers=0,
                       img_scale=preset.img_scale)
    sizes = {}
    for path in (EDGE, EDGE_640):
        row = next(r for r in rc.SETS['realfog_pretrained'].recipes
                   if osp.join(ce.configs_root(), r.config) == path)
        cfg = ce.budget_cfg(path, budget, seed=0, data_root='/d',
                            work_dir=str(tmp_path),
                            keep_img_scale=row.keep_img_scale)
        sizes[osp.basename(path)] = {
            tuple(t.scale) for loader in (cfg.train_dataloader,
                                          cfg.test_dataloader)
            for t in loader.dataset.pipeline if t.type == 'Resize'}
    assert sizes == {osp.basename(EDGE): {(320, 240)},
                     osp.basename(EDGE_640): {(640, 480)}}
    # apart from the size, the data are the other recipes'
    edge, other = ce.read_config(EDGE), ce.read_config(EDGE_640)
    for key in ('train_dataloader', 'test_dataloader'):
        pipe = [dict(t, scale=(640, 480)) if t.type == 'Resize' else t
                for t in edge[key].dataset.pipeline]
        assert pipe == other[key].dataset.pipeline
    assert edge.test_evaluator == other.test_evaluator

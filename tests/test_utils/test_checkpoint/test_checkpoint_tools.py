"""publish_model.py and extract_student.py."""
import glob
import hashlib
import importlib.util
import os.path as osp

import numpy as np
import pytest
import torch
from mmdet.apis import DetInferencer, inference_detector, init_detector
from mmdet.datasets import CityscapesDataset
from mmdet.registry import MODELS
from mmengine.config import Config
from mmengine.logging.history_buffer import HistoryBuffer
from mmengine.registry import init_default_scope

import cbnet_mmdet  # noqa: F401
from cbnet_mmdet.utils.checkpoint.files import (detector_config,
                                                extract_detector,
                                                publish_checkpoint)

ROOT = osp.dirname(
    osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__)))))
DEMO = osp.join(ROOT, 'configs', 'demo',
                'cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py')


def _tool(rel):
    spec = importlib.util.spec_from_file_location(
        osp.basename(rel)[:-3], osp.join(ROOT, 'tools', rel))
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _training_checkpoint(path):
    """What MMEngine's runner writes: weights, optimizer, message hub with
    a HistoryBuffer, schedulers, meta."""
    net = torch.nn.Linear(3, 2)
    opt = torch.optim.AdamW(net.parameters())
    net(torch.ones(1, 3)).sum().backward()
    opt.step()
    buf = HistoryBuffer()
    buf.update(1.5)
    torch.save(
        dict(meta=dict(epoch=3, dataset_meta=dict(classes=('a', 'b'))),
             state_dict=net.state_dict(), optimizer=opt.state_dict(),
             message_hub=dict(log_scalars={'train/loss': buf}),
             param_schedulers=[dict(last_step=3)]), path)
    return net.state_dict()


def test_publish_strips_and_hashes(tmp_path):
    src = str(tmp_path / 'epoch_3.pth')
    weights = _training_checkpoint(src)
    tool = _tool('model_converters/publish_model.py')
    final = tool.main([src, str(tmp_path / 'pub' / 'model.pth')])
    with open(final, 'rb') as f:
        sha = hashlib.sha256(f.read()).hexdigest()
    assert final == str(tmp_path / 'pub' / f'model-{sha[:8]}.pth')
    assert glob.glob(str(tmp_path / 'pub' / '*')) == [final]
    # torch's default weights-only loading reads it
    pub = torch.load(final, weights_only=True)
    assert set(pub) == {'meta', 'state_dict'}
    assert pub['meta']['epoch'] == 3
    for k, v in weights.items():
        assert torch.equal(pub['state_dict'][k], v)
    # --save-keys keeps what is asked
    final = publish_checkpoint(src, str(tmp_path / 'm2.pth'),
                               ['state_dict', 'optimizer'])
    assert set(torch.load(final)) == {'state_dict', 'optimizer'}


def test_publish_errors(tmp_path):
    with pytest.raises(FileNotFoundError, match='nope.pth'):
        publish_checkpoint(str(tmp_path / 'nope.pth'), 'x.pth')
    bad = str(tmp_path / 'bad.pth')
    torch.save(dict(weights=torch.zeros(1)), bad)
    with pytest.raises(ValueError, match='bad.pth.*state_dict'):
        publish_checkpoint(bad, str(tmp_path / 'x.pth'))


@pytest.fixture(scope='module')
def distiller_checkpoint(tmp_path_factory):
    """A CBNet-DD checkpoint of the demo detector whose teacher differs
    from its student, with the config embedded as a runner embeds it."""
    tmp = tmp_path_factory.mktemp('dd')
    cfg = Config.fromfile(DEMO)
    detector = cfg.model
    preprocessor = dict(detector.data_preprocessor,
                        type='CBNetPairedDataPreprocessor')
    cfg.model = dict(type='CBNetDistiller', detector=detector,
                     data_preprocessor=preprocessor)
    cfg.custom_hooks = [dict(type='CBNetTeacherEMAHook', momentum=0.9)]
    init_default_scope('mmdet')
    torch.manual_seed(0)
    model = MODELS.build(cfg.model)
    model.init_weights()
    with torch.no_grad():
        for p in model.teacher.parameters():
            p.add_(0.01)
    path = str(tmp / 'dd_epoch_1.pth')
    torch.save(
        dict(state_dict=model.state_dict(),
             meta=dict(dataset_meta=dict(CityscapesDataset.METAINFO),
                       cfg=cfg.pretty_text),
             optimizer={}), path)
    return dict(path=path, model=model, cfg=cfg, tmp=tmp)


@pytest.mark.parametrize('which', ['student', 'teacher'])
def test_extract_student_weights(distiller_checkpoint, which, tmp_path):
    tool = _tool('model_converters/extract_student.py')
    out = tool.main([distiller_checkpoint['path'],
                     str(tmp_path / 'plain.pth'), '--which', which])
    plain = torch.load(out)
    ref = getattr(distiller_checkpoint['model'], which).state_dict()
    assert set(plain['state_dict']) == set(ref)
    for k, v in ref.items():
        assert torch.equal(plain['state_dict'][k], v), k
    cfg = Config.fromstring(plain['meta']['cfg'], file_format='.py')
    assert cfg.model.type == 'CascadeRCNN'
    assert not any(h.type == 'CBNetTeacherEMAHook' for h in cfg.custom_hooks)
    assert plain['meta']['extracted_from']['which'] == which


def test_extracted_student_runs_in_det_inferencer(distiller_checkpoint,
                                                  cityscapes_like_root,
                                                  tmp_path):
    """DetInferencer loads the exported file alone (config from its
    meta); its predictions are those of the distiller's student."""
    out = extract_detector(distiller_checkpoint['path'],
                           str(tmp_path / 'student.pth'), hashed=True)
    assert osp.basename(out).startswith('student-')
    img = sorted(glob.glob(osp.join(cityscapes_like_root, 'leftImg8bit',
                                    'val', '*', '*.png')))[0]
    inferencer = DetInferencer(weights=out, device='cpu',
                               show_progress=False)
    pred = inferencer(img, return_datasamples=True)['predictions'][0]
    # reference: the demo detector given the student's weights by hand
    plain_cfg = str(tmp_path / 'plain.py')
    detector_config(distiller_checkpoint['cfg']).dump(plain_cfg)
    ref_model = init_detector(plain_cfg, None, device='cpu')
    ref_model.load_state_dict(
        distiller_checkpoint['model'].student.state_dict())
    ref = inference_detector(ref_model, img).pred_instances
    assert len(ref) > 0
    np.testing.assert_allclose(pred.pred_instances.bboxes.numpy(),
                               ref.bboxes.numpy(), atol=1e-4)
    np.testing.assert_allclose(pred.pred_instances.scores.numpy(),
                               ref.scores.numpy(), atol=1e-6)
    assert inferencer.model.dataset_meta['classes'] == \
        CityscapesDataset.METAINFO['classes']


def test_extract_errors(tmp_path):
    plain = str(tmp_path / 'plain.pth')
    torch.save(dict(state_dict={'backbone.w': torch.zeros(1)}), plain)
    with pytest.raises(ValueError, match='no student.* weights'):
        extract_detector(plain, str(tmp_path / 'o.pth'))
    with pytest.raises(ValueError, match="'student' or 'teacher'"):
        extract_detector(plain, str(tmp_path / 'o.pth'), which='ema')
    with pytest.raises(ValueError, match='no `detector`'):
        detector_config(Config(dict(model=dict(type='CascadeRCNN'))))

"""MMDetection's inference API on our configs.

``DetInferencer`` (single image, folder, ``out_dir`` drawings),
``inference_detector`` (path and array) and the frame loop of MMDet's
``demo/video_demo.py``, on the demo model with seeded random weights. The
reference for every prediction is the model run on the item our own
dataset (``CBNetCityscapesDataset`` with the config's test pipeline)
produces for the same image, outside MMDet's inference code.
"""
import glob
import json
import os
import os.path as osp
import shutil

import cv2
import mmcv
import numpy as np
import pytest
import torch
from mmcv.transforms import Compose
from mmdet.apis import DetInferencer, inference_detector, init_detector
from mmdet.datasets import CityscapesDataset
from mmdet.registry import DATASETS, MODELS
from mmengine.config import Config
from mmengine.registry import init_default_scope

import cbnet_mmdet  # noqa: F401

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__))))
DEMO = osp.join(ROOT, 'configs', 'demo',
                'cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py')
# every detector config, the projects' too (the peer baseline's
# dehazer_*.py train a dehazer alone: no detector, nothing for DetInferencer)
SHIPPED = sorted(
    p for p in glob.glob(osp.join(ROOT, 'configs', '**', '*.py'),
                         recursive=True) +
    glob.glob(osp.join(ROOT, 'projects', '*', 'configs', '**', '*.py'),
              recursive=True)
    if '_base_' not in p and not osp.basename(p).startswith('dehazer_')
    # the experiment sets (configs/experiments) are no model configs
    and osp.join('configs', 'experiments') not in p)


@pytest.fixture(scope='module')
def demo(cityscapes_like_root, tmp_path_factory):
    """Demo config file (data_root = the tiny set) and a checkpoint of the
    demo model with seeded random weights, written like a runner's."""
    tmp = tmp_path_factory.mktemp('inference')
    cfg = Config.fromfile(DEMO)
    cfg.merge_from_dict(
        dict(test_dataloader=dict(
            dataset=dict(data_root=cityscapes_like_root + '/'))))
    cfg_file = str(tmp / 'demo.py')
    cfg.dump(cfg_file)
    init_default_scope('mmdet')
    torch.manual_seed(0)
    model = MODELS.build(cfg.model)
    model.init_weights()
    ckpt = str(tmp / 'demo.pth')
    torch.save(
        dict(state_dict=model.state_dict(),
             meta=dict(dataset_meta=dict(CityscapesDataset.METAINFO),
                       cfg=cfg.pretty_text)), ckpt)
    images = sorted(
        glob.glob(osp.join(cityscapes_like_root, 'leftImg8bit', 'val', '*',
                           '*.png')))
    return dict(cfg=cfg, cfg_file=cfg_file, ckpt=ckpt, images=images,
                tmp=tmp)


@pytest.fixture(scope='module')
def reference(demo):
    """Predictions of the loaded model on our dataset's items, per path."""
    model = init_detector(demo['cfg_file'], demo['ckpt'], device='cpu')
    dataset = DATASETS.build(demo['cfg'].test_dataloader.dataset)
    out = {}
    for i in range(len(dataset)):
        item = dataset[i]
        with torch.no_grad():
            pred = model.test_step(
                dict(inputs=[item['inputs']],
                     data_samples=[item['data_samples']]))[0]
        out[item['data_samples'].img_path] = pred.pred_instances
    assert set(out) == set(demo['images'])
    return out


def _assert_same(pred, ref):
    """Same boxes, scores and labels (pred: InstanceData or the
    inferencer's dict of lists)."""
    if isinstance(pred, dict):
        bboxes = np.array(pred['bboxes']).reshape(-1, 4)
        scores, labels = np.array(pred['scores']), np.array(pred['labels'])
    else:
        bboxes = pred.bboxes.numpy()
        scores, labels = pred.scores.numpy(), pred.labels.numpy()
    assert len(ref.scores) > 0  # random weights still give detections
    np.testing.assert_allclose(bboxes, ref.bboxes.numpy(), atol=1e-3)
    np.testing.assert_allclose(scores, ref.scores.numpy(), atol=1e-5)
    np.testing.assert_array_equal(labels, ref.labels.numpy())


@pytest.mark.parametrize('path', SHIPPED,
                         ids=[osp.relpath(p, ROOT) for p in SHIPPED])
def test_inferencer_accepts_every_shipped_test_pipeline(path, demo):
    """DetInferencer finds the loader in every config and its pipeline
    turns an image path into model inputs. The loader reads through the
    checking file backend and CBNetCheckImage follows it (see
    tests/test_datasets/test_transforms/test_check_image.py)."""
    cfg = Config.fromfile(path)
    config_pipeline = cfg.test_dataloader.dataset.pipeline
    types = [t['type'] for t in config_pipeline]
    load = types.index('LoadImageFromFile')
    assert config_pipeline[load].get('backend_args') == dict(
        backend='cbnet_image')
    assert types[load + 1] == 'CBNetCheckImage', types
    init_default_scope('mmdet')
    inferencer = DetInferencer.__new__(DetInferencer)
    pipeline = inferencer._init_pipeline(cfg)
    assert type(pipeline.transforms[0]).__name__ == 'InferencerLoader'
    out = pipeline(demo['images'][0])
    assert out['inputs'].shape[0] == 3
    assert out['data_samples'].ori_shape == (128, 256)


def test_datasets_run_the_pipelines_their_configs_name(demo):
    """No dataset swaps a transform: the test pipeline keeps MMCV's loader
    (the name DetInferencer needs) reading through the checking backend,
    the training pipeline names the checking loader."""
    from mmcv.transforms import LoadImageFromFile

    from cbnet_mmdet.datasets.transforms import CBNetLoadImageFromFile
    cfg = demo['cfg']
    assert cfg.test_dataloader.dataset.pipeline[0].type == \
        'LoadImageFromFile'
    dataset = DATASETS.build(cfg.test_dataloader.dataset)
    loader = dataset.pipeline.transforms[0]
    assert type(loader) is LoadImageFromFile
    assert loader.backend_args == dict(backend='cbnet_image')
    assert cfg.train_pipeline[0].type == 'CBNetLoadImageFromFile'
    train = dict(cfg.test_dataloader.dataset, pipeline=cfg.train_pipeline,
                 test_mode=False)
    train_loader = DATASETS.build(train).pipeline.transforms[0]
    assert type(train_loader) is CBNetLoadImageFromFile


def test_checking_loader_in_a_test_pipeline_breaks_det_inferencer():
    """Why the test pipelines keep MMCV's name: DetInferencer looks for a
    transform typed exactly ``LoadImageFromFile`` and refuses ours."""
    cfg = Config.fromfile(DEMO)
    cfg.test_dataloader.dataset.pipeline[0].type = 'CBNetLoadImageFromFile'
    init_default_scope('mmdet')
    inferencer = DetInferencer.__new__(DetInferencer)
    with pytest.raises(ValueError, match='LoadImageFromFile is not found'):
        inferencer._init_pipeline(cfg)


def test_det_inferencer_images_folder_and_drawings(demo, reference):
    inferencer = DetInferencer(
        model=demo['cfg_file'], weights=demo['ckpt'], device='cpu',
        show_progress=False)
    # one image
    one = inferencer(demo['images'][0], return_datasamples=True)
    _assert_same(one['predictions'][0].pred_instances,
                 reference[demo['images'][0]])
    # a folder, drawings and predictions written to out_dir
    folder = demo['tmp'] / 'images'  # the 3 val images (3 cities)
    folder.mkdir()
    by_name = {}
    for path in demo['images']:
        shutil.copy(path, folder)
        by_name[osp.basename(path)] = reference[path]
    # the inferencer's own listing order (a directory scan, not sorted)
    in_folder = inferencer._inputs_to_list(str(folder))
    assert sorted(map(osp.basename, in_folder)) == sorted(by_name)
    out_dir = str(demo['tmp'] / 'out')
    res = inferencer(str(folder), out_dir=out_dir, no_save_pred=False,
                     pred_score_thr=0.0)
    assert len(res['predictions']) == 3
    for path, pred in zip(in_folder, res['predictions']):
        _assert_same(pred, by_name[osp.basename(path)])
        stem = osp.splitext(osp.basename(path))[0]
        drawn = mmcv.imread(osp.join(out_dir, 'vis', stem + '.png'))
        assert drawn.shape == (128, 256, 3)
        # something was drawn on the image
        assert np.abs(drawn.astype(int) - mmcv.imread(path)).max() > 0
        with open(osp.join(out_dir, 'preds', stem + '.json')) as f:
            assert len(json.load(f)['scores']) == len(pred['scores'])


def test_inference_detector_path_and_array(demo, reference):
    model = init_detector(demo['cfg_file'], demo['ckpt'], device='cpu')
    path = demo['images'][1]
    _assert_same(inference_detector(model, path).pred_instances,
                 reference[path])
    # an array goes through MMDet's LoadImageFromNDArray
    img = mmcv.imread(path)
    _assert_same(inference_detector(model, img).pred_instances,
                 reference[path])


def test_video_demo_frame_loop(demo, reference):
    """MMDet's demo/video_demo.py: pipeline[0] -> LoadImageFromNDArray,
    then inference_detector per frame of an mmcv.VideoReader."""
    model = init_detector(demo['cfg_file'], demo['ckpt'], device='cpu')
    video = str(demo['tmp'] / 'drive.avi')
    writer = cv2.VideoWriter(video, cv2.VideoWriter_fourcc(*'MJPG'), 5,
                             (256, 128))
    for path in demo['images'][:2]:
        writer.write(mmcv.imread(path))
    writer.release()
    model.cfg.test_dataloader.dataset.pipeline[0].type = \
        'mmdet.LoadImageFromNDArray'
    pipeline = Compose(model.cfg.test_dataloader.dataset.pipeline)
    frames = list(mmcv.VideoReader(video))
    assert len(frames) == 2
    for frame in frames:
        via_demo = inference_detector(model, frame, test_pipeline=pipeline)
        # the decoded (lossy) frame through the plain array path
        direct = inference_detector(model, np.ascontiguousarray(frame))
        _assert_same(via_demo.pred_instances, direct.pred_instances)


@pytest.mark.slow  # builds the full-width MiT-B0 paper model (~80M params)
def test_det_inferencer_on_a_paper_config(demo, tmp_path):
    """A paper config (full-size CBNet MiT-B0) with random weights and no
    download (DetInferencer never calls init_weights), at the demo size."""
    cfg = Config.fromfile(
        osp.join(ROOT, 'configs', 'cbnet',
                 'cbnet_mit-b0_nasfpn-crpn_8xb1-12e_cityscapes.py'))
    (resize, ) = [t for t in cfg.test_dataloader.dataset.pipeline
                  if t.type == 'Resize']
    resize.scale = (256, 128)  # CPU: 8x smaller than the paper's 2048x1024
    inferencer = DetInferencer(model=cfg, weights=None, device='cpu',
                               show_progress=False)
    out_dir = str(tmp_path / 'out')
    res = inferencer(demo['images'][0], out_dir=out_dir, no_save_pred=False)
    pred = res['predictions'][0]
    assert len(pred['scores']) == len(pred['labels']) == len(pred['bboxes'])
    assert os.listdir(osp.join(out_dir, 'vis'))

"""The README's inference example ("Quick start") runs as written: exactly
its text, executed in a folder laid out as after ``bash tools/demo.sh``
(the repository's ``configs/``, the demo's data under
``data/cityscapes_like_bench/`` and its checkpoint at
``work_dirs/demo/epoch_8.pth``; here a tiny generated set and the demo
model with seeded random weights), draws every image of the folder it
names and returns one prediction per image."""
import glob
import os
import os.path as osp
import re

import torch
from mmdet.datasets import CityscapesDataset
from mmdet.registry import MODELS
from mmengine.config import Config
from mmengine.registry import init_default_scope
from doc_helpers import ROOT, read_text

import cbnet_mmdet  # noqa: F401


def readme_inference_snippet():
    """The README's first python block: the ``DetInferencer`` example."""
    text = read_text(osp.join(ROOT, 'README.md'))
    blocks = re.findall(r'```python\n(.*?)```', text, flags=re.S)
    assert blocks and 'DetInferencer' in blocks[0], \
        'the README has no DetInferencer example as its first python block'
    return blocks[0]


def test_readme_inference_runs_as_written(cityscapes_like_root, tmp_path,
                                          monkeypatch):
    snippet = readme_inference_snippet()
    config, = re.findall(r"model='([^']+)'", snippet)
    weights, = re.findall(r"weights='([^']+)'", snippet)
    folder, = re.findall(r"inferencer\('([^']+)'", snippet)
    assert config.startswith('configs/') and \
        osp.isfile(osp.join(ROOT, config)), config
    # the layout the demo leaves
    os.symlink(osp.join(ROOT, 'configs'), tmp_path / 'configs')
    (tmp_path / 'data').mkdir()
    os.symlink(cityscapes_like_root,
               tmp_path / 'data' / 'cityscapes_like_bench')
    assert folder.startswith('data/cityscapes_like_bench/')
    images = sorted(glob.glob(str(tmp_path / folder / '*.png')))
    assert images, f'the tiny set has no image under {folder}'
    init_default_scope('mmdet')
    cfg = Config.fromfile(osp.join(ROOT, config))
    torch.manual_seed(0)
    model = MODELS.build(cfg.model)
    model.init_weights()
    os.makedirs(osp.dirname(tmp_path / weights))
    torch.save(
        dict(
            state_dict=model.state_dict(),
            meta=dict(
                dataset_meta=dict(CityscapesDataset.METAINFO),
                cfg=cfg.pretty_text)), tmp_path / weights)
    monkeypatch.chdir(tmp_path)
    scope = {}
    exec(compile(snippet, 'README.md', 'exec'), scope)  # noqa: S102
    result = scope['result']
    assert len(result['predictions']) == len(images)
    for pred in result['predictions']:
        assert set(pred) >= {'labels', 'scores', 'bboxes', 'masks'}
    drawn = sorted(
        osp.basename(p)
        for p in glob.glob(str(tmp_path / 'outputs' / 'vis' / '*.png')))
    assert drawn == [osp.basename(p) for p in images]

"""Score the first N test images, against those images' ground truth only.

MMEngine's ``test_dataloader.dataset.indices=N`` tests the first N images,
but MMDet's ``CocoMetric`` (and ``CBNetInstanceMIoUMetric``) given an
``ann_file`` score against every image of that file: the objects of the
images never tested count as missed and the AP comes out far too low
(4.1 box AP for a model at 29.6 on five images), without a word.

:func:`first_images_cfg` does it right: for a dataset read from a COCO
JSON file it writes that file's first N images (and their annotations) to
a folder and points the dataset and every evaluator that reads an
``ann_file`` at the written files, so the metric sees exactly those
images' ground truth, as if the set had only them. A dataset without a
COCO file (the VOC real-fog folders) is cut with MMEngine's ``indices``
when no evaluator reads an ``ann_file`` (the metrics then build the ground
truth from the tested images). :func:`check_subset_scoring` refuses a
config that sets ``indices`` while an evaluator reads a whole file.
"""
import copy
import json
import os
import os.path as osp
from typing import List, Sequence

from mmengine.config import Config

#: What the refusal of :func:`check_subset_scoring` advises.
ADVICE = ('use --num-images N of tools/test.py, '
          'tools/analysis_tools/ap_drop.py or test_robustness.py '
          '(cbnet_tools.quick_eval), which scores the first N images '
          'against their own ground truth')


def _evaluators(cfg: Config) -> List[dict]:
    evaluators = cfg.get('test_evaluator') or []
    if isinstance(evaluators, dict):
        evaluators = [evaluators]
    return list(evaluators)


def check_subset_scoring(cfg: Config) -> None:
    """Refuse a test subset scored against a whole annotation file.

    Args:
        cfg (Config): A test config.

    Raises:
        ValueError: ``test_dataloader.dataset.indices`` is set and an
            evaluator of ``test_evaluator`` reads an ``ann_file``.
    """
    ds = (cfg.get('test_dataloader') or {}).get('dataset') or {}
    indices = ds.get('indices')
    if indices is None:
        return
    for evaluator in _evaluators(cfg):
        if evaluator.get('ann_file'):
            raise ValueError(
                f'test_dataloader.dataset.indices={indices!r} tests a '
                f"subset of the images, but {evaluator.get('type')} scores "
                f"against every image of {evaluator['ann_file']}: the "
                'objects of the images not tested would count as missed. '
                f'Unset indices and {ADVICE}.')


def _data_path(ds: dict, path: str) -> str:
    """``path`` as the dataset reads it (joined to ``data_root`` when
    relative, as MMEngine's ``BaseDataset`` does)."""
    root = ds.get('data_root')
    if root and not osp.isabs(path):
        return osp.join(root, path)
    return path


def _load(path: str) -> dict:
    if not osp.isfile(path):
        raise FileNotFoundError(f'no annotation file {path}')
    with open(path) as f:
        coco = json.load(f)
    if not isinstance(coco, dict) or not isinstance(
            coco.get('images'), list):
        raise ValueError(f'{path} is not a COCO annotation file (no '
                         '"images" list)')
    return coco


def subset_coco(coco: dict, img_ids: Sequence[int], source: str) -> dict:
    """``coco`` with only the images ``img_ids`` and their annotations
    (categories and the other keys unchanged).

    Raises:
        KeyError: An id of ``img_ids`` is not in ``coco`` (``source``
            names the file).
    """
    wanted = set(img_ids)
    images = [img for img in coco['images'] if img['id'] in wanted]
    missing = wanted - {img['id'] for img in images}
    if missing:
        raise KeyError(f'{source} has no image with id '
                       f'{sorted(missing)[:5]} (the tested images)')
    out = {k: v for k, v in coco.items() if k not in ('images',
                                                      'annotations')}
    out['images'] = images
    out['annotations'] = [a for a in coco.get('annotations', [])
                          if a['image_id'] in wanted]
    return out


def _dataset_length(ds_cfg, scope: str) -> int:
    """How many images the test set of ``ds_cfg`` holds (built without
    its pipeline: only its annotations are read)."""
    from mmdet.registry import DATASETS
    from mmengine.registry import init_default_scope

    import cbnet_mmdet  # noqa: F401  (the project's dataset types)
    init_default_scope(scope)
    ds_cfg = copy.deepcopy(ds_cfg)
    ds_cfg.update(pipeline=[], lazy_init=False)
    return len(DATASETS.build(ds_cfg))


def first_images_cfg(cfg: Config, num_images: int, out_dir: str) -> Config:
    """Copy of ``cfg`` that tests and scores its first ``num_images``
    test images only.

    Args:
        cfg (Config): A test config (``test_dataloader``,
            ``test_evaluator``).
        num_images (int): How many images, from the first of the test set
            (the order of the COCO file's ``images``).
        out_dir (str): Where the cut annotation files are written
            (``first_{N}_{name}.json``).

    Returns:
        Config: The modified copy.

    Raises:
        ValueError: ``num_images`` < 1 or more than the set holds;
            ``indices`` already set; a dataset wrapper; a set without a
            COCO file whose evaluators read an ``ann_file``.
    """
    if isinstance(num_images, bool) or not isinstance(num_images, int) \
            or num_images < 1:
        raise ValueError(f'num_images must be a positive integer, got '
                         f'{num_images!r}')
    cfg = copy.deepcopy(cfg)
    ds = cfg.test_dataloader.dataset
    if ds.get('indices') is not None:
        raise ValueError('test_dataloader.dataset.indices is set: give '
                         'either it or num_images, not both')
    if 'dataset' in ds or 'datasets' in ds:
        raise ValueError(f'num_images needs the test set itself, not the '
                         f"wrapper {ds.get('type')}: set it on the wrapped "
                         'dataset')
    evaluators = _evaluators(cfg)
    ann_file = ds.get('ann_file') or ''
    if not ann_file.endswith('.json'):
        readers = [e.get('type') for e in evaluators if e.get('ann_file')]
        if readers:
            raise ValueError(
                f"test set {ds.get('type')} has no COCO ann_file to cut, "
                f'and {readers} read a whole annotation file')
        # the metrics build the ground truth from the tested images; a
        # set that holds fewer is refused, as a COCO file's is (MMEngine's
        # indices would silently test them all)
        held = _dataset_length(ds, cfg.get('default_scope', 'mmdet'))
        if num_images > held:
            raise ValueError(f"num_images={num_images} but the test set "
                             f"({ds.get('type')} at {ds.get('data_root')}) "
                             f'holds {held} images')
        ds.indices = num_images
        return cfg
    path = _data_path(ds, ann_file)
    coco = _load(path)
    if num_images > len(coco['images']):
        raise ValueError(f'num_images={num_images} but {path} holds '
                         f"{len(coco['images'])} images")
    img_ids = [img['id'] for img in coco['images'][:num_images]]
    os.makedirs(out_dir, exist_ok=True)
    written = {}

    def write(source: str, data: dict) -> str:
        if source not in written:
            name = f'first_{num_images}_{len(written)}_' \
                f'{osp.basename(source)}'
            target = osp.abspath(osp.join(out_dir, name))
            with open(target, 'w') as f:
                json.dump(subset_coco(data, img_ids, source), f)
            written[source] = target
        return written[source]

    ds.ann_file = write(path, coco)
    for evaluator in evaluators:
        source = evaluator.get('ann_file')
        if source:
            evaluator['ann_file'] = write(
                source, coco if source == path else _load(source))
    if isinstance(cfg.test_evaluator, (list, tuple)):
        cfg.test_evaluator = evaluators
    else:
        cfg.test_evaluator = evaluators[0]
    return cfg

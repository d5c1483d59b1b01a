"""Malformed-input sweep: the engine of
``tools/analysis_tools/fuzz_inputs.py``, which documents the mutations,
the checks and the outcomes. :func:`sweep` runs it, :func:`markdown`
reports it; :func:`make_variant`, :func:`audit` and :func:`build` are its
parts.
"""
import copy
import json
import math
import multiprocessing
import os
import os.path as osp
import resource
import shutil
import traceback
from collections import Counter, defaultdict
from typing import Callable, Dict, List, Tuple

import cv2
import numpy as np
import torch
from mmdet.registry import DATASETS, MODELS
from mmengine.config import Config
from mmengine.dataset import pseudo_collate
from mmengine.registry import init_default_scope
from pycocotools import mask as mask_utils

import cbnet_mmdet  # noqa: F401  (registers the components)
from cbnet_mmdet.datasets.cityscapes_paths import foggy_path
from cbnet_tools.markdown import markdown_table

from .config_edits import configs_root

PACKAGE_DIR = osp.dirname(osp.abspath(cbnet_mmdet.__file__)) + os.sep
DEMO = osp.join(configs_root(), 'demo',
                'cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py')
ANN = osp.join('annotations', 'instancesonly_filtered_gtFine_train.json')
CLEAR_TYPES = (FileNotFoundError, ValueError, KeyError, TypeError)
OUTCOMES = ('ok', 'logged drop', 'clear error', 'silent', 'crash')

# -- mutations --------------------------------------------------------------
# A JSON mutation takes (coco dict, rng) and edits it in place; an image
# mutation takes (original image path, output path, rng) and writes a file.


def _ann(coco, rng):
    anns = coco['annotations']
    return anns[int(rng.integers(len(anns)))]


def _box(value):
    def mutate(coco, rng):
        a = _ann(coco, rng)
        x, y, w, h = a['bbox']
        a['bbox'] = value(x, y, w, h, rng)
    return mutate


def _drop(key, where):
    def mutate(coco, rng):
        if where == 'top':
            coco.pop(key, None)
        else:
            for item in coco[where]:
                item.pop(key, None)
    return mutate


def _set(where, key, value):
    def mutate(coco, rng):
        items = coco[where]
        item = items[int(rng.integers(len(items)))]
        item[key] = value(item, rng) if callable(value) else value
    return mutate


def _all_crowd(coco, rng):
    for a in coco['annotations']:
        a['iscrowd'] = 1


def _no_annotations(coco, rng):
    coco['annotations'] = []


def _dup_image_id(coco, rng):
    coco['images'][1]['id'] = coco['images'][0]['id']


def _many_tiny(coco, rng):
    img = coco['images'][0]
    for i in range(200):
        x, y = float(rng.uniform(0, img['width'] - 2)), float(
            rng.uniform(0, img['height'] - 2))
        coco['annotations'].append(
            dict(id=10**6 + i, image_id=img['id'], category_id=26,
                 iscrowd=0, area=1.0, bbox=[x, y, 1.0, 1.0],
                 segmentation=[[x, y, x + 1, y, x + 1, y + 1]]))


def _category(name, edit):
    """Edit the categories list around the category called ``name``."""
    def mutate(coco, rng):
        cats = coco['categories']
        index = next(i for i, c in enumerate(cats) if c['name'] == name)
        edit(cats, index)
    return mutate


def _drop_class(coco, rng):
    """Remove the class 'rider' from the file: its category and its
    annotations (a set without riders); the classes after it must keep
    their labels."""
    cat = next(c for c in coco['categories'] if c['name'] == 'rider')
    coco['categories'].remove(cat)
    coco['annotations'] = [a for a in coco['annotations']
                           if a['category_id'] != cat['id']]


def _reverse_categories(coco, rng):
    coco['categories'].reverse()


def _dup_ann_id(coco, rng):
    coco['annotations'][1]['id'] = coco['annotations'][0]['id']


def _dup_file_name(coco, rng):
    coco['images'][1]['file_name'] = coco['images'][0]['file_name']


def _rle_ann(coco, rng):
    """A random annotation given as RLE (the converter writes RLE)."""
    anns = [a for a in coco['annotations']
            if isinstance(a.get('segmentation'), dict)]
    return anns[int(rng.integers(len(anns)))]


def _rle_short(coco, rng):
    """Counts of a mask one column narrower than the image: they sum to
    less than height x width."""
    a = _rle_ann(coco, rng)
    h, w = a['segmentation']['size']
    rle = mask_utils.encode(np.zeros((h, w - 1), np.uint8, order='F'))
    a['segmentation']['counts'] = rle['counts'].decode()


def _rle_long(coco, rng):
    a = _rle_ann(coco, rng)
    h, w = a['segmentation']['size']
    a['segmentation']['counts'] = [h * w - 7, 50]


def _polygon(value):
    """Replace a segmentation by a triangle of the box with one coordinate
    set to ``value``."""
    def mutate(coco, rng):
        a = _ann(coco, rng)
        x, y, w, h = a['bbox']
        poly = [x, y, x + w, y, x + w, y + h]
        poly[int(rng.integers(6))] = value
        a['segmentation'] = [poly]
    return mutate


def _shift_box(coco, rng):
    a = _ann(coco, rng)
    x, y, w, h = a['bbox']
    a['bbox'] = [x + w + 10.0, y, w, h]


JSON_MUTATIONS: Dict[str, Callable] = {
    'bbox_negative_size': _box(lambda x, y, w, h, r: [x, y, -w, -h]),
    'bbox_zero_size': _box(lambda x, y, w, h, r: [x, y, 0.0, 0.0]),
    'bbox_outside_image': _box(lambda x, y, w, h, r: [5000., 5000., w, h]),
    'bbox_partly_outside': _box(lambda x, y, w, h, r: [-20., -20., w + 40,
                                                       h + 40]),
    'bbox_nan': _box(lambda x, y, w, h, r: [float('nan'), y, w, h]),
    'bbox_inf': _box(lambda x, y, w, h, r: [x, y, float('inf'), h]),
    'bbox_wrong_length': _box(lambda x, y, w, h, r: [x, y, w]),
    'bbox_string': _box(lambda x, y, w, h, r: 'abc'),
    'bbox_missing': _set('annotations', 'bbox', None),
    'segm_empty_list': _set('annotations', 'segmentation', []),
    'segm_two_points': _set('annotations', 'segmentation',
                            [[1.0, 1.0, 5.0, 5.0]]),
    'segm_odd_length': _set('annotations', 'segmentation',
                            [[1.0, 1.0, 9.0, 1.0, 9.0]]),
    'segm_rle_wrong_size': _set(
        'annotations', 'segmentation',
        dict(size=[7, 9], counts='0`0')),
    'segm_rle_garbage': _set('annotations', 'segmentation',
                             dict(size=[128, 256], counts='!!!!')),
    'segm_outside_image': _set(
        'annotations', 'segmentation',
        [[5000.0, 5000.0, 5010.0, 5000.0, 5010.0, 5010.0]]),
    'category_unknown': _set('annotations', 'category_id', 999),
    'category_string': _set('annotations', 'category_id', 'car'),
    'image_id_dangling': _set('annotations', 'image_id', 12345),
    'iscrowd_all': _all_crowd,
    'no_annotations': _no_annotations,
    'duplicate_image_id': _dup_image_id,
    'image_size_wrong': _set('images', 'width', 17),
    'image_size_zero': _set('images', 'height', 0),
    'file_name_missing_file': _set('images', 'file_name',
                                   'nowhere/none_leftImg8bit.png'),
    'file_name_empty': _set('images', 'file_name', ''),
    'key_images_missing': _drop('images', 'top'),
    'key_annotations_missing': _drop('annotations', 'top'),
    'key_categories_missing': _drop('categories', 'top'),
    'image_key_id_missing': _drop('id', 'images'),
    'ann_key_image_id_missing': _drop('image_id', 'annotations'),
    'many_tiny_instances': _many_tiny,
    'json_truncated': lambda coco, rng: None,  # cut when written
    'json_top_level_list': lambda coco, rng: None,  # written as a list
    # labels by category NAME: missing, reordered, renamed, duplicated
    'category_missing_used': _category('car', lambda c, i: c.pop(i)),
    'category_missing_first': _category('person', lambda c, i: c.pop(i)),
    'category_missing_train': _category('train', lambda c, i: c.pop(i)),
    'class_absent': _drop_class,
    'categories_reversed': _reverse_categories,
    'category_renamed': _category(
        'car', lambda c, i: c[i].update(name='automobile')),
    'category_duplicate_name': _category(
        'car', lambda c, i: c[i].update(name=c[i - 1]['name'])),
    # ids: unique and typed
    'image_id_string': _set('images', 'id', lambda it, r: str(it['id'])),
    'image_id_float': _set('images', 'id', lambda it, r: it['id'] + 0.0),
    'ann_image_id_string': _set('annotations', 'image_id',
                                lambda it, r: str(it['image_id'])),
    'duplicate_ann_id': _dup_ann_id,
    'duplicate_file_name': _dup_file_name,
    # values
    'iscrowd_string': _set('annotations', 'iscrowd', '0'),
    'iscrowd_two': _set('annotations', 'iscrowd', 2),
    'rle_counts_short': _rle_short,
    'rle_counts_long': _rle_long,
    'polygon_huge': _polygon(1e30),
    'polygon_nan': _polygon(float('nan')),
    'bbox_mask_mismatch': _shift_box,
    'bbox_below_1px': _box(lambda x, y, w, h, r: [x, y, 0.5, h]),
    'area_zero': _set('annotations', 'area', 0),
    'ignore_true': _set('annotations', 'ignore', True),
}


def _truncate(src, dst, rng):
    data = open(src, 'rb').read()
    open(dst, 'wb').write(data[:int(rng.integers(1, len(data)))])


def _random_bytes(src, dst, rng):
    open(dst, 'wb').write(rng.bytes(int(rng.integers(1, 4096))))


def _flip_bytes(src, dst, rng):
    data = bytearray(open(src, 'rb').read())
    for pos in rng.integers(8, len(data), 16):
        data[pos] ^= 0xFF
    open(dst, 'wb').write(bytes(data))


def _rewrite(convert):
    def mutate(src, dst, rng):
        cv2.imwrite(dst, convert(cv2.imread(src, cv2.IMREAD_COLOR)))
    return mutate


IMAGE_MUTATIONS: Dict[str, Callable] = {
    'img_truncated': _truncate,
    'img_random_bytes': _random_bytes,
    'img_flipped_bytes': _flip_bytes,
    'img_empty_file': lambda s, d, r: open(d, 'wb').close(),
    'img_grey': _rewrite(lambda im: cv2.cvtColor(im, cv2.COLOR_BGR2GRAY)),
    'img_16bit': _rewrite(lambda im: im.astype(np.uint16) * 257),
    'img_rgba': _rewrite(lambda im: cv2.cvtColor(im, cv2.COLOR_BGR2BGRA)),
    'img_1x1': _rewrite(lambda im: im[:1, :1]),
    'img_smaller_than_ann': _rewrite(lambda im: im[:40, :60]),
    'img_directory': lambda s, d, r: os.makedirs(d),
}
#: The foggy twin of one image, read with the paired (CBNet-DD) dataset.
FOGGY_MUTATIONS: Dict[str, Callable] = {
    'foggy_twin_empty': IMAGE_MUTATIONS['img_empty_file'],
    'foggy_twin_truncated': _truncate,
}
MUTATIONS = sorted(JSON_MUTATIONS) + sorted(IMAGE_MUTATIONS) + sorted(
    FOGGY_MUTATIONS)
#: Fog density of the paired variants.
BETA = 0.02
#: Pipeline of the paired variants (no training step: the demo detector
#: takes one image; CBNet-DD's distiller would train on the pair).
PAIRED_PIPELINE = [
    dict(type='CBNetLoadPairedImageFromFile'),
    dict(type='LoadAnnotations', with_bbox=True, with_mask=True),
    dict(type='PackDetInputs'),
]

# -- one variant ------------------------------------------------------------


def make_variant(root: str, out_dir: str, name: str, num_images: int,
                 rng: np.random.Generator) -> Tuple[str, str]:
    """Write the mutated annotation file (and image) of one variant.

    Returns:
        tuple[str, str]: The annotation file and the mutated file (the
        annotation file itself for JSON mutations).
    """
    with open(osp.join(root, ANN)) as f:
        coco = json.load(f)
    keep = [im['id'] for im in coco['images'][:num_images]]
    coco['images'] = coco['images'][:num_images]
    coco['annotations'] = [
        a for a in coco['annotations'] if a['image_id'] in keep
    ]
    os.makedirs(out_dir, exist_ok=True)
    ann_file = osp.join(out_dir, 'train.json')
    mutated = ann_file
    if name in JSON_MUTATIONS:
        JSON_MUTATIONS[name](coco, rng)
    else:
        # an image the training set keeps (one with a non-crowd instance):
        # a mutated image that filter_cfg leaves out would test nothing
        trained = {a['image_id'] for a in coco['annotations']
                   if not a.get('iscrowd')}
        kept = [i for i, im in enumerate(coco['images'])
                if im['id'] in trained] or list(range(len(coco['images'])))
        index = kept[int(rng.integers(len(kept)))]
        image = coco['images'][index]
        src = osp.join(root, 'leftImg8bit', 'train', image['file_name'])
        if name in IMAGE_MUTATIONS:
            mutated = osp.join(out_dir, f'mutated_{index}.png')
            IMAGE_MUTATIONS[name](src, mutated, rng)
            image['file_name'] = mutated  # absolute: os.path.join keeps it
        else:  # a copy of the clear image, its foggy twin mutated
            clear = osp.join(out_dir, 'leftImg8bit', 'train',
                             image['file_name'])
            mutated = foggy_path(clear, BETA)
            for path in (clear, mutated):
                os.makedirs(osp.dirname(path), exist_ok=True)
            shutil.copy(src, clear)
            FOGGY_MUTATIONS[name](foggy_path(src, BETA), mutated, rng)
            image['file_name'] = clear
    with open(ann_file, 'w') as f:
        if name == 'json_truncated':
            f.write(json.dumps(coco)[:100])
        elif name == 'json_top_level_list':
            json.dump([coco], f)
        else:
            json.dump(coco, f)  # NaN as the token NaN, as Python reads it
    return ann_file, mutated


def build(data_root: str, scale: Tuple[int, int]):
    """The demo model (train mode) and its dataset config at ``scale``."""
    init_default_scope('mmdet')
    cfg = Config.fromfile(DEMO)
    dataset = copy.deepcopy(cfg.train_dataloader.dataset.dataset)
    for t in dataset.pipeline:
        if t['type'] == 'Resize':
            t['scale'] = scale
    dataset.update(data_root=data_root,
                   data_prefix=dict(img='leftImg8bit/train/'))
    torch.manual_seed(0)
    model = MODELS.build(cfg.model)
    model.init_weights()  # the heads' own init (focal priors, zero-inits)
    return model.train(), dataset


def _instance_key(file_name, name, crowd, box, mask) -> tuple:
    return (file_name, name, bool(crowd), tuple(round(float(v), 3)
                                                for v in box),
            json.dumps(mask, sort_keys=True))


def audit(dataset, ann_file: str, image_dir: str) -> List[str]:
    """What the dataset lost or changed without counting it.

    The reference is the annotation file itself, read here: an
    annotation belongs to the image(s) whose ``id`` equals its
    ``image_id`` (same type), its class is the NAME of its category, its
    crowd flag ``iscrowd == 1``, its box ``[x, y, x + w, y + h]``.

    Args:
        dataset: A fully initialised ``CBNetCityscapesDataset``.
        ann_file (str): The (mutated) file it read.
        image_dir (str): ``data_prefix.img`` (removed from ``img_path``).

    Returns:
        list[str]: One line per problem: a loaded instance that matches no
        annotation of the file (a changed label, crowd flag, box or mask),
        annotations or images missing from what was loaded AND from the
        dataset's ``load_report`` (drops logged per reason, what
        ``filter_cfg`` left out). Empty: everything accounted for.
    """
    with open(ann_file) as f:
        coco = json.load(f)
    if not isinstance(coco, dict):
        return [f'loaded {len(dataset)} images from a JSON '
                f'{type(coco).__name__}']
    typed = lambda v: (type(v), v)  # noqa: E731  (1 and 1.0 and '1' differ)
    classes = dataset.metainfo['classes']
    names = {typed(c.get('id')): c.get('name') for c in coco['categories']}
    files: Dict[tuple, List[str]] = defaultdict(list)
    for img in coco['images']:
        files[typed(img.get('id'))].append(img.get('file_name'))
    reference = Counter()
    for a in coco['annotations']:
        try:
            x, y, w, h = a['bbox']
            box = [x, y, x + w, y + h]
        except (KeyError, TypeError, ValueError):
            box = [math.nan] * 4  # matches nothing
        for file_name in files.get(typed(a.get('image_id')), []):
            reference[_instance_key(
                file_name, names.get(typed(a.get('category_id'))),
                a.get('iscrowd', 0) == 1, box,
                a.get('segmentation'))] += 1
    loaded = Counter()
    for i in range(len(dataset)):
        info = dataset.get_data_info(i)
        file_name = info['img_path']  # absolute for mutated images
        if file_name.startswith(image_dir):
            file_name = osp.relpath(file_name, image_dir)
        for inst in info['instances']:
            loaded[_instance_key(file_name, classes[inst['bbox_label']],
                                 inst['ignore_flag'], inst['bbox'],
                                 inst.get('mask'))] += 1
    problems = [
        f'loaded instance matches no annotation: {key[:4]}'
        for key in (loaded - reference)
    ]
    report = getattr(dataset, 'load_report', None) or {}
    dropped = sum(report.get('drops', {}).values())
    filtered = report.get('filtered_instances', 0)
    lost = len(coco['annotations']) - sum(loaded.values())
    if lost != dropped + filtered:
        problems.append(
            f'{lost} of {len(coco["annotations"])} annotations not loaded, '
            f'{dropped} logged as dropped and {filtered} left out by '
            f'filter_cfg')
    missing = len(coco['images']) - len(dataset)
    if missing != report.get('filtered_images', 0):
        problems.append(
            f'{missing} of {len(coco["images"])} images not loaded, '
            f'{report.get("filtered_images", 0)} counted as left out by '
            f'filter_cfg')
    return problems


def run_variant(model, dataset_cfg: dict, ann_file: str,
                paired: bool = False) -> dict:
    """Dataset (audited) + pipeline + one forward/backward.

    Args:
        paired (bool): Read with ``CBNetPairedFoggyDataset`` and
            :data:`PAIRED_PIPELINE` instead, without the training step.

    Returns:
        dict: ``outcome`` (``'ok'``, ``'logged drop'`` or ``'silent'``)
        and ``problems`` (of :func:`audit`); errors are raised.
    """
    cfg = copy.deepcopy(dataset_cfg)
    cfg.ann_file = ann_file
    if paired:
        cfg.update(type='CBNetPairedFoggyDataset', beta=BETA,
                   pipeline=PAIRED_PIPELINE)
    dataset = DATASETS.build(cfg)
    dataset.full_init()
    problems = audit(dataset, ann_file, dataset.data_prefix['img'])
    items = [dataset[i] for i in range(len(dataset))]
    if items and not paired:
        data = model.data_preprocessor(pseudo_collate(items), True)
        model.zero_grad()
        losses = model(**data, mode='loss')
        total, log_vars = model.parse_losses(losses)
        bad = [k for k, v in log_vars.items()
               if not torch.isfinite(v).all()]
        if bad:
            raise FloatingPointError(f'non-finite losses {bad}')
        total.backward()
        bad = [
            n for n, p in model.named_parameters()
            if p.grad is not None and not torch.isfinite(p.grad).all()
        ]
        if bad:
            raise FloatingPointError(f'non-finite gradients {bad[:3]}')
    if problems:
        return dict(outcome='silent', problems=problems)
    drops = (getattr(dataset, 'load_report', None) or {}).get('drops')
    return dict(outcome='logged drop' if drops else 'ok', problems=[])


def _vm_bytes() -> int:
    """This process's virtual memory size (Linux), 0 if unknown."""
    try:
        with open('/proc/self/status') as f:
            for line in f:
                if line.startswith('VmSize:'):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return 0


def _child(conn, model, dataset_cfg, ann_file, mutated, memory_gb,
           paired):
    """Run one variant in a forked process; send its result."""
    if memory_gb:
        limit = _vm_bytes() + int(memory_gb * 2**30)
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    try:
        result = run_variant(model, dataset_cfg, ann_file, paired)
    except BaseException as err:  # noqa: B902  (the point of the sweep)
        result = dict(
            outcome=classify(err, mutated, ann_file),
            error=f'{type(err).__name__}: {err}'[:500],
            where=traceback.format_exception(err)[-2][:300])
    conn.send(result)
    conn.close()


def run_isolated(model, dataset_cfg: dict, ann_file: str, mutated: str,
                 timeout: float = 600, memory_gb: float = 4,
                 paired: bool = False) -> dict:
    """:func:`run_variant` (and :func:`classify`) in a forked child: a
    segfault, a kill or a hang there is a ``crash`` outcome here."""
    ctx = multiprocessing.get_context('fork')
    recv, send = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_child, args=(send, model, dataset_cfg,
                                            ann_file, mutated, memory_gb,
                                            paired))
    proc.start()
    send.close()
    result = None
    if recv.poll(timeout):
        try:
            result = recv.recv()
        except EOFError:  # the child died without a word
            pass
    proc.join(5 if result is not None else 0)
    if proc.is_alive():
        proc.kill()
        proc.join()
    if result is None:
        code = proc.exitcode
        why = f'killed by signal {-code}' if code and code < 0 else \
            f'exit code {code}' if code is not None else 'timed out'
        result = dict(outcome='crash', error=f'child process {why}',
                      where='')
    return result


def raised_in_package(err: BaseException) -> bool:
    """Whether ``err`` was raised by the package's own code (its last frame
    lies in the ``cbnet_mmdet`` package directory; a checkout or virtual
    environment that merely has ``cbnet_mmdet`` in its path does not
    count)."""
    frames = traceback.extract_tb(err.__traceback__)
    return bool(frames) and osp.abspath(frames[-1].filename).startswith(
        PACKAGE_DIR)


def classify(err: BaseException, mutated: str, ann_file: str) -> str:
    """``'clear error'`` or ``'crash'`` (see the module docstring)."""
    text = str(err)
    names = mutated in text or ann_file in text
    clear = isinstance(err, CLEAR_TYPES) and raised_in_package(err) and names
    return 'clear error' if clear else 'crash'


def sweep(data_root: str, variants: int, seed: int, num_images: int,
          scale: Tuple[int, int], work: str,
          mutations: List[str] = None, isolate: bool = True,
          memory_gb: float = 4) -> dict:
    """Run ``variants`` random variants (mutations cycled, random details).

    Args:
        isolate (bool): Each variant in a forked child (see
            :func:`run_isolated`); False runs them in this process.
        memory_gb (float): The child's address space beyond the parent's.

    Returns:
        dict: ``tried``, ``outcomes`` (count per outcome of
        :data:`OUTCOMES`), ``per_mutation``, ``silent`` (mutation,
        variant, problems) and ``crashes`` (mutation, variant, error).
    """
    mutations = mutations or MUTATIONS
    model, dataset_cfg = build(data_root, scale)
    rng = np.random.default_rng(seed)
    per_mutation: Dict[str, Counter] = defaultdict(Counter)
    crashes, silent, outcomes = [], [], Counter()
    for i in range(variants):
        name = mutations[i % len(mutations)]
        out_dir = osp.join(work, f'{i:04d}_{name}')
        ann_file, mutated = make_variant(data_root, out_dir, name,
                                         num_images, rng)
        paired = name in FOGGY_MUTATIONS
        if isolate:
            result = run_isolated(model, dataset_cfg, ann_file, mutated,
                                  memory_gb=memory_gb, paired=paired)
        else:
            try:
                result = run_variant(model, dataset_cfg, ann_file, paired)
            except Exception as err:  # noqa: B902  (the point of the sweep)
                result = dict(outcome=classify(err, mutated, ann_file),
                              error=f'{type(err).__name__}: {err}'[:500],
                              where=traceback.format_exception(err)[-2]
                              [:300])
        outcome = result['outcome']
        if outcome == 'crash':
            crashes.append(dict(mutation=name, variant=out_dir,
                                error=result['error'],
                                where=result['where']))
        elif outcome == 'silent':
            silent.append(dict(mutation=name, variant=out_dir,
                               problems=result['problems']))
        per_mutation[name][outcome] += 1
        outcomes[outcome] += 1
        shutil.rmtree(out_dir, ignore_errors=True)
    return dict(tried=variants,
                outcomes={k: outcomes.get(k, 0) for k in OUTCOMES},
                per_mutation={k: dict(v) for k, v in per_mutation.items()},
                silent=silent, crashes=crashes)


def markdown(result: dict) -> str:
    """One row per mutation and a total: tries and count per outcome."""
    rows = [[name, sum(c.values())] + [c.get(k, 0) for k in OUTCOMES]
            for name, c in sorted(result['per_mutation'].items())]
    o = result['outcomes']
    rows.append(['**total**', result['tried']] +
                [o.get(k, 0) for k in OUTCOMES])
    return '\n'.join(
        markdown_table(['mutation', 'tried'] + list(OUTCOMES), rows))

"""model-index.yml and the metafiles, read as mim and MMEngine
read them."""
import glob
import json
import os.path as osp

import pytest
from mim.commands.search import convert2df
from mmengine.infer import BaseInferencer
from modelindex import load
from record_helpers import seed_values

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__))))
#: The configs of the plugin and of the projects (the peer baseline's).
SHIPPED = sorted(
    osp.relpath(p, ROOT)
    for p in glob.glob(osp.join(ROOT, 'configs', '**', '*.py'),
                       recursive=True) +
    glob.glob(osp.join(ROOT, 'projects', '*', 'configs', '**', '*.py'),
              recursive=True) if '_base_' not in p and
    # the experiment sets are no model configs
    osp.join('configs', 'experiments') not in p)


@pytest.fixture(scope='module')
def models():
    return list(BaseInferencer._get_models_from_metafile(ROOT))


def test_every_shipped_config_is_indexed_once(models):
    configs = [m['Config'] for m in models]
    assert sorted(configs) == SHIPPED
    for m in models:
        assert osp.isfile(osp.join(ROOT, m['Config']))
        assert m['Name'] == osp.splitext(osp.basename(m['Config']))[0]


#: The longest "Dataset/metric" key that `mim search --config X` prints
#: with its value on an 80-column terminal: with an 85-character key
#: (2026-11-26) it printed every key of every model without a value.
MIM_KEY_CHARS = 72


def test_results_fit_mims_table(models):
    keys = [f"{r['Dataset']}/{metric}" for m in models
            for r in m['Results'] for metric in r['Metrics']]
    assert max(map(len, keys)) <= MIM_KEY_CHARS, max(keys, key=len)


def test_no_weights_url(models):
    """Nothing is published yet: a Weights URL would be a dead link."""
    assert not [m['Name'] for m in models if 'Weights' in m]


def test_results_say_whose_numbers_they_are(models):
    for m in models:
        for result in m['Results']:
            dataset = result['Dataset']
            assert '(paper, Table ' in dataset or \
                dataset.endswith('(ours, generated data)') or \
                dataset.endswith('(ours, real photographs, 3-seed mean)'), \
                dataset
            # ours only for what the project trained: the demo on its
            # generated data, the pretrained-trunk recipes on real photos
            # (the plugin's and the peer baseline's dehaze-then-detect)
            if dataset.endswith('(ours, generated data)'):
                assert m['Config'].startswith('configs/demo/')
            if 'real photographs' in dataset:
                assert m['Config'].startswith(
                    ('configs/pretrained/', 'configs/yolox_coco/',
                     'configs/coco_trunk/',
                     'projects/peer_dehaze/configs/pretrained/',
                     'projects/peer_dehaze/configs/coco_trunk/',
                     'projects/peer_dehaze/configs/yolox_coco/'))
            for value in result['Metrics'].values():
                assert 0 <= value <= 100


#: The metafiles' metric names -> the comparison records' metric keys.
RECORD_KEYS = {'box AP': 'coco/bbox_mAP', 'box AP50': 'coco/bbox_mAP_50',
               'mask AP': 'coco/segm_mAP', 'mask AP50': 'coco/segm_mAP_50'}


def record_means(config, min_seeds=3, root=ROOT):
    """Per (record, recipe, condition) of every comparison record under
    ``root``/docs that ran ``config`` with at least ``min_seeds`` seeds:
    the mean of each metric over its seeds, in percent."""
    means = {}
    for path in glob.glob(osp.join(root, 'docs', '**', '*.json'),
                          recursive=True):
        with open(path, encoding='utf-8') as f:
            record = json.load(f)
        for (recipe, condition, key), values in seed_values(
                record, config).items():
            if len({seed for seed, _ in values}) >= min_seeds:
                means.setdefault((osp.relpath(path, root), recipe, condition),
                                 {})[key] = (sum(v for _, v in values) /
                                             len(values))
    return means


def real_photo_results(models):
    return [(m['Config'], result['Metrics']) for m in models
            for result in m['Results']
            if result['Dataset'].endswith('(ours, real photographs, 3-seed '
                                          'mean)')]


def test_our_real_photo_results_are_record_means(models):
    """Every '3-seed mean' of a metafile is the mean over 3 seeds of one
    record under docs/ that ran that config."""
    results = real_photo_results(models)
    assert len(results) >= 5, results
    for config, metrics in results:
        means = record_means(config)
        assert means, f'{config}: no record under docs/ has 3 seeds of it'
        assert any(
            all(abs(mean[RECORD_KEYS[name]] - value) <= 0.05 + 1e-9
                for name, value in metrics.items())
            for mean in means.values()), (
                f'{config}: {metrics} is no 3-seed mean of '
                f'{sorted(means)}')


def test_record_means_see_seeds_and_configs(tmp_path):
    """The check above fails on a config with fewer than 3 seeds or a
    mean that is not the record's."""
    docs = tmp_path / 'docs'
    docs.mkdir()
    runs = [dict(recipe='r', seed=s, config='configs/x/a.py',
                 metrics={'fog': {'coco/bbox_mAP': v}})
            for s, v in enumerate((0.10, 0.12, 0.14))]
    (docs / 'rec.json').write_text(json.dumps(dict(runs=runs)))
    root = str(tmp_path)
    means = record_means('configs/x/a.py', root=root)
    assert list(means) == [('docs/rec.json', 'r', 'fog')]
    assert abs(means[('docs/rec.json', 'r', 'fog')]['coco/bbox_mAP']
               - 12.0) < 1e-9
    assert record_means('configs/x/a.py', min_seeds=4, root=root) == {}
    assert record_means('configs/x/b.py', root=root) == {}


def test_mim_reads_the_index():
    """The table `mim search cbnet_mmdet` prints, built from the index."""
    df = convert2df(load(osp.join(ROOT, 'model-index.yml')))
    assert sorted(df.index) == sorted(
        osp.splitext(osp.basename(p))[0] for p in SHIPPED)
    assert 'weight' not in df.columns
    row = df.loc['cbnet-dd_mit-b5_nasfpn-crpn_8xb1-12e_foggy-cityscapes']
    assert row['foggy cityscapes (paper, table 2)/ap'] == 39.5
    assert row['model'] == 'cbnet-dd'
    demo = df.loc['cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like']
    assert demo['cityscapes-like val (ours, generated data)/miou'] > 0

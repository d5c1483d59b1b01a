"""Config edits of the lab (cbnet_lab/config_edits.py): one run's config
from a recipe, a budget and a seed."""
import os
import os.path as osp

import pytest

from cbnet_lab import config_edits as ce
from cbnet_lab.config_edits import reading, strip_pretrained
from cbnet_lab import recipe_comparison as rc

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__))))


def walk_strings(node, key=None):
    if isinstance(node, dict):
        for k, v in node.items():
            yield from walk_strings(v, k)
    elif isinstance(node, (list, tuple)):
        for v in node:
            yield from walk_strings(v, key)
    elif isinstance(node, str):
        yield key, node


@pytest.mark.parametrize('recipe', [r for s in ('arch', 'ablation')
                                    for r in rc.resolve_recipes(s)],
                         ids=lambda r: r[0])
def test_budget_cfg_moves_data_and_sets_the_budget(recipe, tmp_path):
    _, config = recipe
    budget = ce.Budget(iters=17, batch_size=3, lr=5e-4, warmup_iters=5,
                       num_workers=0)
    cfg = ce.budget_cfg(config, budget, seed=7, data_root='/data/x',
                        work_dir=str(tmp_path))
    strings = list(walk_strings(cfg._cfg_dict.to_dict()))
    roots = [v for k, v in strings if k == 'data_root']
    assert roots and set(roots) == {'/data/x/'}
    # evaluators carry absolute annotation paths; datasets relative ones
    anns = [v for k, v in strings if k == 'ann_file' and v.startswith('/')]
    assert anns and all(v.startswith('/data/x/') for v in anns), anns
    assert not [v for _, v in strings if 'cityscapes_like' in v]
    assert cfg.train_dataloader.batch_size == 3
    assert cfg.train_cfg == dict(type='IterBasedTrainLoop', max_iters=17,
                                 val_interval=18)
    assert cfg.val_dataloader is None and cfg.val_evaluator is None
    assert [s['end'] for s in cfg.param_scheduler] == [5, 17]
    assert cfg.optim_wrapper.optimizer.lr == 5e-4
    assert cfg.randomness.seed == 7
    assert cfg.test_dataloader.dataset.data_root == '/data/x/'


def test_data_root_needs_a_top_level_data_root(tmp_path):
    from mmengine.config import Config
    cfg = Config(dict(train_dataloader=dict()))
    with pytest.raises(KeyError, match='no top-level data_root'):
        ce.replace_data_root(cfg, '/x')


def resizes(cfg):
    found = []

    def walk(node):
        if isinstance(node, dict):
            if node.get('type') == 'Resize':
                found.append(tuple(node['scale']))
            for v in node.values():
                walk(v)
        elif isinstance(node, (list, tuple)):
            for v in node:
                walk(v)

    for key in ('train_dataloader', 'test_dataloader'):
        walk(cfg[key])
    return found


@pytest.mark.parametrize('recipe', [r for s in ('arch', 'ablation')
                                    for r in rc.resolve_recipes(s)],
                         ids=lambda r: r[0])
def test_budget_img_scale_resizes_every_pipeline(recipe, tmp_path):
    """The bench preset's image size reaches the training and the test
    pipelines of every recipe, wrapped and paired datasets included."""
    _, config = recipe
    cfg = ce.budget_cfg(config, ce.Budget(iters=2, img_scale=(512, 256)),
                        seed=0, data_root='/d', work_dir=str(tmp_path))
    found = resizes(cfg)
    assert len(found) >= 2 and set(found) == {(512, 256)}
    kept = ce.budget_cfg(config, ce.Budget(iters=2), seed=0,
                         data_root='/d', work_dir=str(tmp_path))
    assert set(resizes(kept)) == {(256, 128)}


def test_img_scale_without_a_resize_is_an_error():
    from mmengine.config import Config
    cfg = Config(dict(
        train_dataloader=dict(dataset=dict(pipeline=[dict(type='Pad')])),
        test_dataloader=dict(dataset=dict(pipeline=[
            dict(type='Resize', scale=(1, 1))]))))
    with pytest.raises(ValueError, match=r"no Resize .*\['train'\]"):
        ce.set_img_scale(cfg, (64, 32))
    with pytest.raises(ValueError, match='must be'):
        ce.set_img_scale(cfg, (64, 0))


def test_a_moved_run_resumes_from_its_own_folder(tmp_path):
    """MMEngine's marker names the ORIGINAL folder's file (absolute
    path); the run resumes from the copy in its work dir."""
    moved = tmp_path / 'moved'
    moved.mkdir()
    (moved / 'last_checkpoint').write_text(
        str(tmp_path / 'original' / 'iter_200.pth'))
    assert ce.resume_file(str(moved)) is None  # no copy: from scratch
    (moved / 'iter_200.pth').write_bytes(b'')
    assert ce.resume_file(str(moved)) == str(moved / 'iter_200.pth')
    assert rc.resume_iter(str(moved)) == 200


def test_a_recipes_own_load_from_is_kept_until_the_run_resumes(tmp_path):
    """A recipe that fine-tunes (``load_from`` in its config or in
    ``--cfg-options``) starts from those weights; before, the harness set
    ``load_from`` to None for every run that did not resume, so such a
    recipe silently trained from scratch. A killed run resumes from its
    own checkpoint, not from the fine-tuning weights."""
    crpn = osp.join(ROOT, 'configs', 'demo', 'rpn',
                    'crpn_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py')
    budget = ce.Budget(iters=6, batch_size=2, warmup_iters=2, num_workers=0)
    run_dir = str(tmp_path / 'run')
    init = str(tmp_path / 'pretrained.pth')
    cfg = ce.budget_cfg(crpn, budget, 0, 'data', run_dir,
                        cfg_options={'load_from': init})
    assert cfg.load_from == init and cfg.resume is False
    recipe = tmp_path / 'finetune.py'
    recipe.write_text(f"_base_ = ['{crpn}']\nload_from = '{init}'\n")
    cfg = ce.budget_cfg(str(recipe), budget, 0, 'data', run_dir)
    assert cfg.load_from == init and cfg.resume is False
    assert ce.budget_cfg(crpn, budget, 0, 'data', run_dir).load_from is None
    # '{seed}': each seed fine-tunes the same seed's weights
    cfg = ce.budget_cfg(crpn, budget, 2, 'data', run_dir, cfg_options={
        'load_from': 'work_dirs/compare/parts/CBNet/seed{seed}/iter_6.pth'})
    assert cfg.load_from == 'work_dirs/compare/parts/CBNet/seed2/iter_6.pth'
    # killed at iteration 3: resumes from its own checkpoint
    os.makedirs(run_dir)
    (tmp_path / 'run' / 'iter_3.pth').write_bytes(b'')
    (tmp_path / 'run' / 'last_checkpoint').write_text(
        osp.join(run_dir, 'iter_3.pth'))
    cfg = ce.budget_cfg(str(recipe), budget, 0, 'data', run_dir,
                        cfg_options={'load_from': init})
    assert cfg.load_from == osp.join(run_dir, 'iter_3.pth')
    assert cfg.resume is True


def test_keep_img_scale_keeps_the_configs_sizes(tmp_path):
    """The edge model's input size is part of the model: with its row's
    ``keep_img_scale`` every Resize keeps its config's size under a
    preset's."""
    recipe = osp.join(ROOT, 'configs', 'demo',
                      'cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py')
    own = set(resizes(ce.read_config(recipe)))
    assert own and (512, 256) not in own
    budget = ce.Budget(iters=2, img_scale=(512, 256))
    cfg = ce.budget_cfg(recipe, budget, seed=0, data_root='/d',
                        work_dir=str(tmp_path), keep_img_scale=True)
    assert set(resizes(cfg)) == own
    plain = ce.budget_cfg(recipe, budget, seed=0, data_root='/d',
                          work_dir=str(tmp_path))
    assert set(resizes(plain)) == {(512, 256)}


def test_read_config_parses_once_and_hands_out_copies(tmp_path,
                                                      monkeypatch):
    """The lab reads each recipe's config several times: parsed once per
    process (a ``mmdet::`` base costs MMEngine a read of every MMDet
    metafile), a fresh copy each call, read again when the file changes."""
    from mmengine.config import Config
    calls = []

    class Spy(Config):
        @staticmethod
        def fromfile(path):
            calls.append(path)
            return Config.fromfile(path)

    monkeypatch.setattr(reading, 'Config', Spy)
    monkeypatch.setattr(reading, '_READ_CONFIGS', {})
    path = tmp_path / 'recipe.py'
    path.write_text("_base_ = 'mmdet::_base_/default_runtime.py'\n"
                    "data_root = 'data/a/'\nnums = [1, 2]\n")
    first = ce.read_config(str(path))
    assert first.data_root == 'data/a/' and first.default_scope == 'mmdet'
    first.nums.append(3)
    first.data_root = 'elsewhere/'
    second = ce.read_config(str(path))
    assert len(calls) == 1
    assert second.nums == [1, 2] and second.data_root == 'data/a/'
    parsed = Config.fromfile(str(path))
    assert second.to_dict() == parsed.to_dict()
    # the same file, text and Python, without yapf's line breaks
    assert (second.filename, second.text, second.env_variables) == \
        (parsed.filename, parsed.text, parsed.env_variables)
    assert Config.fromstring(second.pretty_text, '.py').to_dict() == \
        second.to_dict()
    assert not second._format_python_code
    # rewritten in place (another size): read again
    path.write_text("_base_ = 'mmdet::_base_/default_runtime.py'\n"
                    "data_root = 'data/bb/'\n")
    assert ce.read_config(str(path)).data_root == 'data/bb/'
    assert len(calls) == 2
    # a config whose base reads the environment (as the pretrained
    # recipes' base reads CBNET_PRETRAINED_DIR) is read again when that
    # variable is set, changed or unset, and only then
    (tmp_path / 'trunk.py').write_text(
        "trunk = '{{$CBNET_TEST_TRUNK_DIR:~/cache}}/t.pth'\n")
    path = tmp_path / 'env.py'
    path.write_text("_base_ = './trunk.py'\nlr = 0.1\n")
    monkeypatch.delenv('CBNET_TEST_TRUNK_DIR', raising=False)
    assert ce.read_config(str(path)).trunk == '~/cache/t.pth'
    monkeypatch.setenv('CBNET_TEST_TRUNK_DIR', '/elsewhere')
    assert ce.read_config(str(path)).trunk == '/elsewhere/t.pth'
    monkeypatch.setenv('CBNET_TEST_OTHER', 'x')  # no config reads it
    assert ce.read_config(str(path)).trunk == '/elsewhere/t.pth'
    assert len(calls) == 4
    monkeypatch.delenv('CBNET_TEST_TRUNK_DIR')
    assert ce.read_config(str(path)).trunk == '~/cache/t.pth'
    assert len(calls) == 5
    with pytest.raises(FileNotFoundError, match='no_such.py'):
        ce.read_config(str(tmp_path / 'no_such.py'))


def test_strip_pretrained_any_depth():
    cfg = dict(
        backbone=dict(
            type='X', pretrained='a.pth',
            init_cfg=dict(type='Pretrained', checkpoint='a.pth')),
        neck=dict(init_cfg=[dict(type='Xavier'),
                            dict(type='Pretrained', checkpoint='b')]),
        head=dict(init_cfg=dict(type='Normal', std=0.01)))
    out = strip_pretrained(cfg)
    assert out['backbone'] == dict(type='X', init_cfg=None)
    assert out['neck']['init_cfg'] is None
    assert out['head'] == cfg['head']  # other inits untouched
    assert cfg['backbone']['pretrained'] == 'a.pth'  # input not modified

"""The train/test entry points parse what launchers and mim pass."""
import os
import os.path as osp

import pytest

from tool_helpers import load_tool


def _load(name):
    return load_tool(f'{name}.py')


@pytest.fixture
def clean_local_rank(monkeypatch, restore_environ):
    """No LOCAL_RANK during the test; whatever ``parse_args`` exports is
    undone afterwards (``monkeypatch.delenv`` of an unset variable records
    nothing to undo)."""
    monkeypatch.delenv('LOCAL_RANK', raising=False)


@pytest.mark.parametrize('flag', ['--local_rank', '--local-rank'])
@pytest.mark.parametrize('tool', ['train', 'test'])
def test_local_rank_both_spellings(tool, flag, clean_local_rank):
    mod = _load(tool)
    argv = ['cfg.py'] + (['ckpt.pth'] if tool == 'test' else [])
    args = mod.parse_args(argv + ['--launcher', 'none', flag, '3'])
    assert args.local_rank == 3
    assert os.environ['LOCAL_RANK'] == '3'


def test_torchrun_local_rank_env_wins(monkeypatch, restore_environ):
    monkeypatch.setenv('LOCAL_RANK', '1')
    args = _load('train').parse_args(['cfg.py', '--local-rank', '0'])
    assert args.local_rank == 0
    assert os.environ['LOCAL_RANK'] == '1'


def _write_cfg(tmp_path):
    cfg = tmp_path / 'tiny_cfg.py'
    cfg.write_text('optim_wrapper = dict(type="OptimWrapper", '
                   'optimizer=dict(type="SGD", lr=0.1))\n'
                   'auto_scale_lr = dict(enable=False, base_batch_size=8)\n'
                   'default_hooks = dict(visualization=dict(draw=False))\n'
                   'test_evaluator = dict(type="CocoMetric")\n')
    return str(cfg)


def test_train_cfg_overrides(tmp_path, clean_local_rank):
    mod = _load('train')
    cfg_path = _write_cfg(tmp_path)
    cfg = mod.build_cfg(
        mod.parse_args([
            cfg_path, '--amp', '--auto-scale-lr', '--resume', '--cfg-options',
            'optim_wrapper.optimizer.lr=0.5'
        ]))
    assert cfg.work_dir == osp.join('./work_dirs', 'tiny_cfg')
    assert cfg.optim_wrapper.type == 'AmpOptimWrapper'
    assert cfg.optim_wrapper.optimizer.lr == 0.5
    assert cfg.auto_scale_lr.enable is True
    assert cfg.resume is True and cfg.load_from is None


def test_train_resume_missing_checkpoint_is_clear(
        tmp_path, clean_local_rank):
    mod = _load('train')
    args = mod.parse_args(
        [_write_cfg(tmp_path), '--resume',
         str(tmp_path / 'nope.pth')])
    with pytest.raises(FileNotFoundError, match='nope.pth'):
        mod.build_cfg(args)


def test_test_tool_out_and_show_dir(tmp_path, clean_local_rank):
    mod = _load('test')
    ckpt = tmp_path / 'model.pth'
    ckpt.write_bytes(b'')
    cfg = mod.build_cfg(
        mod.parse_args([
            _write_cfg(tmp_path),
            str(ckpt), '--out',
            str(tmp_path / 'r.pkl'), '--show-dir', 'vis'
        ]))
    assert cfg.load_from == str(ckpt)
    assert [e['type'] for e in cfg.test_evaluator
            ] == ['CocoMetric', 'DumpDetResults']
    assert cfg.default_hooks.visualization.draw is True
    with pytest.raises(ValueError, match='.pkl'):
        mod.build_cfg(
            mod.parse_args(
                [_write_cfg(tmp_path),
                 str(ckpt), '--out', 'r.json']))


def test_test_tool_missing_checkpoint(tmp_path, clean_local_rank):
    mod = _load('test')
    with pytest.raises(FileNotFoundError, match='missing.pth'):
        mod.build_cfg(
            mod.parse_args(
                [_write_cfg(tmp_path),
                 str(tmp_path / 'missing.pth')]))


def test_train_strict_reaches_every_cbnet_dataset(tmp_path,
                                                  clean_local_rank):
    mod = _load('train')
    cfg_path = tmp_path / 'strict_cfg.py'
    cfg_path.write_text(
        'train_dataloader = dict(dataset=dict(type="RepeatDataset", '
        'times=2, dataset=dict(type="CBNetPairedFoggyDataset")))\n'
        'val_dataloader = dict(dataset=dict(type="ConcatDataset", datasets=['
        'dict(type="CBNetCityscapesDataset"), dict(type="CocoDataset")]))\n')
    cfg = mod.build_cfg(mod.parse_args([str(cfg_path), '--strict']))
    assert cfg.train_dataloader.dataset.dataset.strict is True
    assert 'strict' not in cfg.train_dataloader.dataset
    first, other = cfg.val_dataloader.dataset.datasets
    assert first.strict is True and 'strict' not in other
    plain = mod.build_cfg(mod.parse_args([str(cfg_path)]))
    assert 'strict' not in plain.train_dataloader.dataset.dataset

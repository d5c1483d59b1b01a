"""`mim train` / `mim test` run from a regular (wheel) install.

Builds the wheel from a copy of the source tree, installs it into a
throw-away target folder that is put first on PYTHONPATH, and runs mim on
the demo config found by its bare name inside the installed package
(`cbnet_mmdet/.mim/configs`), on the tiny generated dataset.
"""
import json
import os
import os.path as osp
import shutil
import subprocess
import sys
import zipfile

import pytest

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__))))
DEMO = 'cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py'
BIN = osp.dirname(sys.executable)


def _copy_sources(dst):
    skip = {'.venv', '.git', 'data', 'work_dirs', 'build', 'dist',
            '.pytest_cache', '__pycache__'}
    shutil.copytree(
        ROOT, dst, symlinks=True,
        ignore=lambda d, names: [n for n in names if n in skip or
                                 n.endswith('.egg-info')])


def _build_wheel(tmp, version=None):
    """Wheel of a copy of the sources (``version`` replaces the
    package's)."""
    src = tmp / 'src'
    _copy_sources(src)
    if version is not None:
        (src / 'cbnet_mmdet' / 'version.py').write_text(
            f"__version__ = '{version}'\n")
    subprocess.run([
        sys.executable, '-m', 'pip', 'wheel', '--no-deps',
        '--no-build-isolation', '-q', '-w',
        str(tmp / 'dist'),
        str(src)
    ], check=True)
    (whl, ) = (tmp / 'dist').glob('cbnet_mmdet-*.whl')
    return whl


@pytest.fixture(scope='module')
def wheel(tmp_path_factory):
    return _build_wheel(tmp_path_factory.mktemp('wheel'))


def _install(wheel, site):
    subprocess.run([
        sys.executable, '-m', 'pip', 'install', '--no-deps', '-q',
        '--target',
        str(site),
        str(wheel)
    ], check=True)
    env = dict(os.environ, PYTHONPATH=str(site))
    env.pop('LOCAL_RANK', None)
    return env


def test_wheel_carries_mim_configs_and_tools(wheel):
    names = set(zipfile.ZipFile(wheel).namelist())
    for path in ('cbnet_mmdet/.mim/tools/train.py',
                 'cbnet_mmdet/.mim/tools/test.py',
                 'cbnet_mmdet/.mim/tools/dist_train.sh',
                 'cbnet_mmdet/.mim/configs/cbnet_cityscapes.py',
                 f'cbnet_mmdet/.mim/configs/demo/{DEMO}',
                 'cbnet_mmdet/.mim/configs/_base_/models/'
                 'cbnet_mit-b5_nasfpn_crpn_cascade.py',
                 'cbnet_mmdet/.mim/model-index.yml',
                 'cbnet_mmdet/.mim/configs/cbnet/metafile.yml',
                 'cbnet_mmdet/.mim/configs/baselines/metafile.yml',
                 'cbnet_mmdet/.mim/configs/demo/metafile.yml',
                 # the lab the .mim tools import (compare_recipes.py ...)
                 'cbnet_lab/recipe_comparison.py',
                 'cbnet_lab/benchmark.py',
                 # the peer baseline: its package at the top level, its
                 # configs (listed in the model index) and command lines
                 # where the repository has them, under .mim
                 'cbnet_dehaze/__init__.py',
                 'cbnet_dehaze/models/dehazers/attention_dehazer.py',
                 'cbnet_mmdet/.mim/projects/peer_dehaze/configs/'
                 'metafile.yml',
                 'cbnet_mmdet/.mim/projects/peer_dehaze/configs/_base_/'
                 'attention_dehazer.py',
                 'cbnet_mmdet/.mim/projects/peer_dehaze/configs/realfog/'
                 'yolox_tiny_dcp_1xb4-demo_voc-fog.py',
                 'cbnet_mmdet/.mim/projects/peer_dehaze/tools/'
                 'train_dehazer.py',
                 # the tools' library (train.py's CPU launch, the
                 # converter, the renderer)
                 'cbnet_tools/cpu_distributed.py',
                 'cbnet_tools/cityscapes_to_coco.py',
                 'cbnet_tools/synthetic/scene.py',
                 # the serving project: package at the top level, command
                 # lines under .mim
                 'cbnet_serving/server.py',
                 'cbnet_mmdet/.mim/projects/edge_serving/tools/serve.py',
                 'cbnet_mmdet/.mim/projects/edge_serving/tools/'
                 'edge_router.py'):
        assert path in names, path
    # what registers nothing is not in the plugin's package
    assert not any(n.startswith(('cbnet_mmdet/serving/',
                                 'cbnet_mmdet/datasets/synthetic/'))
                   for n in names)
    # real files, not links, and no byte code or tests; the project's
    # package only once, as cbnet_dehaze
    assert not any('__pycache__' in n or n.startswith('tests/')
                   for n in names)
    assert not any(n.startswith(('cbnet_mmdet/.mim/projects/peer_dehaze/'
                                 'cbnet_dehaze',
                                 'cbnet_mmdet/.mim/projects/edge_serving/'
                                 'cbnet_serving')) for n in names)


@pytest.mark.slow  # builds a wheel and trains 4 iterations: ~1-2 min
def test_mim_train_and_test_from_installed_wheel(
        wheel, tmp_path, cityscapes_like_root):
    site = tmp_path / 'site'
    env = _install(wheel, site)
    # run where the demo config's relative data_root resolves to the
    # tiny generated dataset, and where the source tree is not importable
    os.makedirs(tmp_path / 'data')
    os.symlink(cityscapes_like_root, tmp_path / 'data' / 'cityscapes_like')
    work = tmp_path / 'work'
    shrink = [
        'train_dataloader.batch_size=2', 'train_cfg.max_epochs=2',
        'train_cfg.val_interval=100', 'default_hooks.logger.interval=1'
    ]
    train = subprocess.run(
        [osp.join(BIN, 'mim'), 'train', 'cbnet_mmdet', DEMO, '--work-dir',
         str(work), '--cfg-options'] + shrink,
        cwd=tmp_path, env=env, capture_output=True, text=True)
    out = train.stdout + train.stderr
    assert train.returncode == 0, out[-4000:]
    # mim found the config and train.py inside the installed wheel
    pkg = osp.join(str(site), 'cbnet_mmdet', '.mim')
    assert osp.join(pkg, 'configs', 'demo', DEMO) in out
    assert osp.join(pkg, 'tools', 'train.py') in out
    assert 'Epoch(train) [2][2/2]' in out, out[-4000:]
    ckpt = work / 'epoch_2.pth'
    assert ckpt.is_file()

    test = subprocess.run(
        [osp.join(BIN, 'mim'), 'test', 'cbnet_mmdet', DEMO, '--checkpoint',
         str(ckpt), '--work-dir',
         str(tmp_path / 'test')],
        cwd=tmp_path, env=env, capture_output=True, text=True)
    out = test.stdout + test.stderr
    assert test.returncode == 0, out[-4000:]
    assert osp.join(pkg, 'tools', 'test.py') in out
    assert 'coco/segm_mAP' in out and 'cityscapes/mIoU' in out


@pytest.mark.slow  # builds the wheel (shared with the test above)
def test_mim_search_lists_the_model_index(wheel, tmp_path):
    """`mim search cbnet_mmdet` reads the index from the installed wheel."""
    env = _install(wheel, tmp_path / 'site')
    mim = osp.join(BIN, 'mim')
    out = subprocess.run([mim, 'search', 'cbnet_mmdet', '--valid-config'],
                         cwd=tmp_path, env=env, capture_output=True,
                         text=True)
    assert out.returncode == 0, out.stderr[-3000:]
    for name in ('cbnet_cityscapes',
                 'cbnet_mit-b0_nasfpn-crpn_8xb1-12e_cityscapes',
                 'cbnet_mit-b5_nasfpn-crpn_8xb1-12e_cityscapes',
                 'cbnet-dd_mit-b5_nasfpn-crpn_8xb1-12e_foggy-cityscapes',
                 'cbnet_mit-b5_ablation-ce_foggy-cityscapes',
                 'cbnet_mit-b5_ablation-shape-edge-kd_foggy-cityscapes',
                 'yolox_s_8xb8-300e_cityscapes',
                 'cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like',
                 # the peer baseline's (projects/peer_dehaze)
                 'yolox_tiny_dehazer_1xb4-demo_cityscapes-like',
                 'yolox_tiny_dcp_1xb4-demo_voc-fog'):
        assert f"'{name}'" in out.stdout, name
    out = subprocess.run(
        [mim, 'search', 'cbnet_mmdet', '--config', 'cbnet_cityscapes'],
        cwd=tmp_path, env=env, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr[-3000:]
    text = ' '.join(out.stdout.split())
    assert 'cityscapes (paper, table 1)/ap 41.4' in text, out.stdout


@pytest.mark.slow  # builds a second wheel: ~30 s
def test_wheel_installs_into_an_existing_mmdet_environment(tmp_path):
    """pip, offline, into this environment (torch, mmcv, mmdet present):
    every requirement is met by what is installed and only cbnet_mmdet
    would be installed (torch, mmcv, mmdet untouched). The wheel gets a
    local version so that pip does not take the project's own installed
    copy as already satisfying it."""
    whl = _build_wheel(tmp_path, version='0.1.0+existingenv')
    report = subprocess.run([
        sys.executable, '-m', 'pip', 'install', '--dry-run', '--no-index',
        '--report', '-', '-q',
        str(whl)
    ], capture_output=True, text=True)
    assert report.returncode == 0, report.stderr[-3000:]
    installs = json.loads(report.stdout)['install']
    assert [(i['metadata']['name'], i['metadata']['version'])
            for i in installs] == [('cbnet_mmdet', '0.1.0+existingenv')]

"""The layers of the tree: the plugin (registered components) never
imports the lab, so a user's ``custom_imports=['cbnet_mmdet']`` loads no
harness, benchmark or report code; and the model, dataset and metric
packages do not reach up into the engine (hooks, runner).

The peer baseline (``projects/peer_dehaze``, package ``cbnet_dehaze``)
sits on top of the plugin: the plugin never imports it, so importing
``cbnet_mmdet`` registers no dehaze component; the project imports no lab
module either."""
import glob
import json
import os
import os.path as osp
import re
import subprocess
import sys

import pytest

ROOT = osp.dirname(osp.dirname(osp.abspath(__file__)))
PROJECT = osp.join('projects', 'peer_dehaze', 'cbnet_dehaze')
#: What the project registers, by registry: the names of the components
#: it took out of the plugin, unchanged (old configs and checkpoints).
PROJECT_COMPONENTS = {
    'MODELS': [
        'CBNetAttentionDehazer', 'CBNetDarkChannelPrior',
        'CBNetDehazeDataPreprocessor', 'CBNetDehazeModel',
        'CBNetPatchDiscriminator', 'CBNetPatchNCELoss', 'CBNetSSIMLoss'
    ],
    'METRICS': ['CBNetDehazeMetric'],
}


def importers(folder, pattern):
    """Files under ``folder`` with an import line matching ``pattern``."""
    found = []
    for path in glob.glob(osp.join(ROOT, folder, '**', '*.py'),
                          recursive=True):
        with open(path) as f:
            if re.search(r'^\s*(from|import)\s+' + pattern, f.read(),
                         re.M):
                found.append(osp.relpath(path, ROOT))
    return found


def test_no_plugin_module_imports_the_lab():
    assert not importers('cbnet_mmdet', r'cbnet_lab\b')


def test_neither_plugin_nor_lab_imports_the_project():
    assert not importers('cbnet_mmdet', r'cbnet_dehaze\b')
    assert not importers('cbnet_lab', r'cbnet_dehaze\b')


def test_project_does_not_import_the_lab():
    assert importers(PROJECT, r'cbnet_mmdet\b')  # the scan sees imports
    assert not importers(PROJECT, r'cbnet_lab\b')


@pytest.mark.parametrize(
    'folder', ['models', 'datasets', 'evaluation', 'utils'])
def test_components_do_not_import_the_engine(folder):
    assert not importers(osp.join('cbnet_mmdet', folder),
                         r'(cbnet_mmdet\.engine|\.+engine)\b')


@pytest.mark.parametrize('folder', ['models', 'evaluation'])
def test_project_components_do_not_import_the_engine(folder):
    assert not importers(osp.join(PROJECT, folder),
                         r'(cbnet_mmdet\.engine|\.+engine)\b')


def test_importing_and_registering_the_plugin_loads_no_lab_module():
    code = ('import sys; import cbnet_mmdet; '
            'from mmdet.utils import register_all_modules; '
            'register_all_modules(); '
            'print(sorted(m for m in sys.modules '
            "if m.split('.')[0] == 'cbnet_lab'))")
    out = subprocess.run([sys.executable, '-c', code], capture_output=True,
                         text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip().splitlines()[-1] == '[]'


#: Run in a fresh interpreter: what the plugin registers and loads, then
#: what importing the project adds.
REGISTERED = """
import json, sys
import cbnet_mmdet
from mmdet import registry
from mmdet.utils import register_all_modules
register_all_modules()
names = lambda: {r: set(getattr(registry, r).module_dict) for r in %r}
before = names()
loaded = [m for m in sys.modules if m.split('.')[0] == 'cbnet_dehaze']
import cbnet_dehaze
new = {r: sorted(names()[r] - before[r]) for r in before}
print(json.dumps(dict(loaded=loaded, new=new)))
"""


def test_importing_the_plugin_registers_no_dehaze_component():
    """``cbnet_mmdet`` (with MMDet's own modules) registers none of the
    project's names and loads no ``cbnet_dehaze`` module; importing
    ``cbnet_dehaze`` then registers exactly them."""
    env = dict(os.environ,
               PYTHONPATH=osp.join(ROOT, 'projects', 'peer_dehaze'))
    out = subprocess.run(
        [sys.executable, '-c', REGISTERED % sorted(PROJECT_COMPONENTS)],
        capture_output=True, text=True, timeout=300, cwd=ROOT, env=env)
    assert out.returncode == 0, out.stderr[-2000:]
    found = json.loads(out.stdout.strip().splitlines()[-1])
    assert found['loaded'] == []
    assert found['new'] == PROJECT_COMPONENTS

"""The layers of the tree: the plugin (registered components) never
imports the lab, so a user's ``custom_imports=['cbnet_mmdet']`` loads no
harness, benchmark or report code; and the model, dataset and metric
packages do not reach up into the engine (hooks, runner)."""
import glob
import os.path as osp
import re
import subprocess
import sys

import pytest

ROOT = osp.dirname(osp.dirname(osp.abspath(__file__)))


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


@pytest.mark.parametrize(
    'folder', ['models', 'datasets', 'evaluation', 'utils'])
def test_components_do_not_import_the_engine(folder):
    assert not importers(osp.join('cbnet_mmdet', folder),
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

"""The plugin (registered components) never imports the lab: a user's
``custom_imports=['cbnet_mmdet']`` loads no harness, benchmark or report
code."""
import glob
import os.path as osp
import re
import subprocess
import sys

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__))))


def test_no_plugin_module_imports_the_lab():
    offenders = []
    for path in glob.glob(osp.join(ROOT, 'cbnet_mmdet', '**', '*.py'),
                          recursive=True):
        with open(path) as f:
            if re.search(r'^\s*(from|import)\s+cbnet_lab\b', f.read(), re.M):
                offenders.append(osp.relpath(path, ROOT))
    assert not offenders


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

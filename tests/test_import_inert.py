"""Importing ``cbnet_mmdet`` registers its components and does nothing
else.

In a fresh interpreter, everything the plugin's import pulls in from other
packages is imported first (the list is read from a second fresh
interpreter that imported the plugin), then MMEngine's checkpoint schemes,
torch's safe globals, every registry (MMEngine's roots and their children,
MMDetection's), the functions and classes of torch / MMEngine / MMCV /
MMDetection / NumPy (and the attributes of those classes) and the
environment are snapshot before and after ``import cbnet_mmdet``. Allowed:
new names starting with ``CBNet`` in MMDetection's registries, and one new
MMEngine file backend, ``cbnet_image`` (the checked image reader). No
compatibility shim is needed (``CBNetRunner`` enters MMEngine's allow-list
around its own loading only), so none is allowed.
"""
import json
import os
import os.path as osp
import subprocess
import sys

import pytest

ROOT = osp.dirname(osp.dirname(osp.abspath(__file__)))

#: Prints the non-plugin modules a plugin import loads, in import order.
MODULES = r'''
import json, sys
import cbnet_mmdet
print(json.dumps([m for m in sys.modules
                  if m.split('.')[0] not in ('cbnet_mmdet', '__main__')]))
'''

#: Imports ``sys.argv[1]``'s modules, then snapshots around the plugin.
SNAPSHOT = r'''
import importlib, inspect, json, os, sys
for name in json.loads(open(sys.argv[1]).read()):
    try:
        importlib.import_module(name)
    except Exception:  # private or platform modules: not needed
        pass
import torch
import mmengine.registry.root as roots
from mmengine.registry import Registry
from mmengine.fileio.backends import registry_utils as file_backends
from mmengine.runner import CheckpointLoader

PATCHABLE = ('torch', 'mmengine', 'mmcv', 'mmdet', 'numpy')


def name_of(obj):
    return f'{getattr(obj, "__module__", "?")}.' \
        f'{getattr(obj, "__qualname__", type(obj).__name__)}'


def registries():
    found = {}

    def walk(registry):
        key = f'{registry.scope}::{registry.name}'
        if key in found:
            return
        found[key] = {k: name_of(v) for k, v in registry.module_dict.items()}
        for child in registry.children.values():
            walk(child)

    for value in vars(roots).values():
        if isinstance(value, Registry):
            walk(value)
    return found


def callables():
    """(module, attribute) -> the function or class itself, and
    (module, class, attribute) -> what the class defines."""
    found = {}
    for mod_name, module in list(sys.modules.items()):
        if module is None or mod_name.split('.')[0] not in PATCHABLE:
            continue
        for attr, value in list(vars(module).items()):
            if inspect.isclass(value) or callable(value):
                found[(mod_name, attr)] = value
            if inspect.isclass(value) and value.__module__ == mod_name:
                for cattr, cvalue in list(vars(value).items()):
                    if callable(cvalue) or isinstance(
                            cvalue, (staticmethod, classmethod, property)):
                        found[(mod_name, attr, cattr)] = cvalue
    return found


def snapshot():
    return dict(
        schemes={k: name_of(v) for k, v in CheckpointLoader._schemes.items()},
        file_backends={k: name_of(v)
                       for k, v in file_backends.backends.items()},
        file_prefixes={k: name_of(v)
                       for k, v in file_backends.prefix_to_backends.items()},
        safe_globals=sorted(
            str(g) for g in torch.serialization.get_safe_globals()),
        registries=registries(),
        environ=dict(os.environ),
        callables=callables())


before = snapshot()
import cbnet_mmdet  # noqa: E402
after = snapshot()
added, changed = [], []
for key, names in after['registries'].items():
    old = before['registries'].get(key, {})
    added += [f'{key}:{n}' for n in names if n not in old]
    changed += [f'{key}:{n}: {old[n]} -> {v}' for n, v in names.items()
                if n in old and old[n] != v]
    changed += [f'{key}:{n} removed' for n in old if n not in names]
patched = [
    '.'.join(key) for key, value in before['callables'].items()
    if key in after['callables'] and after['callables'][key] is not value
]
print(json.dumps(dict(
    added=sorted(added), changed=sorted(changed), patched=sorted(patched),
    schemes=[before['schemes'], after['schemes']],
    file_backends=[before['file_backends'], after['file_backends']],
    file_prefixes=[before['file_prefixes'], after['file_prefixes']],
    safe_globals=[before['safe_globals'], after['safe_globals']],
    environ=sorted(set(before['environ'].items()) ^
                   set(after['environ'].items())))))
'''


def python(code, *args):
    env = dict(os.environ, OMP_NUM_THREADS='1', PYTHONWARNINGS='ignore')
    proc = subprocess.run([sys.executable, '-c', code, *args], cwd=ROOT,
                          env=env, capture_output=True, text=True,
                          timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


@pytest.fixture(scope='module')
def diff(tmp_path_factory):
    modules = tmp_path_factory.mktemp('import') / 'modules.json'
    modules.write_text(json.dumps(python(MODULES)))
    return python(SNAPSHOT, str(modules))


def test_registers_only_cbnet_names_in_mmdet_registries(diff):
    assert diff['added'], 'nothing registered: the snapshot is broken'
    outside = [a for a in diff['added']
               if not a.startswith('mmdet::')
               or not a.split(':')[-1].startswith('CBNet')]
    assert outside == []
    assert 'mmdet::model:CBNetBoundaryAwareLoss' in diff['added']
    assert 'mmdet::runner:CBNetRunner' in diff['added']
    assert diff['changed'] == []


def test_mmengine_checkpoint_loader_untouched(diff):
    before, after = diff['schemes']
    assert after == before
    assert before[''] == 'mmengine.runner.checkpoint.load_from_local'


def test_file_backends_only_gain_the_checked_image_backend(diff):
    # MMEngine's file backends are a registry too: the plugin adds its
    # checked image reader under its own name (configs opt in with
    # backend_args=dict(backend='cbnet_image')) and replaces none
    before, after = diff['file_backends']
    assert {k: v for k, v in after.items() if k in before} == before
    assert {k: v for k, v in after.items() if k not in before} == {
        'cbnet_image': 'cbnet_mmdet.datasets.transforms.image_file_backend.'
        'CBNetImageFileBackend'}
    assert diff['file_prefixes'][1] == diff['file_prefixes'][0]


def test_torch_safe_globals_untouched(diff):
    # no shim: MMEngine's allow-list is entered around CBNetRunner's
    # loading only (cbnet_mmdet/utils/checkpoint/safe_globals.py)
    before, after = diff['safe_globals']
    assert after == before


def test_nothing_patched_and_environment_kept(diff):
    assert diff['patched'] == []
    assert diff['environ'] == []

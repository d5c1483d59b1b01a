"""The layers of the tree (docs/architecture.md, "Who may import whom").

* The plugin ``cbnet_mmdet`` holds registered components and the helpers
  they import: every module of it registers something or is imported (at
  any depth) by a module that does, or by the package's own
  ``__init__.py``. What registers nothing lives elsewhere: the command
  lines' library ``cbnet_tools`` (renderer, converter, statistics, tables,
  timing), the lab ``cbnet_lab`` (measurements), the projects' packages
  ``cbnet_dehaze`` (the peer baseline) and ``cbnet_serving`` (the serving
  stack).
* The plugin imports none of them, so a user's
  ``custom_imports=['cbnet_mmdet']`` loads no renderer, harness, dehazer
  or serving code; ``cbnet_tools`` imports only the plugin; the lab and
  the peer baseline import the plugin and ``cbnet_tools`` (not each
  other); the serving project imports the plugin and ``cbnet_tools``
  (the dark channel estimates of its haze score are the plugin's
  ``utils/dark_channel.py``), and nothing imports it.
* The rules read every Python file of the packages, of each project's
  whole folder (its package, ``tools/`` and ``configs/``, whose
  ``custom_imports`` count as imports: a project's command lines and
  configs follow its package's rules) and of the repository's ``tools/``
  (the plugin, the lab and ``cbnet_tools``; the projects' command lines
  are in their own ``tools/``).
* The model, dataset, metric and utility packages of the plugin do not
  reach up into its engine (hooks, runner).
"""
import ast
import glob
import json
import os
import os.path as osp
import re
import subprocess
import sys

import pytest

ROOT = osp.dirname(osp.dirname(osp.abspath(__file__)))
#: Where each package's sources are in the repository.
PACKAGES = {
    'cbnet_mmdet': 'cbnet_mmdet',
    'cbnet_tools': 'cbnet_tools',
    'cbnet_lab': 'cbnet_lab',
    'cbnet_dehaze': osp.join('projects', 'peer_dehaze', 'cbnet_dehaze'),
    'cbnet_serving': osp.join('projects', 'edge_serving', 'cbnet_serving'),
}
#: The packages each layer must not import.
FORBIDDEN = {
    'cbnet_mmdet':
    ['cbnet_tools', 'cbnet_lab', 'cbnet_dehaze', 'cbnet_serving'],
    'cbnet_tools': ['cbnet_lab', 'cbnet_dehaze', 'cbnet_serving'],
    'cbnet_lab': ['cbnet_dehaze', 'cbnet_serving'],
    'cbnet_dehaze': ['cbnet_lab', 'cbnet_serving'],
    'cbnet_serving': ['cbnet_lab', 'cbnet_dehaze'],
    'tools': ['cbnet_dehaze', 'cbnet_serving'],
}
#: Every folder whose Python files the rules read, with the layer whose
#: rules it follows: a project's whole folder (package, tools/, configs/)
#: its package's, the repository's command lines their own.
LAYERS = {
    'cbnet_mmdet': 'cbnet_mmdet',
    'cbnet_tools': 'cbnet_tools',
    'cbnet_lab': 'cbnet_lab',
    osp.join('projects', 'peer_dehaze'): 'cbnet_dehaze',
    osp.join('projects', 'edge_serving'): 'cbnet_serving',
    'tools': 'tools',
}
PROJECT = PACKAGES['cbnet_dehaze']
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


def importers(folder, pattern, root=ROOT):
    """Files under ``folder`` with an import line matching ``pattern``, or
    a config naming a module that matches it in ``custom_imports``."""
    found = []
    for path in glob.glob(osp.join(root, folder, '**', '*.py'),
                          recursive=True):
        with open(path) as f:
            text = f.read()
        if re.search(r'^\s*(from|import)\s+' + pattern, text, re.M) or \
                re.search(r'custom_imports\s*=\s*dict\(\s*imports\s*=\s*'
                          r'\[[^\]]*[\'"]' + pattern, text):
            found.append(osp.relpath(path, root))
    return found


@pytest.mark.parametrize('folder', sorted(LAYERS))
def test_folders_import_only_the_layers_below(folder):
    layer = LAYERS[folder]
    bad = {other: importers(folder, rf'{other}\b')
           for other in FORBIDDEN[layer]}
    assert not any(bad.values()), f'{folder} ({layer}) imports {bad}'


def test_the_rules_read_every_project_folder_and_the_tools():
    projects = glob.glob(osp.join(ROOT, 'projects', '*', ''))
    assert {osp.relpath(p, ROOT) for p in projects} <= set(LAYERS)
    assert set(FORBIDDEN) == set(LAYERS.values())
    for package, folder in PACKAGES.items():
        assert any(osp.commonpath([folder, f]) == f and LAYERS[f] == package
                   for f in LAYERS), package


def test_the_import_scan_sees_imports():
    for package in ('cbnet_tools', 'cbnet_lab', 'cbnet_dehaze',
                    'cbnet_serving'):
        assert importers(PACKAGES[package], r'cbnet_mmdet\b'), package
    assert importers(PACKAGES['cbnet_serving'],
                     r'cbnet_mmdet\.utils\.dark_channel\b')
    assert importers(PACKAGES['cbnet_lab'], r'cbnet_tools\b')
    # a project's command lines, its configs' custom_imports, tools/
    tools = osp.join('projects', 'peer_dehaze', 'tools')
    assert osp.join(tools, 'train_dehazer.py') in importers(
        tools, r'cbnet_dehaze\b')
    assert importers(osp.join('projects', 'peer_dehaze', 'configs'),
                     r'cbnet_dehaze\b')
    assert importers('tools', r'cbnet_lab\b')


@pytest.mark.parametrize(
    'folder', ['models', 'datasets', 'evaluation', 'utils'])
def test_components_do_not_import_the_engine(folder):
    assert not importers(osp.join('cbnet_mmdet', folder),
                         r'(cbnet_mmdet\.engine|\.+engine)\b')


@pytest.mark.parametrize('folder', ['models', 'evaluation'])
def test_project_components_do_not_import_the_engine(folder):
    assert not importers(osp.join(PROJECT, folder),
                         r'(cbnet_mmdet\.engine|\.+engine)\b')


# -- every module of the plugin registers or helps one that does --------

#: Calls that put something in a registry (MMEngine's registries, its file
#: backends, its checkpoint loader schemes).
REGISTERING_CALLS = {'register_module', 'register_backend',
                     'register_scheme'}


def _modules(folder, package):
    """{dotted name: file} of every module under ``folder`` (the folder of
    ``package``); a package is its ``__init__.py``."""
    out = {}
    for path in glob.glob(osp.join(folder, '**', '*.py'), recursive=True):
        parts = osp.relpath(path, folder)[:-3].split(os.sep)
        if parts[-1] == '__init__':
            parts = parts[:-1]
        out['.'.join([package] + parts)] = path
    return out


def _parse(path):
    with open(path) as f:
        return ast.parse(f.read(), path)


def _registers(tree):
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            func = node.func
            name = func.attr if isinstance(func, ast.Attribute) else \
                getattr(func, 'id', None)
            if name in REGISTERING_CALLS:
                return True
    return False


def _absolute(module, is_package, node):
    """The absolute module name of an ``ImportFrom`` node in ``module``
    (``is_package``: ``module`` is a package's ``__init__.py``)."""
    if not node.level:
        return node.module
    parts = module.split('.')
    if not is_package:
        parts = parts[:-1]
    parts = parts[:len(parts) - node.level + 1]
    return '.'.join(parts + ([node.module] if node.module else []))


class ImportGraph:
    """Which modules of a package a module imports, with names imported
    from a package resolved to the submodule its ``__init__.py`` takes
    them from (importing ``use_channels_last`` from ``models.utils`` is an
    import of ``models/utils/memory_format.py``, not of the whole
    ``models/utils``)."""

    def __init__(self, folder, package):
        self.files = _modules(folder, package)
        self.trees = {m: _parse(p) for m, p in self.files.items()}
        self.packages = {m for m, p in self.files.items()
                         if p.endswith('__init__.py')}

    def _source(self, module, node):
        return _absolute(module, module in self.packages, node)

    def resolve(self, target, name, depth=0):
        """Modules that provide ``name`` imported from ``target``."""
        if f'{target}.{name}' in self.files:
            return {f'{target}.{name}'}
        if target not in self.packages or depth > 10:
            return {target} if target in self.files else set()
        found = set()
        for node in self.trees[target].body:
            if isinstance(node, ast.ImportFrom):
                source = self._source(target, node)
                for alias in node.names:
                    if alias.name == '*' or \
                            (alias.asname or alias.name) == name:
                        found |= self.resolve(source, name if
                                              alias.name == '*' else
                                              alias.name, depth + 1)
        return found or {target}

    def imports(self, module):
        """The modules ``module`` imports (package ``__init__``s only
        where a whole package is imported)."""
        out = set()
        for node in ast.walk(self.trees[module]):
            if isinstance(node, ast.Import):
                out |= {a.name for a in node.names if a.name in self.files}
            elif isinstance(node, ast.ImportFrom):
                source = self._source(module, node)
                for alias in node.names:
                    out |= self.resolve(source, alias.name)
        return out & set(self.files)

    def whole_package(self, module):
        """Everything a package's ``__init__`` imports."""
        return self.imports(module) if module in self.packages else set()


def modules_that_help_no_registration(folder, package):
    """Files of ``package`` (its sources in ``folder``) that register
    nothing and that no registering module imports, directly or through
    other helpers; the package's own ``__init__.py`` counts as an importer
    of the modules (not the subpackages) it imports. Package
    ``__init__.py`` files re-export and are not checked."""
    graph = ImportGraph(folder, package)
    seen = {m for m, tree in graph.trees.items() if _registers(tree)}
    seen |= {m for m in graph.imports(package) if m not in graph.packages}
    todo = list(seen)
    while todo:
        module = todo.pop()
        for dep in graph.imports(module) - seen:
            if dep in graph.packages:  # `import pkg` / `from . import pkg`
                new = graph.whole_package(dep) - seen
            else:
                new = {dep}
            seen |= new | {dep}
            todo += list(new)
    return sorted(
        osp.relpath(graph.files[m], osp.dirname(folder))
        for m in set(graph.files) - seen - graph.packages)


def test_every_plugin_module_registers_or_helps_one_that_does():
    assert modules_that_help_no_registration(
        osp.join(ROOT, 'cbnet_mmdet'), 'cbnet_mmdet') == []


def test_the_registration_scan_finds_a_module_nobody_registering_uses(
        tmp_path):
    """A converter kept in a plugin's datasets/ is found; a helper of a
    registered class, at any depth, and what ``__init__`` imports, are
    not; a re-export in a subpackage's ``__init__.py`` does not count."""
    pkg = tmp_path / 'plug'
    files = {
        '__init__.py': 'from .version import v\nfrom . import datasets\n',
        'version.py': 'v = 1\n',
        'datasets/__init__.py': ('from .ds import DS\n'
                                 'from .convert import convert\n'
                                 'from .helpers import *\n'),
        'datasets/ds.py': ('from mmdet.registry import DATASETS\n'
                           'from .helpers import check\n'
                           '@DATASETS.register_module()\nclass DS: pass\n'),
        'datasets/helpers.py': 'from .paths import p\ndef check(): pass\n',
        'datasets/paths.py': 'p = 1\n',
        'datasets/convert.py': 'from .paths import p\ndef convert(): p\n',
        'utils/__init__.py': 'from .table import table\n',
        'utils/table.py': 'def table(): pass\n',
    }
    for name, text in files.items():
        (pkg / name).parent.mkdir(parents=True, exist_ok=True)
        (pkg / name).write_text(text)
    assert modules_that_help_no_registration(str(pkg), 'plug') == [
        'plug/datasets/convert.py', 'plug/utils/table.py'
    ]


# -- what importing the plugin loads and registers ----------------------

def test_importing_and_registering_the_plugin_loads_no_other_package():
    """Neither the lab, the tools' library nor the projects' packages are
    loaded by ``import cbnet_mmdet`` and MMDet's own registration."""
    others = sorted(set(PACKAGES) - {'cbnet_mmdet'})
    code = ('import sys; import cbnet_mmdet; '
            'from mmdet.utils import register_all_modules; '
            'register_all_modules(); '
            'print(sorted(m for m in sys.modules '
            f"if m.split('.')[0] in {others!r}))")
    out = subprocess.run([sys.executable, '-c', code], capture_output=True,
                         text=True, timeout=300, cwd=ROOT)
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

"""Tests share helpers through modules that are not test files, as
MMDetection's tests share ``mmdet.testing``: ``tests/test_tools/
tool_helpers.py``, a folder's own helper module (``set_helpers.py``,
``serving_helpers.py``, ``doc_helpers.py`` ...) and, for pytest fixtures,
``conftest.py``. No Python file under ``tests/`` imports a test module
(``test_*.py``): one that did tied the two files together (moving or
splitting one broke the other), ran the other file's module-level code
where it was not under test, and took fixtures into a second module by
name (each import needing its own ``noqa``).
"""
import ast
import glob
import os.path as osp

TESTS = osp.dirname(osp.abspath(__file__))


def imports_of_test_modules(folder):
    """``(file, module)`` of every import of a test module (a ``test_*.py``
    file under ``folder``) by a Python file under ``folder``, at any depth
    of the file (imports inside functions too)."""
    files = glob.glob(osp.join(folder, '**', '*.py'), recursive=True)
    tests = {osp.basename(f)[:-3] for f in files
             if osp.basename(f).startswith('test_')}
    found = []
    for path in files:
        with open(path, encoding='utf-8') as f:
            tree = ast.parse(f.read(), path)
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and not node.level:
                names = [node.module]
            else:
                continue
            found += [(osp.relpath(path, folder), name) for name in names
                      if name.split('.')[0] in tests]
    return sorted(found)


def test_no_file_under_tests_imports_a_test_module():
    assert imports_of_test_modules(TESTS) == []


def test_the_scan_finds_imports_of_test_modules(tmp_path):
    files = {
        'test_a.py': 'import os\nfrom a_helpers import x\n',
        'sub/test_b.py': 'from test_a import y\n',
        'sub/test_c.py': 'def f():\n    import test_b\n',
        'sub/conftest.py': 'import test_c as c\n',
        'a_helpers.py': 'x = 1\n',
    }
    for name, text in files.items():
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text(text)
    assert imports_of_test_modules(str(tmp_path)) == [
        ('sub/conftest.py', 'test_c'), ('sub/test_b.py', 'test_a'),
        ('sub/test_c.py', 'test_b')
    ]

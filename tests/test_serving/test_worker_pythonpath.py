"""The PYTHONPATH the server gives Ray's workers (server.worker_pythonpath).

An installed cbnet_mmdet lives in site-packages; putting that folder on
PYTHONPATH puts it ahead of the standard library in every worker, where
cityscapesScripts' `typing` 3.7 backport shadows Python's `typing` and
`import ray` fails (measured 2026-11-25: every replica died at start)."""
import os
import os.path as osp
import site

import pytest

pytest.importorskip('ray')
from cbnet_mmdet.serving import server  # noqa: E402


def _fake_package_in(monkeypatch, folder):
    monkeypatch.setattr(
        server, '__file__',
        osp.join(folder, 'cbnet_mmdet', 'serving', 'server.py'))


def test_source_tree_folder_goes_first(monkeypatch, tmp_path):
    _fake_package_in(monkeypatch, str(tmp_path))
    monkeypatch.setenv('PYTHONPATH', '/elsewhere')
    assert server.worker_pythonpath() == os.pathsep.join(
        [str(tmp_path), '/elsewhere'])


def test_site_packages_is_never_added(monkeypatch):
    _fake_package_in(monkeypatch, site.getsitepackages()[0])
    monkeypatch.delenv('PYTHONPATH', raising=False)
    assert server.worker_pythonpath() == ''
    monkeypatch.setenv('PYTHONPATH', '/elsewhere')
    assert server.worker_pythonpath() == '/elsewhere'

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
from cbnet_serving import server  # noqa: E402

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.dirname(
    osp.abspath(__file__)))))


def _fake_package_in(monkeypatch, folder):
    monkeypatch.setattr(
        server, '__file__', osp.join(folder, 'cbnet_serving', 'server.py'))
    monkeypatch.setattr(server, 'WORKER_PACKAGES', ())


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


def test_source_trees_of_plugin_and_projects_are_added(monkeypatch):
    """From the source tree (as pytest runs), workers get the serving
    project's folder, the repository root (cbnet_mmdet) and the peer
    baseline's folder (cbnet_dehaze), once each, then the caller's."""
    if osp.dirname(osp.dirname(server.__file__)) != osp.join(
            ROOT, 'projects', 'edge_serving'):
        pytest.skip('cbnet_serving is imported from an installed package')
    monkeypatch.setenv('PYTHONPATH', '/elsewhere')
    folders = server.worker_pythonpath().split(os.pathsep)
    assert folders == [
        osp.join(ROOT, 'projects', 'edge_serving'), ROOT,
        osp.join(ROOT, 'projects', 'peer_dehaze'), '/elsewhere'
    ]

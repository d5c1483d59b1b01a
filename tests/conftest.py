"""Shared fixtures.

``cityscapes_like_root``: a tiny generated Cityscapes / Foggy Cityscapes
tree (4 train + 3 val images at 128x256, seed 0; image 2 of each split has
no instances, images 0 of each split have a crowd region), converted to COCO
JSON under ``{root}/annotations/instancesonly_filtered_gtFine_{split}.json``.
Generated once per test session (about 2 s) into its own temporary folder
(not pytest's ``tmp_path_factory``, whose old numbered folders a concurrent
pytest run may delete), removed at the end of the session.

``log_messages``: ``log_messages(logger=None, level=logging.DEBUG)``
starts recording what an MMLogger (default: the current one) logs at
``level`` and above, and returns the list of messages (detached at the
end of the test).

``restore_environ``: puts ``os.environ`` back as it was after the test (for
tests that run a tool's ``main``/``parse_args``, which export
``LOCAL_RANK`` as launchers expect).

Every test module must leave ``os.environ`` as it found it
(``environment_unchanged``, autouse): a leaked variable (``LOCAL_RANK``,
``MASTER_PORT``...) changes how later tests and the tools they run behave.

Every test skipped with reason ``'needs CUDA'`` is marked ``cuda``
(``pytest_collection_modifyitems``): ``pytest -m cuda FILES`` runs the
CUDA-only tests on a GPU machine (tools/device/run_all.py).

What collection leaves alive (the imported libraries, the collected items:
370,000 objects) is moved out of the garbage collector's sight
(``gc.freeze``, ``pytest_collection_finish``): MMEngine's ``BaseDataset``
calls ``gc.collect()`` each time it serialises a data list, and each full
collection walked them all again (0.25 s). Measured on
``tests/test_lab/test_realfog.py tests/test_datasets`` (a ``gc.callbacks``
timer, one thread, load 3): 54 s of 177 s in collections before, 17 s of
135 s after.

``tools/run_tests.sh`` runs the suite in several worker processes
(pytest-xdist), each collecting every file at once. openmim's import makes
its cache folder ``~/.cache/mim`` if it is missing, without ``exist_ok``:
on a fresh machine two workers importing it together raced, and one
failed to collect (``FileExistsError``, seen once here). This file, loaded
first by the process that starts the workers, makes the folder.

Every test module starts with MMEngine's default scope as the previous
one found it (``default_scope_restored``, autouse): a ``Runner`` built
without ``default_scope`` makes ``'mmengine'`` the current scope for the
rest of the process, and every later ``MODELS.build`` of a name
registered in MMDetection's registry then looks in MMEngine's root
registry and fails (``KeyError: 'CBNetDehazeModel is not in the
mmengine::model registry'``): which modules a pytest-xdist worker runs
after which changes from run to run, and a CI run failed so.
"""
import gc
import os
import os.path as osp
import socket
import sys
import tempfile

import cv2  # noqa: F401  (see below)
import pytest

# cv2's import exports LD_LIBRARY_PATH and QT_QPA_* once per process:
# imported here, before any module's environment snapshot, so that the
# first test to load an image is not reported as leaking them.

# before any worker imports openmim (see the module's docstring)
os.makedirs(osp.join(osp.expanduser('~'), '.cache', 'mim'), exist_ok=True)

# the one loader of tools/ scripts (tests/test_tools/tool_helpers.py:
# load_tool, DEMO, demo_checkpoint), importable from every test folder
sys.path.append(osp.join(osp.dirname(osp.abspath(__file__)), 'test_tools'))
# the toy model and test-only hooks (helper_hooks) of the reliability and
# engine tests
sys.path.append(osp.join(osp.dirname(osp.abspath(__file__)),
                         'test_reliability'))


@pytest.fixture(scope='session')
def cityscapes_like_root():
    """Root of the tiny generated dataset (4 train / 3 val images at
    128x256, seed 0: tests rely on these), annotations converted."""
    from cbnet_tools.synthetic import tiny_converted
    with tempfile.TemporaryDirectory(prefix='cbnet_cityscapes_like_') as tmp:
        root = tiny_converted(osp.join(tmp, 'cityscapes'))
        assert osp.isfile(
            osp.join(root, 'annotations',
                     'instancesonly_filtered_gtFine_val.json'))
        yield root


@pytest.fixture
def log_messages():
    """Record an MMLogger's messages (see the module docstring)."""
    import logging

    from mmengine.logging import MMLogger
    attached = []

    def attach(logger=None, level=logging.DEBUG):
        logger = logger or MMLogger.get_current_instance()
        seen = []
        handler = logging.Handler(level)
        handler.emit = lambda record: seen.append(record.getMessage())
        logger.addHandler(handler)
        attached.append((logger, handler))
        return seen

    yield attach
    for logger, handler in attached:
        logger.removeHandler(handler)


@pytest.fixture
def free_port() -> int:
    """A TCP port free on 127.0.0.1 right now (for ``MASTER_PORT``; a fixed
    port collides with concurrent test runs)."""
    with socket.socket() as sock:
        sock.bind(('127.0.0.1', 0))
        return sock.getsockname()[1]


#: Variables the test run's own machinery sets, not the tests: pytest (the
#: running test and phase) and torch (its inductor cache folder, exported
#: once per process on first use, whichever test that is).
NOT_CHECKED = ('PYTEST_CURRENT_TEST', 'TORCHINDUCTOR_CACHE_DIR')


def environ_diff(before: dict, after: dict) -> list:
    """Names added, removed or changed between two environment copies
    (:data:`NOT_CHECKED` aside)."""
    return sorted(k for k in before.keys() | after.keys()
                  if before.get(k) != after.get(k) and k not in NOT_CHECKED)


def restore_environment(saved: dict) -> dict:
    """Put ``os.environ`` back to ``saved``.

    Returns:
        dict: The changed variables and the values they had (None: unset).
    """
    changed = environ_diff(saved, dict(os.environ))
    leaked = {k: os.environ.get(k) for k in changed}
    for key in changed:
        if key in saved:
            os.environ[key] = saved[key]
        else:
            del os.environ[key]
    return leaked


@pytest.fixture
def restore_environ():
    """Restore ``os.environ`` after the test, whatever the test set."""
    saved = dict(os.environ)
    yield
    restore_environment(saved)


@pytest.fixture(scope='module', autouse=True)
def environment_unchanged(request):
    """Fail the module whose tests leave ``os.environ`` changed (then put
    it back, so that one leak does not spread to the next modules)."""
    saved = dict(os.environ)
    yield
    leaked = restore_environment(saved)
    if leaked:
        pytest.fail(f'{request.module.__name__} left os.environ changed: '
                    f'{leaked} (use monkeypatch.setenv or restore_environ)')


@pytest.fixture(scope='module', autouse=True)
def default_scope_restored():
    """Give the next module MMEngine's default scopes as this one found
    them (see the module's docstring). MMEngine keeps them in
    ``DefaultScope._instance_dict`` (the newest is the current one) and
    itself puts a copy back the same way
    (``DefaultScope.overwrite_default_scope``)."""
    from mmengine.registry import DefaultScope
    saved = DefaultScope._instance_dict.copy()
    yield
    DefaultScope._instance_dict = saved


#: The reason every CUDA-only test gives its skip (STYLE.md:
#: ``skipif(not torch.cuda.is_available(), reason='needs CUDA')``).
CUDA_SKIP_REASON = 'needs CUDA'


def pytest_collection_finish(session):
    """Freeze what collection built (see the module's docstring): later
    collections walk only what the tests themselves create."""
    gc.collect()
    gc.freeze()


def pytest_collection_modifyitems(config, items):
    """Mark ``cuda`` every test skipped with :data:`CUDA_SKIP_REASON`, so
    that ``pytest -m cuda`` runs the CUDA-only tests on a GPU machine
    (tools/device/run_all.py) without each file repeating the marker."""
    for item in items:
        if any(m.kwargs.get('reason') == CUDA_SKIP_REASON
               for m in item.iter_markers('skipif')):
            item.add_marker(pytest.mark.cuda)

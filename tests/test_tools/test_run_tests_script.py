"""tools/run_tests.sh: how many worker processes run the suite."""
import os
import shlex
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def run_tests(tmp_path, *args, **env_vars):
    env = {k: v for k, v in os.environ.items()
           if k != 'CBNET_TEST_WORKERS'}
    # should --print-command ever stop answering, the script would go on to
    # install: point it at an empty environment and a Python that fails,
    # so the test fails at once instead of installing into .venv
    env.update(CBNET_VENV=str(tmp_path / 'venv'), PYTHON='false')
    env.update(env_vars)
    return subprocess.run(['bash', str(ROOT / 'tools/run_tests.sh'), *args],
                          env=env, cwd=ROOT, capture_output=True, text=True,
                          timeout=60)


def pytest_args(tmp_path, *args, **env_vars):
    out = run_tests(tmp_path, '--print-command', *args, **env_vars)
    assert out.returncode == 0, out.stderr
    cmd = shlex.split(out.stdout)
    assert cmd[:3] == [str(tmp_path / 'venv/bin/python'), '-m', 'pytest']
    return cmd[3:]


def test_one_worker_per_core_whatever_omp_num_threads(tmp_path):
    # the script exports OMP_NUM_THREADS=1 for the tests; GNU nproc honours
    # it, which would leave one worker on a machine of several cores
    cores = len(os.sched_getaffinity(0))
    for env in (dict(OMP_NUM_THREADS='1', OMP_THREAD_LIMIT='1'), {}):
        args = pytest_args(tmp_path, **env)
        if cores > 1:
            assert args[args.index('-n') + 1] == str(cores)
            assert args[args.index('--dist') + 1] == 'loadfile'
        else:
            assert '-n' not in args


def test_workers_are_the_users_choice_and_args_pass_through(tmp_path):
    args = pytest_args(tmp_path, '-m', 'not slow', CBNET_TEST_WORKERS='3')
    assert args[args.index('-n') + 1] == '3'
    assert args[-2:] == ['-m', 'not slow']
    # one worker: the plain pytest of one process, no xdist option at all
    args = pytest_args(tmp_path, 'tests/test_tools',
                       CBNET_TEST_WORKERS='1')
    assert '-n' not in args and '--dist' not in args
    assert args[-1] == 'tests/test_tools'


@pytest.mark.parametrize('bad', ['0', 'two', '-1', '2.5'])
def test_a_bad_worker_count_is_an_error_before_installing(tmp_path, bad):
    out = run_tests(tmp_path, CBNET_TEST_WORKERS=bad)
    assert out.returncode == 2
    assert 'CBNET_TEST_WORKERS' in out.stderr and repr(bad) in out.stderr
    assert not (tmp_path / 'venv').exists()

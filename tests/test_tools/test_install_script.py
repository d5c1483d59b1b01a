"""tools/install.sh: how many jobs compile mmcv."""
import os
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def build_jobs(tmp_path, **env_vars):
    env = {k: v for k, v in os.environ.items() if k != 'MAX_JOBS'}
    # should --print-build-jobs ever stop answering, the script would go on
    # to install: point it at an empty environment and a Python that fails,
    # so the test fails at once instead of installing into .venv
    env.update(CBNET_VENV=str(tmp_path / 'venv'), PYTHON='false')
    env.update(env_vars)
    out = subprocess.run(['bash', str(ROOT / 'tools/install.sh'),
                          '--print-build-jobs'], env=env, cwd=ROOT,
                         capture_output=True, text=True, check=True)
    return int(out.stdout)


def test_mmcv_compiles_on_every_core_whatever_omp_num_threads(tmp_path):
    # tools/demo.sh exports OMP_NUM_THREADS=1 before it installs; GNU nproc
    # honours it, which once compiled mmcv on one core of two
    cores = len(os.sched_getaffinity(0))
    assert build_jobs(tmp_path, OMP_NUM_THREADS='1',
                      OMP_THREAD_LIMIT='1') == cores
    assert build_jobs(tmp_path) == cores


def test_max_jobs_is_the_users_choice(tmp_path):
    assert build_jobs(tmp_path, MAX_JOBS='3', OMP_NUM_THREADS='1') == 3

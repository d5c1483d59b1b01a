"""tools/install.sh: how many jobs compile mmcv; the setuptools pin."""
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


def setuptools_specs():
    """Every place that pins setuptools for an install, by file."""
    import re
    places = {
        'tools/install.sh': r'pipq "(setuptools[^"]+)"',
        'requirements/constraints.txt': r'^(setuptools\S+)',
        'tools/device/run_all.py': r"'(setuptools[^']+)'",
        'docs/install.md': r'pip install "(setuptools[^"]+)"',
    }
    found = {}
    for path, pattern in places.items():
        found[path] = re.findall(pattern, (ROOT / path).read_text(), re.M)
    return found


def test_setuptools_pinned_below_its_pkg_resources_warning():
    """From 80.9 every import of pkg_resources (MMEngine's config bases,
    imagecorruptions, openmim) warns; 81 removed it. One range everywhere,
    which keeps 80.8 and leaves out 80.9."""
    from packaging.requirements import Requirement
    specs = setuptools_specs()
    assert all(len(v) == 1 for v in specs.values()), specs
    ranges = {Requirement(v[0]).specifier for v in specs.values()}
    assert len(ranges) == 1, specs
    spec = ranges.pop()
    assert spec.contains('80.8.0') and spec.contains('77.0.0')
    assert not spec.contains('80.9.0') and not spec.contains('76.1.0')


def test_installed_setuptools_imports_pkg_resources_without_a_warning():
    """What tools/install.sh installed (CI runs the suite in it)."""
    import sys
    out = subprocess.run(
        [sys.executable, '-W', 'error::UserWarning', '-c',
         'import pkg_resources'],
        capture_output=True, text=True)
    assert out.returncode == 0, out.stderr[-2000:]

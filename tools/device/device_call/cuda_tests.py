"""The tests step: the CUDA-only tests of the tree."""
import glob
import os
import os.path as osp
import re
import time
import xml.etree.ElementTree as ET

from .runner import BOXES, DRY_BOXES, ROOT, Runner

#: A CUDA-only test's decorator (tests/conftest.py marks the second kind).
CUDA_TEST = re.compile(r"^@pytest\.mark\.(cuda\b|skipif\(.*"
                       r"reason='needs CUDA'\))", re.M)


def cuda_test_files():
    """Test files holding CUDA-only tests (marked ``cuda``, or skipped
    with 'needs CUDA', which tests/conftest.py marks ``cuda``)."""
    found = []
    for path in sorted(glob.glob(osp.join(ROOT, 'tests', '**', 'test_*.py'),
                                 recursive=True)):
        with open(path) as f:
            text = f.read()
        if CUDA_TEST.search(text):
            found.append(osp.relpath(path, ROOT))
    return found


def step_tests(r: Runner, env) -> dict:
    t0 = time.time()
    files = cuda_test_files()
    if not files:
        return r.step('tests', 'failed', 0, 'no CUDA test file found')
    junit = osp.join(r.work, 'tests', 'junit.xml')
    os.makedirs(osp.dirname(junit), exist_ok=True)
    res = r.run([r.args.python, '-m', 'pytest', '-q', '-m', 'cuda',
                 '-p', 'no:cacheprovider', f'--junitxml={junit}'] + files,
                min(BOXES['tests'] if not r.args.dry_run else
                    DRY_BOXES['tests'], r.left()), 'tests', env)
    counts = junit_counts(junit)
    ok = res['rc'] == 0 and counts.get('tests', 0) > 0
    return r.step('tests', 'timed out' if res['timed_out'] else
                  'ok' if ok else 'failed', time.time() - t0,
                  ', '.join(f'{k} {v}' for k, v in counts.items()),
                  files=files, counts=counts, runs=[res])


def junit_counts(path) -> dict:
    """tests / failures / errors / skipped of a JUnit XML report."""
    try:
        root = ET.parse(path).getroot()
    except (OSError, ET.ParseError):
        return {}
    suite = root if root.tag == 'testsuite' else root.find('testsuite')
    return {k: int(suite.get(k, 0))
            for k in ('tests', 'failures', 'errors', 'skipped')}

"""``make_detector_cfg``: the plugin tests' tiny MMDetection detector (and
their default scope), taken from tests/test_models/test_detectors/
conftest.py, loaded by its path as tool_helpers.load_tool loads the tools:
the dehazing preprocessor is tested in front of the same detector."""
import importlib.util
import os.path as osp

TESTS = osp.abspath(osp.join(osp.dirname(__file__), *['..'] * 4))
_spec = importlib.util.spec_from_file_location(
    'cbnet_test_detector_fixtures',
    osp.join(TESTS, 'test_models', 'test_detectors', 'conftest.py'))
_detectors = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_detectors)

make_detector_cfg = _detectors.make_detector_cfg

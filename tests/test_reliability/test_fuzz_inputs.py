"""A sample of the malformed-input sweep (tools/analysis_tools/
fuzz_inputs.py): every mutation kind that once crashed, plus a few others,
through dataset + pipeline + one training step; no unexplained crash."""
import importlib.util
import os.path as osp

import pytest

from tiny_configs import REPO

#: Mutations that crashed before the dataset checks, and some others.
SAMPLE = [
    'bbox_string', 'bbox_wrong_length', 'iscrowd_all', 'no_annotations',
    'key_images_missing', 'segm_empty_list', 'segm_rle_garbage',
    'segm_rle_wrong_size', 'img_smaller_than_ann', 'img_truncated',
    'json_truncated', 'bbox_nan', 'img_grey', 'many_tiny_instances'
]


def load_fuzz_tool():
    spec = importlib.util.spec_from_file_location(
        'cbnet_tools_fuzz_inputs',
        osp.join(REPO, 'tools', 'analysis_tools', 'fuzz_inputs.py'))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.slow  # ~30 s on 2 cores (14 variants, ~6 training steps)
def test_fuzz_sample_has_no_crash(cityscapes_like_root, tmp_path):
    fuzz = load_fuzz_tool()
    assert set(SAMPLE) <= set(fuzz.MUTATIONS)
    result = fuzz.sweep(cityscapes_like_root, len(SAMPLE), seed=0,
                        num_images=2, scale=(128, 64),
                        work=str(tmp_path), mutations=SAMPLE)
    assert result['tried'] == len(SAMPLE)
    assert not result['crashes'], result['crashes']
    outcomes = result['outcomes']
    assert outcomes.get('ok', 0) >= 2 and outcomes.get('clear error') >= 10
    table = fuzz.markdown(result)
    assert f'| **total** | {len(SAMPLE)} |' in table
